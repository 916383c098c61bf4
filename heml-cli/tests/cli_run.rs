//! End-to-end tests of `heml run` and `heml demo` through the binary: the output is
//! read back with heml's own readers and checked against physics.

use std::path::{Path, PathBuf};

use heml::io::{read_mesh_data, read_pvd};
use heml::Vec3;

#[path = "support/bin.rs"]
mod support;
use support::heml;

/// A fresh, empty temporary directory for one test.
fn temp_dir(name: &str) -> support::TestDir {
    support::temp_dir("cli-run", name)
}

/// The node positions of a VTU frame.
fn positions(path: &Path) -> Vec<Vec3> {
    read_mesh_data(path).unwrap_or_else(|e| panic!("{e}")).0.nodes
}

/// The frames listed by `frames.pvd`, checked to exist, in order.
fn frames(dir: &Path) -> Vec<(f64, PathBuf)> {
    let list = read_pvd(&dir.join("frames.pvd")).unwrap();
    let on_disk = std::fs::read_dir(dir)
        .unwrap()
        .filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().ends_with(".vtu"))
        .count();
    assert_eq!(list.len(), on_disk, "the pvd must list every frame written");
    for (i, (_, f)) in list.iter().enumerate() {
        assert_eq!(f, &format!("frame_{i:05}.vtu"));
    }
    assert!(list.windows(2).all(|w| w[1].0 > w[0].0), "frame times increase");
    list.into_iter().map(|(t, f)| (t, dir.join(f))).collect()
}

/// The rows of `energy.csv`, checked for the header and finite values (at least
/// two rows, or one when the run `blew_up`).
fn csv_rows(dir: &Path, blew_up: bool) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some(
            "time,step,kinetic,elastic,gravity,loads,total,reaction_x,reaction_y,reaction_z,reaction_norm,dt,dt_reason,cg_iterations"
        )
    );
    // column 13 (dt_reason) is a word: the numbers are the 13 others
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            let mut cols: Vec<&str> = l.split(',').collect();
            assert_eq!(cols.len(), 14, "{l}");
            let reason = cols.remove(12);
            assert!(["fixed", "base", "stiffness", "recovering"].contains(&reason), "{l}");
            cols.iter().map(|v| v.parse::<f64>().unwrap()).collect()
        })
        .collect();
    // a run that blew up may have stopped at its first step (the t = 0 row only);
    // every row is an accepted state, finite whatever happened next
    assert!(rows.len() >= if blew_up { 1 } else { 2 });
    for r in &rows {
        assert_eq!(r.len(), 13);
        assert!(r.iter().all(|v| v.is_finite()), "{r:?}");
    }
    rows
}

#[test]
fn demo_sags_under_gravity_and_writes_a_complete_series() {
    let dir = temp_dir("demo");
    let out = dir.join("out");
    let (ok, stdout, err) = heml(&["demo", "--out", out.to_str().unwrap(), "--duration", "0.6", "--quiet"]);
    assert!(ok, "{err}");
    assert!(stdout.contains("done:") && stdout.contains("frames"), "{stdout}");
    let frames = frames(&out);
    assert!(frames.len() >= 10, "{}", frames.len());
    assert!((frames.last().unwrap().0 - 0.6).abs() < 1e-9);
    let rest = positions(&frames[0].1);
    let x = positions(&frames.last().unwrap().1);
    let u: Vec<Vec3> = x.iter().zip(&rest).map(|(a, b)| a - b).collect();
    assert!(u.iter().all(|v| v.iter().all(|c| c.is_finite())));
    // the clamped face x = 0 did not move at all (positions are stored exactly)
    let clamped: Vec<usize> = (0..rest.len()).filter(|&i| rest[i].x == 0.0).collect();
    assert_eq!(clamped.len(), 13 * 11);
    assert!(clamped.iter().all(|&i| x[i] == rest[i]));
    // Sag in the direction of gravity, of a plausible size. Beam theory for a free
    // cantilever of length L = 8 cm and height h = 5 cm under its weight gives a tip
    // deflection d_c = q L^4 / (8 E I) = 1.5 rho g L^4 / (E h^2) = 3.0 cm. The demo is
    // no free cantilever: the tool patch at mid-length is held at (close to) its rest
    // position early on, which props the block up (a cantilever of length L/2 would
    // sag d_c/16), while shear deformation of so stubby a block (Timoshenko: +45 % at
    // h/L = 0.6) and the tool's own descent (4.3 mm at t = 0.6 s) add to it. So the
    // tip sag must lie within an order of magnitude of d_c: in [d_c/10, 2 d_c].
    let d_c = 1.5 * 1000.0 * 9.81 * 0.08f64.powi(4) / (8.0e3 * 0.05f64.powi(2));
    let tip: Vec<usize> = (0..rest.len()).filter(|&i| (rest[i].x - 0.08).abs() < 1e-12).collect();
    let tip_sag = -tip.iter().map(|&i| u[i].z).sum::<f64>() / tip.len() as f64;
    assert!(
        tip_sag > d_c / 10.0 && tip_sag < 2.0 * d_c,
        "tip sag {tip_sag} m vs d_c = {d_c} m"
    );
    // every free node moved down on average, none of them up by much
    let mean_sag = -u.iter().map(|v| v.z).sum::<f64>() / u.len() as f64;
    assert!(mean_sag > 0.0, "{mean_sag}");
    // The supports (clamp + tool) carry the weight m g = 2.354 N: the rest of the
    // reaction is the inertia of the body still settling (the damping leaves e^(-alpha
    // t / 2) = 1 % of the initial transient at 0.6 s) and of the slow tool: 5 %.
    let rows = csv_rows(&out, false);
    let weight = 0.08 * 0.06 * 0.05 * 1000.0 * 9.81;
    let last = rows.last().unwrap();
    assert!((last[0] - 0.6).abs() < 1e-9);
    assert!(
        (last[9] - weight).abs() < 0.05 * weight,
        "reaction {last:?} vs weight {weight}"
    );
    // energies: gravity potential decreased, elastic energy stored
    assert!(last[4] < 0.0 && last[3] > 0.0, "{last:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A cantilever beam settled under its weight: the tip deflection against
/// Euler-Bernoulli beam theory.
#[test]
fn cantilever_scene_matches_beam_theory() {
    let dir = temp_dir("beam");
    let scene = dir.join("beam.toml");
    std::fs::write(
        &scene,
        r#"
[mesh]
generate = { kind = "beam", size = [100.0, 20.0, 20.0], cells = [20] }
units = "mm"
[[material]]
law = "neo_hookean"
params = { E = 5e5, nu = 0.3 }
density = 1000.0
[[fix]]
plane = { point = [0, 0, 0], normal = [1, 0, 0] }
[loads]
gravity = [0, 0, -9.81]
[damping]
mass = 60.0
[solver]
integrator = "velocity_verlet"
duration = 0.4
[output]
dir = "out"
every = 1000
"#,
    )
    .unwrap();
    let out = dir.join("out");
    let (ok, stdout, err) = heml(&["run", scene.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(stdout.contains("400") || stdout.contains("done:"), "{stdout}");
    let frames = frames(&out);
    let rest = positions(&frames[0].1);
    let x = positions(&frames.last().unwrap().1);
    let clamped: Vec<usize> = (0..rest.len()).filter(|&i| rest[i].x == 0.0).collect();
    assert!(!clamped.is_empty() && clamped.iter().all(|&i| x[i] == rest[i]));
    let tip: Vec<usize> = (0..rest.len()).filter(|&i| (rest[i].x - 0.1).abs() < 1e-12).collect();
    let sag = -tip.iter().map(|&i| x[i].z - rest[i].z).sum::<f64>() / tip.len() as f64;
    // Euler-Bernoulli: q L^4 / (8 E I) = 1.5 rho g L^4 / (E h^2) = 7.36 mm (7 % of L:
    // geometric nonlinearity is second order). Shear (Timoshenko) adds 4 % at h/L = 0.2;
    // linear tets split six per cell, two cells through the thickness, are too stiff
    // in bending (measured ratio 0.82; 0.98 with the 24-tet split). Band: [0.6, 1.1].
    let beam = 1.5 * 1000.0 * 9.81 * 0.1f64.powi(4) / (5e5 * 0.02f64.powi(2));
    let ratio = sag / beam;
    assert!((0.6..1.1).contains(&ratio), "tip sag {sag} m, beam theory {beam} m");
    // settled: alpha = 60/s damps the fundamental (about 55 rad/s) to e^-12 by 0.4 s
    let rows = csv_rows(&out, false);
    let last = rows.last().unwrap();
    assert!(last[2] < 1e-6 * last[3], "kinetic {} vs elastic {}", last[2], last[3]);
    let weight = 0.1 * 0.02 * 0.02 * 1000.0 * 9.81;
    assert!((last[9] - weight).abs() < 1e-3 * weight, "{last:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_blow_up_stops_with_step_and_node_and_keeps_the_last_good_frame() {
    let dir = temp_dir("nan");
    let scene = dir.join("nan.toml");
    // dt 300 times the stable estimate (1.5 ms) with the check switched off
    std::fs::write(
        &scene,
        r#"
[mesh]
generate = { kind = "box", size = [0.02, 0.02, 0.02], cells = [2, 2, 2] }
[[material]]
law = "neo_hookean"
params = { E = 3e3, nu = 0.45 }
[[fix]]
plane = { point = [0, 0, 0], normal = [1, 0, 0] }
[loads]
gravity = [0, 0, -9.81]
[solver]
dt = 0.5
duration = 100.0
dt_policy = "ignore"
[output]
every = 1
"#,
    )
    .unwrap();
    let out = dir.join("out");
    let (ok, _, err) = heml(&["run", scene.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(!ok, "the run must fail");
    assert!(!err.contains("panicked"), "{err}");
    let step: u64 = err
        .split("step ")
        .nth(1)
        .and_then(|s| s.split(':').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no step in: {err}"));
    assert!(err.contains("at node "), "{err}");
    assert!(err.contains("non-finite") || err.contains("diverging"), "{err}");
    // one frame per good step (every = 1): steps 0..step-1, the last one named
    let frames = frames(&out);
    assert_eq!(frames.len() as u64, step, "{err}");
    let last = &frames.last().unwrap().1;
    assert!(err.contains(&last.display().to_string()), "{err}");
    assert!(positions(last).iter().all(|p| p.iter().all(|c| c.is_finite())));
    // the last row is the last good state: a state is accepted only when its
    // positions, velocities and forces are finite, so its energies are finite too
    csv_rows(&out, true);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_refused_dt_writes_nothing_and_an_unknown_key_names_line_and_suggestion() {
    let dir = temp_dir("bad");
    let scene = dir.join("bad.toml");
    let good = "[mesh]
generate = { kind = \"box\", size = [0.02, 0.02, 0.02], cells = [1, 1, 1] }
                [[material]]
law = \"neo_hookean\"
params = { E = 3e3, nu = 0.45 }
";
    std::fs::write(
        &scene,
        format!(
            "{good}densty = 1000.0
[solver]
duration = 0.1
"
        ),
    )
    .unwrap();
    let (ok, _, err) = heml(&["run", scene.to_str().unwrap(), "--out", dir.join("o").to_str().unwrap()]);
    assert!(!ok);
    assert!(err.contains("bad.toml:6:"), "line of the unknown key: {err}");
    assert!(err.contains("did you mean `density`?"), "{err}");
    std::fs::write(
        &scene,
        format!(
            "{good}[solver]
dt = 1.0
duration = 2.0
dt_policy = \"refuse\"
"
        ),
    )
    .unwrap();
    let (ok, _, err) = heml(&["run", scene.to_str().unwrap(), "--out", dir.join("o").to_str().unwrap()]);
    assert!(!ok);
    assert!(
        err.contains("exceeds the stable estimate") && err.contains("[solver]"),
        "{err}"
    );
    assert!(!dir.join("o").exists(), "a refused run writes nothing");
    // --duration: refused by the flag's name, and a refusal about the duration says
    // the flag set it (not the scene's line)
    let out = dir.join("o");
    let run = |d: &str| heml(&["run", scene.to_str().unwrap(), "--out", out.to_str().unwrap(), d]);
    let (ok, _, err) = run("--duration=-1");
    assert!(
        !ok && err.contains("--duration -1: expected a finite number of seconds > 0"),
        "{err}"
    );
    std::fs::write(&scene, format!("{good}[solver]\nduration = 0.1\n")).unwrap();
    let (ok, _, err) = run("--duration=1e30");
    assert!(
        !ok && err.contains("above max_steps") && err.contains("from --duration"),
        "{err}"
    );
    assert!(!out.exists(), "a refused run writes nothing");
    // a non-ASCII letter before a key of a malformed inline table: an error with the
    // line (the key lookup of the message used to cut the letter and panic)
    let accent = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../heml-core/tests/fuzz_seeds/repro_key_after_accent.toml"
    );
    let (ok, _, err) = heml(&["run", accent, "--out", out.to_str().unwrap()]);
    assert!(
        !ok && err.contains("repro_key_after_accent.toml:6") && !err.contains("panicked"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The whole demo's output (frames compressed by default) stays under 25 MB: it was
/// 79 MB for 62 uncompressed base64 frames.
#[test]
fn the_demo_writes_less_than_25_mb() {
    let dir = temp_dir("demo-size");
    let out = dir.join("out");
    let (ok, _, err) = heml(&["demo", "--out", out.to_str().unwrap(), "--quiet"]);
    assert!(ok, "{err}");
    let files: Vec<_> = std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().path()).collect();
    let total: u64 = files.iter().map(|p| std::fs::metadata(p).unwrap().len()).sum();
    let frames = files
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "vtu"))
        .count();
    assert!(frames >= 50, "{frames} frames");
    assert!(total < 25 << 20, "{frames} frames, {total} bytes");
    std::fs::remove_dir_all(&dir).unwrap();
}
