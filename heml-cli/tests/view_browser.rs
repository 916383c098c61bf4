//! `heml view` in a real browser: Debian's headless Chromium driven by chromedriver
//! (WebDriver, the fantoccini crate). The page must draw the organ (WebGL through
//! SwiftShader), its pause and step buttons must stop and step the simulation, and
//! its E field must change the server's material. A screenshot is saved to
//! `target/view-e2e/screenshot.png`.
//!
//! Needs `chromium` and `chromedriver` on PATH (`.ci/run` installs them); without
//! them the test says so loudly and returns, except under CI (`CI` set), where it fails.
#[path = "support/view.rs"]
mod view;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use fantoccini::{ClientBuilder, Locator};
use serde_json::json;
use view::{Client, ViewServer};

const WAIT: Duration = Duration::from_secs(60);

fn on_path(name: &str) -> Option<PathBuf> {
    std::env::var_os("PATH")?
        .to_str()?
        .split(':')
        .map(|d| Path::new(d).join(name))
        .find(|p| p.is_file())
}

struct Driver(Child);

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

#[tokio::test(flavor = "current_thread")]
async fn the_page_draws_the_organ_and_drives_the_simulation() {
    let (Some(chromium), Some(chromedriver)) = (on_path("chromium"), on_path("chromedriver")) else {
        let msg = "chromium and chromedriver are not on PATH: the browser test of `heml view` did NOT run \
                   (apt-get install chromium chromium-driver; .ci/run installs them)";
        if std::env::var_os("CI").is_some() {
            panic!("{msg}");
        }
        eprintln!("\n*** SKIPPED: {msg} ***\n");
        return;
    };
    let server = ViewServer::start(&["view", "--demo", "--threads", "1"]);
    let port = free_port();
    let _driver = Driver(
        Command::new(&chromedriver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start chromedriver"),
    );
    let profile = std::env::temp_dir().join(format!("heml-view-chromium-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&profile);
    let caps = json!({
        "browserName": "chrome",
        "goog:chromeOptions": {
            "binary": chromium,
            "args": [
                "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--window-size=1000,700",
                format!("--user-data-dir={}", profile.display()),
            ]
        }
    });
    let caps = match caps {
        serde_json::Value::Object(m) => m,
        _ => unreachable!(),
    };
    // chromedriver takes a moment to listen
    let start = Instant::now();
    let browser = loop {
        match ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
            .capabilities(caps.clone())
            .connect(&format!("http://127.0.0.1:{port}"))
            .await
        {
            Ok(c) => break c,
            Err(e) if start.elapsed() < Duration::from_secs(30) => {
                let _ = e;
                tokio::time::sleep(Duration::from_millis(200)).await;
            }
            Err(e) => panic!("cannot start a WebDriver session: {e}"),
        }
    };
    browser.goto(&server.url).await.expect("open the page");

    // frames arrive and are drawn
    let start = Instant::now();
    loop {
        let frames = browser
            .execute("return window.hemlView ? window.hemlView.frames : 0", vec![])
            .await
            .unwrap()
            .as_u64()
            .unwrap_or(0);
        if frames >= 10 {
            break;
        }
        assert!(start.elapsed() < WAIT, "the page received {frames} frames in {WAIT:?}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    tokio::time::sleep(Duration::from_millis(500)).await;
    let probe = browser.execute("return window.hemlView.probe()", vec![]).await.unwrap();
    let inside = probe["inside"].as_f64().unwrap();
    let area = probe["area"].as_f64().unwrap();
    assert_eq!(probe["webgl"], true, "no WebGL context: {probe}");
    // the organ's projected bounding box is mostly covered by the box-shaped demo
    // block: at least a third of its pixels differ from the background
    assert!(area > 1000.0 && inside > area / 3.0, "organ pixels: {probe}");
    // and little is drawn outside it (fixed-node markers at the box's edge)
    assert!(probe["outside"].as_f64().unwrap() < 0.05 * area, "{probe}");

    let png = browser.screenshot().await.expect("screenshot");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/view-e2e");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("screenshot.png"), &png).unwrap();

    // pause from the page: the server's time stops
    let mut ws = Client::connect(&server).await;
    assert!(ws.until(WAIT, |c| c.status.is_object()).await);
    browser.find(Locator::Id("pause")).await.unwrap().click().await.unwrap();
    assert!(ws.until(WAIT, |c| c.paused()).await, "the pause button did not pause");
    ws.drain(Duration::from_millis(300)).await;
    let (t0, steps0) = (ws.time(), ws.steps());
    ws.drain(Duration::from_millis(700)).await;
    assert_eq!((ws.time(), ws.steps()), (t0, steps0), "time went on while paused");

    // one step from the page: exactly one dt
    let dt = ws.status["dt"].as_f64().unwrap();
    browser.find(Locator::Id("step")).await.unwrap().click().await.unwrap();
    assert!(ws.until(WAIT, |c| c.steps() == steps0 + 1).await, "{}", ws.status);
    assert!((ws.time() - (t0 + dt)).abs() <= 4.0 * f64::EPSILON * (t0 + dt));
    ws.drain(Duration::from_millis(300)).await;
    assert_eq!(ws.steps(), steps0 + 1, "one click stepped more than once");

    // E from the page's field: the server's law changes (mu ∝ E)
    let e0 = ws.scene_param("E");
    let mu0 = ws.law_param("mu");
    let field = browser.find(Locator::Id("E")).await.unwrap();
    field.click().await.unwrap();
    field.clear().await.unwrap();
    field.send_keys(&format!("{}", 3.0 * e0)).await.unwrap();
    browser.find(Locator::Id("setE")).await.unwrap().click().await.unwrap();
    assert!(
        ws.until(WAIT, |c| c.scene_param("E") == 3.0 * e0).await,
        "{}",
        ws.status
    );
    assert!((ws.law_param("mu") / mu0 - 3.0).abs() < 1e-12);
    // the panel shows the status
    let shown = browser.find(Locator::Id("time")).await.unwrap().text().await.unwrap();
    assert!(shown.ends_with(" s"), "panel time {shown:?}");

    browser.close().await.unwrap();
    let _ = std::fs::remove_dir_all(&profile);
}
