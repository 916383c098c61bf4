//! `heml view`'s WebSocket protocol against a running server: malformed, oversized,
//! non-finite and unknown messages are ignored (the server stays up, the
//! simulation's state does not change), and valid commands keep working after them.
#[path = "support/bin.rs"]
mod bin;
#[path = "support/view.rs"]
mod view;

use std::time::Duration;

use serde_json::json;
use view::{Client, ViewServer};

const WAIT: Duration = Duration::from_secs(30);

#[tokio::test(flavor = "current_thread")]
async fn bad_messages_are_ignored_and_change_nothing() {
    let mut server = ViewServer::start(&["view", "--demo", "--threads", "1"]);
    let mut c = Client::connect(&server).await;
    // on connect: the mesh, then frames of 32 + 16 n bytes
    assert!(
        c.until(WAIT, |c| c.mesh.is_object() && c.frames > 0 && c.status.is_object())
            .await
    );
    let n = c.mesh["nodes"].as_array().unwrap().len();
    assert!(n > 0 && !c.mesh["triangles"].as_array().unwrap().is_empty());
    assert_eq!(c.frame_bytes, 32 + 16 * n);

    c.send(json!({"type": "pause"})).await;
    assert!(c.until(WAIT, |c| c.paused()).await, "no paused status");
    c.drain(Duration::from_millis(300)).await;
    let (t0, steps0, mu0, e0) = (c.time(), c.steps(), c.law_param("mu"), c.scene_param("E"));
    assert!(mu0 > 0.0 && e0 > 0.0, "{}", c.status);

    // each of these is refused; the text ones get a reply, none changes the state
    let bad_texts = [
        "not json at all",
        r#"{"type":"set_param","name":"E","value":NaN}"#,
        r#"{"type":"set_param","name":"E","value":1e999}"#,
        r#"{"type":"set_param","name":"E","value":-5}"#,
        r#"{"type":"explode"}"#,
        r#"{"type":"pause","extra":true}"#,
        r#"{"type":"grasp_move","target":[0,0,1e300]}"#,
        r#"{"type":"set_param","name":"no_such_parameter","value":5}"#,
        r#"{"type":"field","field":"/etc/passwd"}"#,
        // a blade 100 m away meets no tet
        r#"{"type":"cut","blade":[[100,100,100],[101,100,100],[100,101,100]]}"#,
    ];
    let before = c.replies.len();
    for text in bad_texts {
        c.send_text(text).await;
    }
    c.send_binary(vec![0xff; 100]).await;
    let want = before + bad_texts.len();
    assert!(
        c.until(WAIT, |c| c.replies.len() >= want).await,
        "replies: {:?}",
        c.replies
    );
    for r in &c.replies[before..] {
        assert_eq!(r["ok"], false, "{r}");
    }
    // the cut that meets nothing says so
    let last = c.replies.last().unwrap()["message"].as_str().unwrap().to_string();
    assert!(last.contains("meets no tet"), "{last}");
    c.drain(Duration::from_millis(300)).await;
    assert!(c.paused());
    assert_eq!(
        (c.time(), c.steps()),
        (t0, steps0),
        "a bad message moved the simulation"
    );
    assert_eq!((c.law_param("mu"), c.scene_param("E")), (mu0, e0));

    // an oversized message closes this connection, not the server
    let huge = format!(r#"{{"type":"pause","pad":"{}"}}"#, "x".repeat(100_000));
    c.send_text(&huge).await;
    c.until(Duration::from_secs(10), |c| c.closed).await;
    assert!(c.closed, "the server kept a connection that sent 100 kB");
    assert!(server.alive(), "the server died");

    // a new connection: same state, and valid commands work
    let mut c = Client::connect(&server).await;
    assert!(c.until(WAIT, |c| c.mesh.is_object() && c.status.is_object()).await);
    assert!(c.paused());
    assert_eq!((c.time(), c.steps()), (t0, steps0));
    c.send(json!({"type": "step"})).await;
    assert!(c.until(WAIT, |c| c.steps() == steps0 + 1).await, "{}", c.status);
    // the explicit demo steps adaptively: the status after a step reports the step
    // just taken (the controller may re-estimate before any step, so the dt shown
    // before it need not be the one used); t accumulates t + dt in f64, equal to the
    // sum up to one rounding of t
    let dt = c.status["dt"].as_f64().unwrap();
    assert!(dt > 0.0, "{}", c.status);
    assert!(
        (c.time() - (t0 + dt)).abs() <= 4.0 * f64::EPSILON * (t0 + dt),
        "{} vs {}",
        c.time(),
        t0 + dt
    );

    // E doubled: the law's mu = E / (2 (1 + nu)) doubles; the state is carried over
    c.send(json!({"type": "set_param", "name": "E", "value": 2.0 * e0}))
        .await;
    assert!(c.until(WAIT, |c| c.scene_param("E") == 2.0 * e0).await, "{}", c.status);
    assert!(
        (c.law_param("mu") / mu0 - 2.0).abs() < 1e-12,
        "mu {} -> {}",
        mu0,
        c.law_param("mu")
    );
    assert_eq!(c.steps(), steps0 + 1, "the rebuild reset the clock");

    // the colour field: J near 1 (the demo sags a few percent), energy density ≥ 0
    c.send(json!({"type": "field", "field": "j"})).await;
    assert!(c.until(WAIT, |c| c.frame_field().0 == 1).await);
    let (_, j) = c.frame_field();
    assert_eq!(j.len(), n);
    assert!(j.iter().all(|&j| j > 0.5 && j < 1.5), "J out of range");
    assert!(j.iter().any(|&j| j != 1.0), "J is exactly 1 everywhere: not computed");
    c.send(json!({"type": "field", "field": "energy"})).await;
    assert!(c.until(WAIT, |c| c.frame_field().0 == 2).await);
    assert!(c.frame_field().1.iter().all(|&w| w >= 0.0 && w.is_finite()));
    assert!(server.alive());
}

/// Flow control: a page that acks its frames has at most one in flight (no frame
/// comes until its next ack, and then exactly one: the newest), and the ack gets no
/// reply; a client that never acks gets the frames as they are made.
#[tokio::test(flavor = "current_thread")]
async fn an_acking_page_has_one_frame_in_flight() {
    let server = ViewServer::start(&["view", "--demo", "--threads", "1", "--fps", "40"]);
    let mut free = Client::connect(&server).await;
    let mut acking = Client::connect(&server).await;
    assert!(acking.until(WAIT, |c| c.frames > 0).await);
    acking.send(json!({"type": "ack"})).await;
    // what was sent before the ack arrives, then the one frame the ack allows
    acking.drain(Duration::from_secs(1)).await;
    let held = acking.frames;
    // a second, 40 frames are made meanwhile: none comes
    acking.drain(Duration::from_secs(1)).await;
    assert_eq!(acking.frames, held, "frames came without an ack");
    for k in 1..=3 {
        acking.send(json!({"type": "ack"})).await;
        acking.drain(Duration::from_millis(700)).await;
        assert_eq!(acking.frames, held + k, "ack {k}: one frame per ack");
    }
    assert!(acking.replies.is_empty(), "an ack was answered: {:?}", acking.replies);
    // the other connection got them all: ~40/s over the 3+ s above; 20 leaves room
    // for a loaded machine
    free.drain(Duration::from_millis(500)).await;
    assert!(free.frames >= 20, "{} frames without acks", free.frames);
}

/// `heml view OUTPUT_DIR` plays a finished run's frames: the mesh is the run's
/// surface, the frames carry its positions, `step` shows the next frame and commands
/// of the live simulation are refused; a directory without a `.pvd` is an error.
#[tokio::test(flavor = "current_thread")]
async fn a_finished_run_plays_back() {
    let dir = bin::temp_dir("view", "playback");
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        r#"
[mesh]
generate = { kind = "box", size = [0.04, 0.01, 0.01], cells = [4, 1, 1] }
[[material]]
law = "neo_hookean"
params = { E = 5e3, nu = 0.3 }
[[fix]]
plane = { point = [0, 0, 0], normal = [1, 0, 0] }
[loads]
gravity = [0, 0, -9.81]
[solver]
duration = 0.01
[output]
dir = "out"
frame_interval = 0.002
csv = false
"#,
    )
    .unwrap();
    let out = dir.join("out");
    let (ok, _, err) = bin::heml(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(ok, "{err}");
    let frames = heml::io::read_pvd(&out.join("frames.pvd")).unwrap();
    assert!(frames.len() >= 5, "{frames:?}");

    let server = ViewServer::start(&["view", out.to_str().unwrap()]);
    let mut c = Client::connect(&server).await;
    assert!(
        c.until(WAIT, |c| c.mesh.is_object() && c.frames > 0 && c.status.is_object())
            .await
    );
    assert_eq!(c.mesh["mode"], "playback");
    // a 4 × 1 × 1 box of 6-tet cells: 20 nodes, all on the surface
    assert_eq!(c.mesh["nodes"].as_array().unwrap().len(), 20);
    assert_eq!(c.status["integrator"], "playback");
    c.send(json!({"type": "pause"})).await;
    assert!(c.until(WAIT, |c| c.paused()).await);
    c.drain(Duration::from_millis(200)).await;
    let k = c.steps();
    c.send(json!({"type": "step"})).await;
    assert!(
        c.until(WAIT, |c| c.steps() == (k + 1) % frames.len() as u64).await,
        "{}",
        c.status
    );
    // the shown frame's time is the .pvd's
    let t = c.time();
    assert!(frames.iter().any(|(ft, _)| *ft == t), "time {t} not in {frames:?}");
    let n = c.replies.len();
    c.send(json!({"type": "set_param", "name": "E", "value": 1e4})).await;
    assert!(c.until(WAIT, |c| c.replies.len() > n).await);
    assert_eq!(c.replies[n]["ok"], false);
    assert!(c.replies[n]["message"].as_str().unwrap().contains("playback"));

    let (ok, _, err) = bin::heml(&["view", dir.join("nothing").to_str().unwrap(), "--no-open"]);
    assert!(!ok);
    assert!(err.contains("nothing"), "{err}");
    std::fs::create_dir_all(dir.join("empty")).unwrap();
    let (ok, _, err) = bin::heml(&["view", dir.join("empty").to_str().unwrap(), "--no-open"]);
    assert!(!ok && err.contains("no .pvd file"), "{err}");
}

/// A scene whose step is long (backward Euler at dt = 20 ms) and cheap (a small
/// block) runs at real time, not ahead of it: the server naps while the simulation
/// leads the clock and does not step until it is due (it used to nap 2 ms and step
/// anyway, 7x real time on the 20k kidney).
#[tokio::test(flavor = "current_thread")]
async fn a_long_cheap_step_runs_at_real_time() {
    let dir = bin::temp_dir("view", "pacing");
    let scene = dir.join("implicit_block.toml");
    std::fs::write(
        &scene,
        r#"[mesh]
generate = { kind = "box", size = [0.08, 0.06, 0.05], cells = [8, 6, 5], split = "six" }

[[material]]
law = "neo_hookean"
params = { E = 8.0e3, nu = 0.45 }
density = 1000.0

[[fix]]
plane = { point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }

[loads]
gravity = [0.0, 0.0, -9.81]

[damping]
mass = 5.0

[solver]
integrator = "backward_euler"
dt = 0.02
duration = 1.0
"#,
    )
    .unwrap();
    let server = ViewServer::start(&["view", scene.to_str().unwrap(), "--threads", "1"]);
    let mut c = Client::connect(&server).await;
    assert!(c.until(WAIT, |c| c.status.is_object() && c.time() > 0.0).await);
    let (t0, wall0) = (c.time(), std::time::Instant::now());
    c.drain(Duration::from_secs(3)).await;
    let (t1, wall) = (c.time(), wall0.elapsed().as_secs_f64());
    // the simulation advanced (it is not stalled) and by no more than the wall time
    // plus 0.2 s: one status period (0.1 s) of staleness on each reading and a step
    // of 0.02 s taken just before it was due; at the old pacing a 1 440-tet implicit
    // step (~1 ms) ran ~10x real time, 30 s of simulated time here
    assert!(t1 > t0, "the simulation did not advance: {t0} → {t1}");
    assert!(
        t1 - t0 <= wall + 0.2,
        "ran ahead of real time: {:.3} s simulated in {wall:.3} s",
        t1 - t0
    );
    drop(server);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The live view plays the scene's script as `heml run` does: a `[[cut]]` at its
/// time notches the tissue and the page receives the new surface (the live loop
/// used to step the integrator alone, so a scene's cuts, ramped surface loads and
/// scripted tools never happened in `heml view`).
#[tokio::test(flavor = "current_thread")]
async fn the_scenes_cuts_happen_in_the_live_view() {
    let dir = bin::temp_dir("view", "scripted-cut");
    let scene = dir.join("notched_block.toml");
    std::fs::write(
        &scene,
        r#"[mesh]
generate = { kind = "box", size = [0.08, 0.02, 0.02], cells = [8, 2, 2], split = "six" }

[[material]]
law = "neo_hookean"
params = { E = 8.0e3, nu = 0.3 }
density = 1000.0

[[fix]]
plane = { point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }

[solver]
duration = 1.0

[[cut]]
time = 0.05
from = [[0.045, -0.1, 0.1], [0.045, 0.1, 0.1]]
to = [[0.045, -0.1, 0.01], [0.045, 0.1, 0.01]]
"#,
    )
    .unwrap();
    let server = ViewServer::start(&["view", scene.to_str().unwrap(), "--threads", "1"]);
    let mut c = Client::connect(&server).await;
    assert!(c.until(WAIT, |c| c.mesh.is_object()).await, "no mesh message");
    let (version, triangles) = (
        c.mesh["version"].as_u64().unwrap(),
        c.mesh["triangles"].as_array().unwrap().len(),
    );
    // the cut comes at t = 0.05 s of a real-time run
    assert!(
        c.until(WAIT, |c| c.mesh["version"].as_u64() > Some(version)).await,
        "no new surface after the cut (t = {})",
        c.time()
    );
    // a notch's faces are added to the surface (the tets it removes were interior
    // to the top half, so their neighbours' faces are now boundary)
    let after = c.mesh["triangles"].as_array().unwrap().len();
    assert!(after > triangles, "{triangles} -> {after} triangles");

    // changing E keeps the cut: the law is replaced in the running system (it used
    // to be rebuilt from the scene, uncut, and the scene's cut then came again as a
    // new surface)
    assert!(c.until(WAIT, |c| c.time().is_finite()).await, "no status");
    let (version, mu0, n) = (c.mesh["version"].as_u64(), c.law_param("mu"), c.replies.len());
    c.send(json!({"type": "set_param", "name": "E", "value": 1.6e4})).await;
    assert!(c.until(WAIT, |c| c.replies.len() > n).await, "no reply to set_param");
    assert_eq!(c.replies[n]["ok"], true, "{}", c.replies[n]);
    let t = c.time();
    assert!(
        c.until(WAIT, |c| c.time() > t + 0.05).await,
        "the run stopped after set_param: {}",
        c.status
    );
    // (mu = E / (2 (1 + nu)): doubled, to round-off of the division)
    assert!(
        (c.law_param("mu") / mu0 - 2.0).abs() < 1e-12,
        "mu {mu0} -> {}",
        c.law_param("mu")
    );
    assert_eq!(
        c.mesh["version"].as_u64(),
        version,
        "the surface changed after set_param"
    );
    assert_eq!(
        c.mesh["triangles"].as_array().unwrap().len(),
        after,
        "the cut was undone"
    );
    drop(server);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The port of a server's URL (`http://127.0.0.1:PORT/`).
fn port_of(server: &ViewServer) -> u16 {
    server
        .url
        .trim_end_matches('/')
        .rsplit(':')
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

/// A WebSocket handshake with these headers: `Ok(())` if accepted, else the HTTP
/// status of the refusal.
async fn handshake(server: &ViewServer, headers: &[(&'static str, String)]) -> Result<(), u16> {
    use tokio_tungstenite::tungstenite::{client::IntoClientRequest, Error};
    let mut req = server.ws_url().into_client_request().unwrap();
    for (name, value) in headers {
        req.headers_mut().insert(*name, value.parse().unwrap());
    }
    match tokio_tungstenite::connect_async(req).await {
        Ok(_) => Ok(()),
        Err(Error::Http(resp)) => Err(resp.status().as_u16()),
        Err(e) => panic!("handshake failed otherwise: {e}"),
    }
}

/// Other sites cannot drive the simulation: a WebSocket handshake from another
/// site's page (its `Origin`) is refused with 403, and so is any request naming
/// another host (DNS rebinding); the server's own page (a loopback origin) and
/// clients without an `Origin` are served.
#[tokio::test(flavor = "current_thread")]
async fn other_sites_pages_and_hosts_are_refused() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let server = ViewServer::start(&["view", "--demo", "--threads", "1"]);
    let port = port_of(&server);
    let mut c = Client::connect(&server).await;
    c.send(json!({"type": "pause"})).await;
    assert!(c.until(WAIT, |c| c.paused()).await, "no paused status");
    c.drain(Duration::from_millis(300)).await;
    let steps0 = c.steps();

    let evil = [("Origin", "http://evil.example.com".to_string())];
    assert_eq!(
        handshake(&server, &evil).await,
        Err(403),
        "a foreign origin was accepted"
    );
    let https = [("Origin", format!("https://localhost:{port}"))];
    assert_eq!(handshake(&server, &https).await, Err(403));
    let rebound = [("Host", format!("rebind.attacker.example:{port}"))];
    assert_eq!(
        handshake(&server, &rebound).await,
        Err(403),
        "a foreign host was accepted"
    );
    // the page itself: a plain GET naming another host is refused, with a reason
    let mut tcp = tokio::net::TcpStream::connect(("127.0.0.1", port)).await.unwrap();
    tcp.write_all(b"GET / HTTP/1.1\r\nHost: rebind.attacker.example\r\nConnection: close\r\n\r\n")
        .await
        .unwrap();
    let mut answer = String::new();
    tokio::time::timeout(WAIT, tcp.read_to_string(&mut answer))
        .await
        .unwrap()
        .unwrap();
    assert!(answer.starts_with("HTTP/1.1 403"), "{answer}");
    assert!(answer.contains("rebind.attacker.example"), "{answer}");

    // the server's own pages are served
    for origin in [format!("http://127.0.0.1:{port}"), format!("http://localhost:{port}")] {
        assert_eq!(
            handshake(&server, &[("Origin", origin.clone())]).await,
            Ok(()),
            "{origin}"
        );
    }
    let mut tcp = tokio::net::TcpStream::connect(("127.0.0.1", port)).await.unwrap();
    let get = format!("GET / HTTP/1.1\r\nHost: localhost:{port}\r\nConnection: close\r\n\r\n");
    tcp.write_all(get.as_bytes()).await.unwrap();
    let mut answer = String::new();
    tokio::time::timeout(WAIT, tcp.read_to_string(&mut answer))
        .await
        .unwrap()
        .unwrap();
    assert!(
        answer.starts_with("HTTP/1.1 200"),
        "{}",
        &answer[..answer.len().min(200)]
    );

    // nothing moved the simulation
    c.drain(Duration::from_millis(300)).await;
    assert!(c.paused());
    assert_eq!(c.steps(), steps0);
}

/// A client flooding commands gets `busy` replies once the simulation's queue is
/// full instead of growing it without bound, and a command after the flood is
/// answered within seconds.
#[tokio::test(flavor = "current_thread")]
async fn a_flood_of_commands_is_refused_busy() {
    let server = ViewServer::start(&["view", "--demo", "--threads", "1"]);
    let mut c = Client::connect(&server).await;
    c.send(json!({"type": "pause"})).await;
    assert!(c.until(WAIT, |c| c.paused()).await, "no paused status");
    // steps take the simulation far longer than the server takes to queue them
    for _ in 0..15 {
        for _ in 0..200 {
            c.send_text(r#"{"type":"step"}"#).await;
        }
        c.drain(Duration::from_millis(1)).await;
    }
    let busy = |c: &Client| {
        c.replies
            .iter()
            .any(|r| r["ok"] == false && r["message"].as_str().is_some_and(|m| m.contains("busy")))
    };
    assert!(
        c.until(Duration::from_secs(10), busy).await,
        "no busy reply to 3000 steps"
    );
    // the queue drains: quiet within seconds
    let start = std::time::Instant::now();
    loop {
        let n = c.replies.len();
        c.drain(Duration::from_millis(500)).await;
        if c.replies.len() == n {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(20), "the replies never stop");
    }
    let n = c.replies.len();
    let steps = c.steps();
    c.send(json!({"type": "step"})).await;
    assert!(
        c.until(Duration::from_secs(5), |c| c.replies.len() > n).await,
        "the step after the flood was not answered"
    );
    assert_eq!(c.replies[n]["command"], "step");
    assert_eq!(c.replies[n]["ok"], true, "{}", c.replies[n]);
    assert!(c.until(Duration::from_secs(5), |c| c.steps() == steps + 1).await);
    assert!(!c.closed);
}

/// `heml view FILE.pvd`: its exit status and stderr, or a failure if it is still
/// running (serving) after 20 s.
fn view_exits(pvd: &std::path::Path) -> (bool, String) {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_heml"))
        .args(["view", pvd.to_str().unwrap(), "--no-open", "--port", "0"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run heml view");
    let end = std::time::Instant::now() + Duration::from_secs(20);
    while child.try_wait().unwrap().is_none() {
        if std::time::Instant::now() > end {
            let _ = child.kill();
            let _ = child.wait();
            panic!("heml view {} was still running after 20 s", pvd.display());
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = child.wait_with_output().unwrap();
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into())
}

/// Writes a `.pvd` collection at `path` listing (timestep text, file) entries as
/// written, however wrong.
fn write_pvd(path: &std::path::Path, entries: &[(String, String)]) {
    let sets: String = entries
        .iter()
        .map(|(t, f)| format!("<DataSet timestep=\"{t}\" group=\"\" part=\"0\" file=\"{f}\"/>\n"))
        .collect();
    let text = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n{sets}</Collection>\n</VTKFile>\n"
    );
    std::fs::write(path, text).unwrap();
}

/// A `.pvd` whose times are not finite or do not increase is refused, naming the
/// file and the entry (the player used to spin on them).
#[test]
fn a_pvd_with_bad_times_is_refused() {
    use heml::mesh::generate::{box_mesh, HexSplit};
    let dir = bin::temp_dir("view", "bad-times");
    let mesh = box_mesh([0.02, 0.01, 0.01], [2, 1, 1], HexSplit::Six).unwrap();
    for f in ["f0.vtu", "f1.vtu", "f2.vtu"] {
        heml::io::write_mesh(&dir.join(f), &mesh).unwrap();
    }
    let pvd = |name: &str, times: [&str; 3]| {
        let path = dir.join(name);
        let entries: Vec<(String, String)> = times
            .iter()
            .enumerate()
            .map(|(k, t)| (t.to_string(), format!("f{k}.vtu")))
            .collect();
        write_pvd(&path, &entries);
        path
    };
    for (name, times, entry) in [
        ("nan.pvd", ["0", "nan", "0.2"], "f1.vtu"),
        ("decreasing.pvd", ["0", "0.2", "0.1"], "f2.vtu"),
        ("repeated.pvd", ["0", "0", "0.1"], "f1.vtu"),
    ] {
        let (ok, err) = view_exits(&pvd(name, times));
        assert!(!ok, "{name} was accepted");
        assert!(err.contains(name) && err.contains(entry), "{name}: {err}");
    }
}

/// A `.pvd` whose frames would decode to more than the playback's 2 GiB is refused
/// from its first frame's size and its entry count, before any other frame is read
/// (60 000 entries of a 20³-cell box's 2 402 surface vertices: 60 000 × 2 402 × 16 B
/// = 2.3 GB).
#[test]
fn a_pvd_too_large_to_play_is_refused_before_loading() {
    use heml::mesh::generate::{box_mesh, HexSplit};
    let dir = bin::temp_dir("view", "huge-pvd");
    let mesh = box_mesh([0.1, 0.1, 0.1], [20, 20, 20], HexSplit::Six).unwrap();
    heml::io::write_mesh(&dir.join("f.vtu"), &mesh).unwrap();
    let pvd = dir.join("huge.pvd");
    let entries: Vec<(String, String)> = (0..60_000).map(|k| (k.to_string(), "f.vtu".to_string())).collect();
    write_pvd(&pvd, &entries);
    let (ok, err) = view_exits(&pvd);
    assert!(!ok, "a 2.3 GB playback was accepted");
    assert!(
        err.contains("huge.pvd") && err.contains("60000 frames of 2402 surface vertices") && err.contains("2 GiB"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A connection that never finishes its request's headers is closed after a few
/// seconds (they used to stay open for good).
#[tokio::test(flavor = "current_thread")]
async fn a_request_without_its_end_is_closed() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let server = ViewServer::start(&["view", "--demo", "--threads", "1"]);
    let mut tcp = tokio::net::TcpStream::connect(("127.0.0.1", port_of(&server)))
        .await
        .unwrap();
    tcp.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n").await.unwrap();
    let mut rest = Vec::new();
    let closed = tokio::time::timeout(Duration::from_secs(15), tcp.read_to_end(&mut rest)).await;
    assert!(closed.is_ok(), "a half-sent request was kept open 15 s");
}
