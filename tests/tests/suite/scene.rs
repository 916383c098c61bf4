//! Scene files: parsing, strict errors with lines and suggestions, unit conversion,
//! selections, per-region materials, and running the example scene.

use std::path::{Path, PathBuf};

use heml::io::{read_pvd, write_mesh};
use heml::prelude::*;
use heml::scene::Scene;

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

/// Builds need the registries of the member crates linked (the facade does it).
fn link() {
    let _ = (heml::materials_list(), heml::integrators_list());
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("heml-scene-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

const BASE: &str = r#"
[mesh]
generate = { kind = "box", size = [0.02, 0.02, 0.02], cells = [2, 2, 2] }

[[material]]
law = "neo_hookean"
params = { E = 3e3, nu = 0.45 }

[solver]
duration = 0.01
"#;

fn err_of(text: &str) -> String {
    link();
    match Scene::from_toml_str(text, ".").and_then(|s| s.build()) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn example_scene_parses_builds_and_runs_at_reduced_duration() {
    link();
    let mut scene = Scene::from_file(scenes_dir().join("example.toml")).unwrap();
    assert_eq!(scene.solver.integrator, "symplectic_euler");
    assert_eq!(scene.materials[0].prony.len(), 1);
    assert_eq!(scene.loads.nodal.len(), 1);
    let dir = temp_dir("example");
    scene.output.dir = Some(dir.to_string_lossy().into_owned());
    scene.solver.duration = 0.04;
    let mut sim = scene.build().unwrap();
    // mm -> m and the translation: the beam spans x in [0, 0.1], y in [-0.01, 0.01]
    let (lo, hi) = sim.system.mesh().bounding_box();
    assert!(
        (hi.x - 0.1).abs() < 1e-15 && (lo.y + 0.01).abs() < 1e-15,
        "{lo:?} {hi:?}"
    );
    // frame_interval = 0.02 s rounds to whole steps of the stable dt
    assert_eq!(sim.frame_every, (0.02 / sim.dt).round() as u64);
    assert!(sim.dt <= sim.system.stable_dt());
    let summary = sim.run(|_| {}).unwrap();
    assert!((summary.time - 0.04).abs() < 1e-12);
    let frames = read_pvd(&dir.join("frames.pvd")).unwrap();
    assert_eq!(frames.len(), summary.frames);
    assert!(frames.len() >= 3, "t = 0, 0.02, 0.04");
    let csv = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    assert!(csv.starts_with(heml::scene::CSV_HEADER));
    // the prescribed end moved sideways by r(0.04) * 1 cm with the smooth ramp
    let s = 0.04 / 0.5;
    let expected = 0.01 * s * s * (3.0 - 2.0 * s);
    let p = &sim.system.constraints().prescribed[0];
    let i = p.node;
    let uy = sim.system.positions()[i].y - sim.system.rest_positions()[i].y;
    assert!((uy - expected).abs() < 1e-15, "{uy} vs {expected}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn demo_scene_parses_and_builds() {
    link();
    let scene = Scene::from_file(scenes_dir().join("demo.toml")).unwrap();
    assert_eq!(scene.output.dir.as_deref(), Some("heml-demo-output"));
    let sim = scene.build().unwrap();
    // 8 x 6 x 5 cm at 5 mm cells: 17 x 13 x 11 nodes; the clamped face has 13 x 11,
    // the tool patch 3 x 3
    assert_eq!(sim.system.mesh().n_nodes(), 17 * 13 * 11);
    assert_eq!(sim.system.constraints().fixed.len(), 13 * 11);
    assert_eq!(sim.system.constraints().prescribed.len(), 9);
    assert!((sim.system.total_mass() - 0.24).abs() < 1e-12);
    assert!(sim.warnings.is_empty(), "{:?}", sim.warnings);
}

#[test]
fn unknown_keys_are_errors_with_line_and_suggestion() {
    let text = BASE.replace("[solver]", "[solver]\ndurration = 1.0");
    let e = err_of(&text);
    assert!(e.starts_with("<scene>:10:"), "{e}");
    assert!(
        e.contains("unknown field `durration`") && e.contains("did you mean `duration`?"),
        "{e}"
    );
    // in an inline table, and an unknown enum value
    let e = err_of(&BASE.replace("cells = [2, 2, 2]", "cells = [2, 2, 2], splitt = \"six\""));
    assert!(e.contains("<scene>:3:") && e.contains("did you mean `split`?"), "{e}");
    let e = err_of(&format!(
        "{BASE}[[prescribe]]\nnodes = [1]\ndisplacement = [0, 0, 0.001]\nramp = {{ kind = \"smoth\", duration = 1 }}\n"
    ));
    assert!(e.contains("<scene>:14:") && e.contains("did you mean `smooth`?"), "{e}");
    // a top-level typo
    let e = err_of(&format!("{BASE}[dampng]\nmass = 1.0\n"));
    assert!(e.contains("did you mean `damping`?"), "{e}");
}

/// Huge and tiny numbers in messages are written as 1e300, not as the 301 digits
/// Rust's `{}` gives an `f64` (`HemlError`'s message compacts them).
#[test]
fn huge_and_tiny_numbers_in_messages_stay_short() {
    for (from, to, shown) in [
        ("duration = 0.01", "duration = -1e300", "duration = -1e300 must be"),
        ("E = 3e3", "E = -1e300", "E = -1e300 must be"),
        (
            "duration = 0.01",
            "duration = 0.01\ndt = -1e-300",
            "dt = -1e-300 must be",
        ),
    ] {
        let e = err_of(&BASE.replace(from, to));
        assert!(e.contains(shown) && e.len() < 300, "{e}");
    }
}

#[test]
fn unknown_law_integrator_and_parameter_names_list_the_known_ones() {
    let e = err_of(&BASE.replace("neo_hookean", "neo_hokean"));
    assert!(e.contains("[[material]] #1") && e.contains(":5:"), "{e}");
    assert!(
        e.contains("did you mean 'neo_hookean'") && e.contains("mooney_rivlin"),
        "{e}"
    );
    let e = err_of(&BASE.replace("[solver]", "[solver]\nintegrator = \"verlet\""));
    assert!(
        e.contains("[solver]") && e.contains("velocity_verlet") && e.contains("explicit_euler"),
        "{e}"
    );
    let e = err_of(&BASE.replace("nu = 0.45", "nuu = 0.45"));
    assert!(e.contains("did you mean 'nu' for 'nuu'?"), "{e}");
}

#[test]
fn selections_that_select_nothing_are_named() {
    let text = format!(
        "{BASE}[[fix]]\nplane = {{ point = [0, 0, 0], normal = [1, 0, 0] }}\n\
         [[fix]]\nbox = {{ min = [1, 1, 1], max = [2, 2, 2] }}\n"
    );
    let e = err_of(&text);
    assert!(e.contains("<scene>:13: [[fix]] #2 (box) selects no node"), "{e}");
    let e = err_of(&format!("{BASE}[[fix]]\ntag = 7\n"));
    assert!(e.contains("[[fix]] #1 (tag)") && e.contains("no tet has tag 7"), "{e}");
    let e = err_of(&format!("{BASE}[[fix]]\nnodes = [1]\ntag = 0\n"));
    assert!(e.contains("several selectors (nodes, tag)"), "{e}");
    let e = err_of(&format!(
        "{BASE}[[loads.nodal]]\nplane = {{ point = [0, 0, 0.5], normal = [0, 0, 1] }}\nforce = [0, 0, 1]\n"
    ));
    assert!(e.contains("[[loads.nodal]] #1 (plane) selects no node"), "{e}");
}

#[test]
fn units_scale_the_mesh_and_selections_and_loads_act_in_metres() {
    link();
    let dir = temp_dir("units");
    // a 20 mm cube written in millimetres
    let cube = heml::mesh::generate::box_mesh([20.0; 3], [2, 2, 2], heml::mesh::generate::HexSplit::Six).unwrap();
    write_mesh(&dir.join("cube.msh"), &cube).unwrap();
    let text = BASE.replace(
        "generate = { kind = \"box\", size = [0.02, 0.02, 0.02], cells = [2, 2, 2] }",
        "file = \"cube.msh\"\nunits = \"mm\"\ntranslate = [0.0, 0.0, 1.0]",
    ) + "[[fix]]\nplane = { point = [0, 0, 1.0], normal = [0, 0, 1] }\n\
         [[loads.nodal]]\nbox = { min = [0, 0, 1.02], max = [0.02, 0.02, 1.02] }\nforce = [0, 0, -0.9]\n";
    let sim = Scene::from_toml_str(&text, &dir).unwrap().build().unwrap();
    let (lo, hi) = sim.system.mesh().bounding_box();
    assert!(
        (hi - lo - Vec3::repeat(0.02)).norm() < 1e-15 && lo.z == 1.0,
        "{lo:?} {hi:?}"
    );
    // volume 8e-6 m3 at 1000 kg/m3
    assert!((sim.system.total_mass() - 8e-3).abs() < 1e-15);
    assert_eq!(sim.system.constraints().fixed.len(), 9);
    // the top face has 9 nodes sharing 0.9 N
    let f = sim.system.nodal_forces();
    assert_eq!(f.len(), 9);
    assert!(f.iter().all(|(_, v)| (v.z + 0.1).abs() < 1e-15));
    // scale = 0.001 is the same; both at once is an error
    let scaled = text.replace("units = \"mm\"", "scale = 0.001");
    let sim2 = Scene::from_toml_str(&scaled, &dir).unwrap().build().unwrap();
    assert_eq!(sim2.system.mesh().nodes(), sim.system.mesh().nodes());
    let both = text.replace("units = \"mm\"", "units = \"mm\"\nscale = 0.001");
    let e = Scene::from_toml_str(&both, &dir)
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(e.contains("`scale` or `units`, not both"), "{e}");
    // a missing mesh file names the path
    let e = err_of(&text.replace("cube.msh", "nowhere.msh"));
    assert!(e.contains("nowhere.msh"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn per_region_materials_follow_the_mesh_tags() {
    link();
    let dir = temp_dir("regions");
    // two 1 cm cubes side by side, tagged 1 (x < 1 cm) and 2
    let m =
        heml::mesh::generate::box_mesh([0.02, 0.01, 0.01], [2, 1, 1], heml::mesh::generate::HexSplit::Five).unwrap();
    let tags: Vec<i32> = (0..m.n_tets())
        .map(|t| {
            if m.tet_points(t).iter().map(|p| p.x).sum::<f64>() < 0.04 {
                1
            } else {
                2
            }
        })
        .collect();
    let nodes = m.nodes().to_vec();
    let tets: Vec<[usize; 4]> = m.tets().iter().map(|t| t.map(|i| i as usize)).collect();
    let tagged = TetMesh::with_tags(nodes, tets, tags).unwrap();
    write_mesh(&dir.join("two.vtu"), &tagged).unwrap();
    let text = r#"
[mesh]
file = "two.vtu"
[[material]]
tag = 2
law = "mooney_rivlin"
params = { c10 = 1e3, c01 = 2e2, kappa = 5e4 }
density = 2000.0
[[material]]
law = "neo_hookean"
params = { E = 3e3, nu = 0.45 }
density = 1000.0
[[fix]]
tag = 1
[solver]
duration = 0.01
"#;
    let sim = Scene::from_toml_str(text, &dir).unwrap().build().unwrap();
    let regions = sim.system.regions();
    assert_eq!(regions.len(), 2);
    let by_tag = |t: Option<i32>| regions.iter().find(|r| r.tag() == t).unwrap();
    assert_eq!(by_tag(Some(2)).material().name(), "mooney_rivlin");
    assert_eq!(by_tag(None).material().name(), "neo_hookean");
    assert_eq!(by_tag(Some(2)).field().n_tets(), 5);
    assert_eq!(by_tag(None).field().n_tets(), 5);
    // 1e-6 m3 at 1000 and 1e-6 m3 at 2000 kg/m3
    assert!((sim.system.total_mass() - 3e-3).abs() < 1e-15);
    // `tag = 1` fixes the nodes of the first cube: its 8 corners (five-tet split)
    assert_eq!(sim.system.constraints().fixed.len(), 8);

    // edited parameters reach the running system's matching region (by tag), and
    // only it; the state stays
    let mut scene = Scene::from_toml_str(text, &dir).unwrap();
    let mut sim = scene.build().unwrap();
    sim.out_dir = dir.join("out");
    let ten = |p: &heml::scene::Progress| {
        if p.step >= 10 {
            std::ops::ControlFlow::Break(())
        } else {
            std::ops::ControlFlow::Continue(())
        }
    };
    assert!(sim.run_until(ten).unwrap().stopped);
    let (x, t) = (sim.system.positions().to_vec(), sim.system.time());
    let values = |sim: &heml::scene::Simulation, tag| {
        let r = sim.system.regions().iter().find(|r| r.tag() == tag).unwrap();
        r.material().param_values()
    };
    let neo = values(&sim, None);
    scene.materials[0].params.set("c10", 4e3);
    scene.update_laws(&mut sim.system, &[0]).unwrap();
    assert_eq!(values(&sim, Some(2))[0], 4e3);
    assert_eq!(values(&sim, None), neo);
    assert_eq!((sim.system.positions(), sim.system.time()), (&x[..], t));
    // bad values and entries are errors naming the entry; nothing changes
    scene.materials[0].params.set("c10", -1.0);
    let e = scene.update_laws(&mut sim.system, &[1, 0]).unwrap_err().to_string();
    assert!(e.contains("[[material]] #1") && e.contains("c10"), "{e}");
    assert_eq!(values(&sim, Some(2))[0], 4e3);
    assert_eq!(values(&sim, None), neo);
    let e = scene.update_laws(&mut sim.system, &[2]).unwrap_err().to_string();
    assert!(e.contains("no [[material]] #3"), "{e}");
    // two untagged materials are an error naming the second
    let e = err_of(&text.replace("tag = 2\n", "").replace("two.vtu", "x.vtu"));
    assert!(e.contains("x.vtu"), "{e}");
    let two_untagged = text.replace("tag = 2\n", "");
    let e = Scene::from_toml_str(&two_untagged, &dir)
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(e.contains("[[material]] #2") && e.contains("without `tag`"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A 2 × 1 × 1 cm bar (4 × 2 × 2 cells) with its nodes in a random order, as a
/// mesher might write them, saved as `bar.msh` in `dir`; returns the mesh as read back.
fn shuffled_bar(dir: &Path) -> TetMesh {
    use heml::mesh::generate::{box_mesh, HexSplit};
    use heml::mesh::reorder::Permutation;
    use rand::seq::SliceRandom;
    let m = box_mesh([0.02, 0.01, 0.01], [4, 2, 2], HexSplit::Six).unwrap();
    let mut order: Vec<usize> = (0..m.n_nodes()).collect();
    order.shuffle(&mut heml_tests::rng(17));
    let shuffled = m
        .renumbered(&Permutation::from_new_to_old(order), &Permutation::identity(m.n_tets()))
        .unwrap();
    let path = dir.join("bar.msh");
    write_mesh(&path, &shuffled).unwrap();
    let written = heml::io::read_mesh(&path).unwrap().0;
    assert_eq!(written.nodes(), shuffled.nodes());
    written
}

/// The bar clamped at x = 0 and pulled at x = 2 cm, both by explicit (file) node ids.
fn bar_scene(mesh: &TetMesh, out: &Path, renumber: bool, pull: f64) -> String {
    let ids = |x: f64| -> Vec<usize> {
        (0..mesh.n_nodes())
            .filter(|&i| (mesh.nodes()[i].x - x).abs() < 1e-9)
            .collect()
    };
    format!(
        r#"
[mesh]
file = "bar.msh"
renumber = {renumber}
[[material]]
law = "neo_hookean"
params = {{ E = 3e3, nu = 0.45 }}
[[fix]]
nodes = {:?}
[[loads.nodal]]
nodes = {:?}
force = [{pull}, 0.0, -0.01]
[solver]
duration = 0.01
dt = 2.5e-4
[output]
dir = "{}"
every = 10
"#,
        ids(0.0),
        ids(0.02),
        out.display()
    )
}

/// Positions of the system's nodes in the file's numbering.
fn file_positions(sim: &heml::scene::Simulation) -> Vec<Vec3> {
    match &sim.node_order {
        Some(p) => p.unapply(sim.system.positions()),
        None => sim.system.positions().to_vec(),
    }
}

/// `[mesh] renumber` reorders the nodes internally only: selections by id, final
/// positions per id and the VTU frames are those of the file's numbering.
#[test]
fn renumbering_changes_the_internal_order_only() {
    use heml::io::vtu;
    link();
    let dir = temp_dir("renumber");
    let mesh = shuffled_bar(&dir);
    let run = |renumber: bool| {
        let out = dir.join(format!("out-{renumber}"));
        let text = bar_scene(&mesh, &out, renumber, 0.05);
        let mut sim = Scene::from_toml_str(&text, &dir).unwrap().build().unwrap();
        let summary = sim.run(|_| {}).unwrap();
        assert_eq!(summary.steps, 40);
        (sim, out, summary.frames)
    };
    let (renumbered, out_r, frames) = run(true);
    let (plain, out_p, _) = run(false);

    // the shuffled order is not the Morton order: renumbering happened, and the
    // renumbered system's rest positions are the file's in another order
    let order = renumbered.node_order.as_ref().expect("the shuffled mesh is renumbered");
    assert!(order.new_to_old.iter().enumerate().any(|(i, &o)| i != o));
    assert!(plain.node_order.is_none());
    assert_ne!(renumbered.system.rest_positions(), mesh.nodes());
    assert_eq!(order.unapply(renumbered.system.rest_positions()), mesh.nodes());
    assert_eq!(plain.system.rest_positions(), mesh.nodes());

    // Same motion per file id. The two systems add the same force contributions at
    // each node, possibly in another order (the force blocks number their nodes
    // following the node ids), so they may differ by round-off only: ~1e-16 relative
    // per force evaluation, amplified mildly over 40 stable steps. The free end moves
    // by ~4 mm, so 1e-12 of the 2 cm bar is far above round-off and far below any
    // real difference (a load or clamp on the wrong nodes changes positions by
    // millimetres here).
    let size = 0.02;
    let (a, b) = (file_positions(&renumbered), file_positions(&plain));
    let moved = a
        .iter()
        .zip(mesh.nodes())
        .map(|(x, p)| (x - p).norm())
        .fold(0.0, f64::max);
    assert!(moved > 1e-6, "the load should move the bar: {moved}");
    let diff = heml_tests::max_diff(&a, &b);
    assert!(diff <= 1e-12 * size, "positions differ by {diff:e} m");
    // the clamp holds the file's x = 0 nodes
    for (i, p) in mesh.nodes().iter().enumerate().filter(|(_, p)| p.x < 1e-9) {
        assert_eq!(a[i], *p, "file node {i}");
    }

    // the frames are in file order: frame 0 is the file's mesh exactly, the last
    // frames of both runs agree, with the file's connectivity
    let file_tets: Vec<[usize; 4]> = mesh.tets().iter().map(|t| t.map(|i| i as usize)).collect();
    let first = vtu::read(&out_r.join("frame_00000.vtu")).unwrap();
    assert_eq!(first.nodes, mesh.nodes());
    assert_eq!(first.tets, file_tets);
    assert_eq!(first.tags, mesh.tags());
    let last = format!("frame_{:05}.vtu", frames - 1);
    let (lr, lp) = (
        vtu::read(&out_r.join(&last)).unwrap(),
        vtu::read(&out_p.join(&last)).unwrap(),
    );
    assert_eq!(lr.tets, file_tets);
    assert_eq!(lp.tets, file_tets);
    assert!(heml_tests::max_diff(&lr.nodes, &lp.nodes) <= 1e-12 * size);
    assert!(
        heml_tests::max_diff(&lr.nodes, &a) == 0.0,
        "the last frame is the final state"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Messages about nodes name them by their file ids, at run time and at build time.
#[test]
fn renumbered_scenes_name_nodes_by_file_id() {
    link();
    let dir = temp_dir("renumber-errors");
    let mesh = shuffled_bar(&dir);
    let text = bar_scene(&mesh, &dir.join("out"), true, 0.05);
    let order = Scene::from_toml_str(&text, &dir)
        .unwrap()
        .build()
        .unwrap()
        .node_order
        .unwrap();
    // a free file node whose internal id differs (the message could not pass by luck)
    let k = (0..mesh.n_nodes())
        .find(|&i| mesh.nodes()[i].x > 1e-9 && order.old_to_new[i] != i)
        .unwrap();

    // 1e308 N on node k alone: its velocity overflows in the first step, so k is
    // the first and only non-finite node
    let blow_up = format!("{text}[[loads.nodal]]\nnodes = [{k}]\nforce = [0.0, 0.0, 1e308]\n");
    let mut sim = Scene::from_toml_str(&blow_up, &dir).unwrap().build().unwrap();
    let e = sim.run(|_| {}).unwrap_err().to_string();
    assert!(
        e.contains("step 1: non-finite") && e.contains(&format!(" at node {k} ")),
        "{e}"
    );

    let both = format!(
        "{text}[[prescribe]]\nnodes = [{k}]\ndisplacement = [0.0, 0.0, 0.001]\nramp = {{ kind = \"step\" }}\n\
         [[fix]]\nnodes = [{k}]\n"
    );
    let e = err_of_in(&both, &dir);
    assert!(
        e.contains(&format!("[[prescribe]] #1: node {k} is already fixed by")) && e.contains("[[fix]] #2"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Builds and runs a scene text (paths relative to the working folder) to its end.
fn run_text(text: &str) -> heml::scene::RunSummary {
    Scene::from_toml_str(text, ".")
        .unwrap()
        .build()
        .unwrap()
        .run(|_| {})
        .unwrap()
}

fn err_of_in(text: &str, dir: &Path) -> String {
    match Scene::from_toml_str(text, dir).and_then(|s| s.build()) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e.to_string(),
    }
}

/// `shared/meshes` of the mesh collection that sits next to the repository checkout
/// (`<workspace>/../shared/meshes`; in a git worktree one level further up), or
/// `$HEML_MESHES`. Panics with a clear message when absent: the tests that
/// need it must not pass silently.
fn shared_meshes() -> PathBuf {
    if let Some(dir) = std::env::var_os("HEML_MESHES") {
        return PathBuf::from(dir);
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let candidates = [root.join("../shared/meshes"), root.join("../../shared/meshes")];
    candidates.iter().find(|d| d.is_dir()).cloned().unwrap_or_else(|| {
        panic!(
            "this test needs the shared mesh collection: ../shared/meshes next to the checkout \
             (looked in {candidates:?}); set HEML_MESHES to its path"
        )
    })
}

#[test]
fn kidney_crush_and_release_at_default_settings() {
    link();
    let mut scene = Scene::from_file(scenes_dir().join("crush_kidney.toml")).unwrap();
    scene.mesh.file = Some(
        shared_meshes()
            .join("msh/gen_kidney_2k.msh")
            .to_string_lossy()
            .into_owned(),
    );
    // default solver settings: nothing but the duration in [solver]
    assert_eq!(scene.solver.dt, None);
    assert_eq!(scene.solver.dt_policy, None);
    assert_eq!(scene.solver.safety, None);
    assert_eq!(scene.solver.integrator, "symplectic_euler");
    let dir = temp_dir("crush");
    scene.output.dir = Some(dir.to_string_lossy().into_owned());
    scene.output.vtu = false;
    let mut sim = scene.build().unwrap();
    assert_eq!(
        sim.dt_policy,
        TimeStepPolicy::Adapt,
        "prescribed motion defaults to adapt"
    );
    let (lo, hi) = sim.system.mesh().bounding_box();
    let height = hi.x - lo.x;
    // the plate goes down to 10 % of the thickness: plate nodes start within 2 mm of
    // the top and move by 0.9 of the height
    let p = &sim.system.constraints().prescribed[0];
    assert!(
        (p.displacement.x + 0.9 * height).abs() < 1e-4 * height,
        "{:?}",
        p.displacement
    );
    let summary = sim.run(|_| {}).expect("the crush must finish with no NaN");
    eprintln!("kidney crush: {summary}");
    let min_j = summary.min_j.expect("the adaptive run reports min J");
    // really crushed (tets squeezed past inversion: the J0 extension pushes them
    // back), and the step went down
    assert!(min_j < 0.4, "min J {min_j}");
    assert!(summary.dt_range.0 < 0.5 * summary.dt_range.1, "{:?}", summary.dt_range);
    let csv = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    assert!(
        csv.lines().any(|l| l.split(',').nth(12) == Some("stiffness")),
        "no row limited by stiffness"
    );
    assert!(!csv.contains("NaN") && !csv.contains("inf"));
    // recovered: after the release and 2 s of damping at 20/s (e^-40 on the motion)
    // the organ is at rest. Measured 6.9e-13 m at most, 2e-11 of the height; bound
    // 1e-9 of it. (The issue's criterion was RMS < 1 % of the height; the runs
    // ended with nodes still jittering at 0.6 m/s, 4e-4 m off rest, while the
    // adaptive steps alternated two sizes to land on the CSV rows.)
    let u = sim.system.displacements();
    let rms = (u.iter().map(|d| d.norm_squared()).sum::<f64>() / u.len() as f64).sqrt();
    let largest = u.iter().map(|d| d.norm()).fold(0.0, f64::max);
    eprintln!(
        "kidney crush: min J {min_j:.3}, RMS displacement after release {:.3e} of the height",
        rms / height
    );
    assert!(
        largest < 1e-9 * height,
        "largest displacement {largest:e} m, height {height:e} m"
    );
    // stable neo-Hookean (physical through inversion, no J0 extension) crushed the
    // same way: it diverged at t = 0.67 s, when its first tets inverted, while the
    // adaptive estimate probed only upright states
    let mut snh = scene.clone();
    snh.materials[0].law = "stable_neo_hookean".into();
    let summary = snh
        .build()
        .unwrap()
        .run(|_| {})
        .expect("stable neo-Hookean's crush must finish");
    let min_j = summary.min_j.expect("adaptive");
    assert!(min_j < 0.0, "the crush inverts tets: min J {min_j}");
    assert!(summary.max_displacement < 1e-9 * height, "{summary}");
    // the same crush with the step fixed at the rest estimate (the old default) blows up
    scene.solver.dt_policy = Some(TimeStepPolicy::Warn);
    let e = scene.build().unwrap().run(|_| {}).unwrap_err().to_string();
    assert!(e.contains("non-finite") || e.contains("diverging"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The demo block (8 x 6 x 5 cm, clamped, gravity, a tool) as a scene text with the
/// given `[solver]` and `[output]` lines.
fn demo_block(solver: &str, output: &str) -> String {
    let demo = std::fs::read_to_string(scenes_dir().join("demo.toml")).unwrap();
    let head = demo.split("[solver]").next().unwrap();
    format!("{head}[solver]\n{solver}\n[output]\n{output}\n")
}

#[test]
fn a_blow_up_keeps_a_last_good_state_with_finite_forces() {
    link();
    let dir = temp_dir("blowup");
    // dt = 2e-2 s, ~40x the stable estimate, with the check off: blows up in a few steps
    let text = demo_block(
        "duration = 1.0\ndt = 2e-2\ndt_policy = \"ignore\"",
        &format!("dir = {:?}\nevery = 1", dir.to_string_lossy()),
    );
    let mut sim = Scene::from_toml_str(&text, ".").unwrap().build().unwrap();
    let e = sim.run(|_| {}).unwrap_err().to_string();
    assert!(e.contains("diverging") && e.contains("last good state"), "{e}");
    // the state kept — and saved as the last frame — has finite positions,
    // velocities and forces (the frame is written with the forces of that state)
    sim.system
        .compute_forces()
        .expect("the last good state has finite forces");
    let sys = &sim.system;
    assert!(sys.step_count() >= 1, "{e}");
    let finite = |a: &[Vec3]| a.iter().all(|v| v.iter().all(|c| c.is_finite()));
    assert!(finite(sys.positions()) && finite(sys.velocities()) && finite(sys.forces()));
    assert!(sys.energies().unwrap().total.is_finite());
    // and displacements of the order of the body, not the 1e12 m of a state taken
    // one step too late (a step may move a node by at most the body's diagonal,
    // 0.11 m here)
    let umax = sys.displacements().iter().map(|d| d.norm()).fold(0.0, f64::max);
    let (lo, hi) = sys.mesh().bounding_box();
    assert!(umax < (hi - lo).norm(), "max displacement {umax:e} m");
    let frames = read_pvd(&dir.join("frames.pvd")).unwrap();
    assert_eq!(frames.len() as u64, sys.step_count() + 1, "a frame per accepted step");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn energy_csv_is_appended_whole_rows_at_frame_boundaries() {
    link();
    let dir = temp_dir("csv");
    let text = format!(
        "{BASE}dt = 1e-4\n[output]\ndir = {:?}\nevery = 25\ncsv_every = 1\nvtu = false\n",
        dir.to_string_lossy()
    );
    let mut sim = Scene::from_toml_str(&text, ".").unwrap().build().unwrap();
    assert_eq!(sim.steps, 100);
    let s = sim.run(|_| {}).unwrap();
    let csv = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    // a row per step and one at t = 0, each complete, steps in order
    assert_eq!(rows.len(), 101);
    for (k, r) in rows.iter().enumerate() {
        let cols: Vec<&str> = r.split(',').collect();
        assert_eq!(cols.len(), 14, "{r}");
        assert_eq!(cols[1].parse::<u64>().unwrap(), k as u64);
        assert_eq!(cols[12], "fixed");
        assert_eq!(cols[13], "0", "an explicit step takes no CG iteration");
    }
    // appended, never rewritten: the bytes written are the file's length, in one
    // write for the header and one per frame boundary (t = 0 and every 25 steps),
    // not one per row — whereas rewriting the file at every frame would write
    // ~2.5x its length here and grow quadratically with the run
    assert_eq!(s.csv_bytes, csv.len() as u64);
    assert_eq!(s.csv_writes, 1 + 1 + 100 / 25);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_rerun_into_the_same_folder_leaves_only_its_own_frames() {
    link();
    let dir = temp_dir("rerun");
    let run = |steps: usize| {
        let text = format!(
            "{BASE}dt = 1e-4\n[output]\ndir = {:?}\nevery = 1\n",
            dir.to_string_lossy()
        )
        .replace("duration = 0.01", &format!("duration = {}", steps as f64 * 1e-4));
        let mut sim = Scene::from_toml_str(&text, ".").unwrap().build().unwrap();
        sim.run(|_| {}).unwrap();
    };
    let frames_on_disk = || {
        let mut n: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("frame_") && n.ends_with(".vtu"))
            .collect();
        n.sort();
        n
    };
    run(8);
    assert_eq!(frames_on_disk().len(), 9);
    // a file of the user's own is kept
    std::fs::write(dir.join("notes.txt"), "mine").unwrap();
    run(3);
    let listed = read_pvd(&dir.join("frames.pvd")).unwrap();
    assert_eq!(listed.len(), 4);
    assert_eq!(frames_on_disk().len(), 4, "{:?}", frames_on_disk());
    assert!(dir.join("notes.txt").exists());
    // an output folder that is a file: refused by name
    let file = dir.join("notes.txt");
    let text = format!("{BASE}[output]\ndir = {:?}\n", file.to_string_lossy());
    let e = match Scene::from_toml_str(&text, ".")
        .and_then(|s| s.build())
        .and_then(|mut s| s.run(|_| {}))
    {
        Ok(_) => panic!("an output folder that is a file must be refused"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("exists and is not a folder"), "{e}");
    // a dangling symbolic link in its place: named with its target (the error was
    // the system's bare "File exists")
    #[cfg(unix)]
    {
        let link = dir.join("gone");
        std::os::unix::fs::symlink(dir.join("no-such-folder"), &link).unwrap();
        let text = format!("{BASE}[output]\ndir = {:?}\n", link.to_string_lossy());
        let e = Scene::from_toml_str(&text, ".")
            .and_then(|s| s.build())
            .and_then(|mut s| s.run(|_| {}))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("is a symbolic link to") && e.contains("no-such-folder") && e.contains("[output] dir"),
            "{e}"
        );
        assert!(!dir.join("no-such-folder").exists());
    }
    // a run that writes nothing creates no folder
    let none = dir.join("none");
    let text = format!(
        "{BASE}[output]\ndir = {:?}\nvtu = false\ncsv = false\n",
        none.to_string_lossy()
    );
    run_text(&text);
    assert!(!none.exists(), "an empty output folder was created");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_run_plan_estimates_warns_and_refuses_naming_the_keys() {
    link();
    // 1e11 steps: refused before anything is built, naming the key
    let e = err_of(&BASE.replace("duration = 0.01", "duration = 1e5\ndt = 1e-6"));
    assert!(
        e.contains("<scene>:9: [solver]") && e.contains("max_steps = 100000000"),
        "{e}"
    );
    // raised limit, but a frame per step over 1e6 steps of a 27-node box: ~5 GB
    let text =
        BASE.replace("duration = 0.01", "duration = 100.1\ndt = 1e-4\nmax_steps = 2000000") + "[output]\nevery = 1\n";
    let e = err_of(&format!("{text}max_output_bytes = 1000000000\n"));
    assert!(e.contains("[output]") && e.contains("max_output_bytes = 1.0 GB"), "{e}");
    // under the hard limits, over the warning thresholds: built, with both warnings
    let sim = Scene::from_toml_str(&format!("{text}max_output_bytes = 100000000000\n"), ".")
        .unwrap()
        .build()
        .unwrap();
    let p = &sim.plan;
    assert_eq!((p.steps, p.frames, p.csv_rows), (1_001_000, 1_001_001, 1_001_001));
    assert!(
        p.warnings.iter().any(|w| w.contains("warn_steps = 1000000")),
        "{:?}",
        p.warnings
    );
    assert!(
        p.warnings.iter().any(|w| w.contains("warn_output_bytes")),
        "{:?}",
        p.warnings
    );
    // and the estimate matches what a run writes: within 10 % for uncompressed
    // frames (the XML header and the CSV's number widths vary), and an upper bound
    // within 3× for compressed ones: how well zlib does depends on the data, and
    // this 48-tet box barely deformed compresses far better than real frames (the
    // demo's: within 15 % of the bound)
    for (compression, range) in [("none", 0.9..1.1), ("zlib", 1.0..3.0)] {
        let dir = temp_dir(&format!("plan-{compression}"));
        let text = format!(
            "{BASE}dt = 1e-4\n[output]\ndir = {:?}\nevery = 10\ncompression = {compression:?}\n",
            dir.to_string_lossy()
        );
        let mut sim = Scene::from_toml_str(&text, ".").unwrap().build().unwrap();
        let plan = sim.plan.clone();
        assert!(plan.warnings.is_empty() && !plan.adaptive);
        let s = sim.run(|_| {}).unwrap();
        assert_eq!(plan.frames, s.frames as u64);
        let written: u64 = std::fs::read_dir(&dir)
            .unwrap()
            .map(|f| f.unwrap().metadata().unwrap().len())
            .sum();
        let ratio = plan.est_bytes as f64 / written as f64;
        assert!(
            range.contains(&ratio),
            "{compression}: estimated {} B, written {written} B",
            plan.est_bytes
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn scene_messages_name_the_key_and_line() {
    // scale = 1e300: the overflow is blamed on `scale`, not on a default tolerance
    let e = err_of(&BASE.replace("cells = [2, 2, 2] }", "cells = [2, 2, 2] }\nscale = 1e300"));
    assert!(
        e.contains("<scene>:2: [mesh]") && e.contains("check `scale` or `units`"),
        "{e}"
    );
    assert!(!e.contains("tolerance"), "{e}");
    // an empty output directory is named with its key (the run said only ": No such
    // file or directory")
    let e = err_of(&format!("{BASE}\n[output]\ndir = \"\"\n"));
    assert!(e.contains("[output]") && e.contains("dir = \"\" is empty"), "{e}");
    // a spring constant of zero: no stable estimate, and the message says why
    let spring = BASE.replace(
        "law = \"neo_hookean\"\nparams = { E = 3e3, nu = 0.45 }",
        "law = \"mass_spring\"\nparams = { k = 0.0 }",
    );
    let e = err_of(&spring);
    assert!(
        e.contains("<scene>:9: [solver]") && e.contains("no stiffness at rest"),
        "{e}"
    );
    // a wrong value type names its key (and its line)
    let e = err_of(&BASE.replace("E = 3e3", "E = \"1.0\""));
    assert!(
        e.contains("<scene>:7:") && e.contains("`E`: invalid type: string \"1.0\""),
        "{e}"
    );
    // a node both fixed and prescribed: both entries named, with their lines
    let e = err_of(&format!(
        "{BASE}[[fix]]\nnodes = [0, 1]\n[[prescribe]]\nnodes = [1]\ndisplacement = [0, 0, 0.001]\nramp = {{ kind = \"step\" }}\n"
    ));
    assert!(
        e.contains("<scene>:13: [[prescribe]] #1: node 1 is already fixed by <scene>:11: [[fix]] #1"),
        "{e}"
    );
    // a material tag the mesh does not have: the entry and its line
    let e = err_of(&BASE.replace("law = \"neo_hookean\"", "law = \"neo_hookean\"\ntag = 9"));
    assert!(
        e.contains("<scene>:5: [[material]] #1: tag = 9 has no tets (the mesh's tags are [0])"),
        "{e}"
    );
    // keyframes: one direction, increasing times
    let kf = |k: &str| format!("{BASE}[[prescribe]]\nnodes = [1]\nkeyframes = {k}\n");
    let e = err_of(&kf("[[1.0, 0, 0, 0.01], [2.0, 0.01, 0, 0]]"));
    assert!(
        e.contains("[[prescribe]] #1: keyframes: keyframe #1") && e.contains("one direction"),
        "{e}"
    );
    let e = err_of(&kf("[[1.0, 0, 0, 0.01], [1.0, 0, 0, 0]]"));
    assert!(e.contains("times must increase strictly"), "{e}");
    let e = err_of(&format!(
        "{BASE}[[prescribe]]\nnodes = [1]\ndisplacement = [0, 0, 0.01]\n"
    ));
    assert!(e.contains("`displacement` needs a `ramp`"), "{e}");
}

#[test]
fn hostile_scene_values_are_named_in_the_scene_words_with_their_lines() {
    // a repeated key names itself
    let e = err_of(&format!("{BASE}dt = 1e-4\ndt = 2e-4\n"));
    assert!(e.contains("duplicate key `dt`"), "{e}");
    // no keyframe at all: the expected row is [t, ux, uy, uz]
    let e = err_of(&format!("{BASE}[[prescribe]]\nnodes = [1]\nkeyframes = []\n"));
    assert!(
        e.contains("<scene>:11: [[prescribe]] #1: keyframes: at least one [t, ux, uy, uz]"),
        "{e}"
    );
    // density, Prony terms and the safety factor: the entry and its line
    let e = err_of(&BASE.replace("law = \"neo_hookean\"", "law = \"neo_hookean\"\ndensity = -1"));
    assert!(
        e.contains("<scene>:5: [[material]] #1: density = -1 must be a finite number > 0"),
        "{e}"
    );
    let e = err_of(&BASE.replace(
        "law = \"neo_hookean\"",
        "law = \"neo_hookean\"\nprony = [{ alpha = 0.3, tau = 0.0 }]",
    ));
    assert!(
        e.contains("<scene>:5: [[material]] #1: prony: Prony term 0: tau = 0"),
        "{e}"
    );
    let e = err_of(&format!("{BASE}safety = 2\n"));
    assert!(e.contains("<scene>:9: [solver]: safety = 2 must lie in (0, 1]"), "{e}");
    // a mesh file that is not there: the key as written and the path as resolved
    let e = err_of(
        &BASE
            .replace("[mesh]", "[mesh]\nfile = \"nope.msh\"")
            .replace("generate = ", "# generate = "),
    );
    assert!(
        e.contains("<scene>:2: [mesh]: file = \"nope.msh\": cannot read ./nope.msh"),
        "{e}"
    );
    // surface loads and their selections as the scene writes them, not Rust's debug text
    let load = |l: &str| format!("{BASE}[[surface_load]]\n{l}\n");
    let e = err_of(&load("pressure = nan\ntag = 0"));
    assert!(e.contains("surface load: pressure = NaN Pa is not finite"), "{e}");
    let e = err_of(&load("pressure = 100.0\nbbox = { min = [5, 5, 5], max = [6, 6, 6] }"));
    assert!(
        e.contains("the selection bbox = { min = [5, 5, 5], max = [6, 6, 6] } (m) contains no boundary face"),
        "{e}"
    );
}

#[test]
fn unreferenced_nodes_name_the_scene_key() {
    link();
    let dir = temp_dir("loose");
    // a one-tet mesh with a fifth node that no tet uses
    let mesh = dir.join("loose.node");
    std::fs::write(&mesh, "5 3 0 0\n0 0 0 0\n1 0.01 0 0\n2 0 0.01 0\n3 0 0 0.01\n4 1 1 1\n").unwrap();
    std::fs::write(dir.join("loose.ele"), "1 4 0\n0 0 1 2 3\n").unwrap();
    let text = "[mesh]\nfile = \"loose.node\"\n[[material]]\nlaw = \"neo_hookean\"\nparams = { E = 3e3, nu = 0.45 }\n[solver]\nduration = 0.01\n";
    let e = Scene::from_toml_str(text, &dir)
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("<scene>:1: [mesh]: 1 node(s) belong to no tet") && e.contains("ids 4"),
        "{e}"
    );
    assert!(
        e.contains("`pin_unreferenced = true` in [mesh]") && !e.contains(".pin_unreferenced()"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_killed_writer_leaves_no_temporary_for_the_next_run() {
    link();
    let dir = temp_dir("stale");
    // what a kill -9 between creating and renaming a frame leaves: an empty
    // temporary of a process that is gone (pid above Linux's pid_max)
    let stale = dir.join(".frame_00002.vtu.tmp-4194305-0");
    std::fs::write(&stale, b"").unwrap();
    let text = format!("{BASE}dt = 1e-3\n[output]\ndir = {:?}\n", dir.to_string_lossy());
    run_text(&text);
    if Path::new("/proc/self").exists() {
        assert!(!stale.exists(), "stale temporary kept");
    }
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
        .collect();
    assert!(
        leftovers.is_empty() || !Path::new("/proc/self").exists(),
        "{leftovers:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn keyframed_prescribed_motion_goes_down_and_back_up_adaptively() {
    link();
    let dir = temp_dir("keyframes");
    // press the top of the cube 4 mm down over 0.05 s, release by 0.1 s
    let text = format!(
        "{BASE}[[fix]]\nplane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}\n[[prescribe]]\n\
         plane = {{ point = [0, 0, 0.02], normal = [0, 0, 1] }}\n\
         keyframes = [[0.05, 0, 0, -0.004], [0.1, 0, 0, 0]]\n[damping]\nmass = 50.0\n[output]\ndir = {:?}\nvtu = false\n",
        dir.to_string_lossy()
    )
    .replace("duration = 0.01", "duration = 0.15");
    let scene = Scene::from_toml_str(&text, ".").unwrap();
    let mut sim = scene.build().unwrap();
    assert_eq!(sim.dt_policy, TimeStepPolicy::Adapt);
    let p = sim.system.constraints().prescribed[0].clone();
    assert_eq!(p.displacement, Vec3::new(0.0, 0.0, -0.004));
    let s = sim.run(|_| {}).unwrap();
    // back at rest: the plate returned, and the time is exact
    let i = p.node;
    assert!((sim.system.positions()[i] - sim.system.rest_positions()[i]).norm() < 1e-15);
    assert!((s.time - 0.15).abs() < 1e-12, "{}", s.time);
    let csv = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    // column 13 is `dt_reason` (after it: `cg_iterations`)
    let reasons: Vec<&str> = csv.lines().skip(1).map(|l| l.split(',').nth(12).unwrap()).collect();
    assert!(
        reasons.iter().all(|r| ["base", "stiffness", "recovering"].contains(r)),
        "{reasons:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn volumetric_keys_choose_the_nodal_formulation_per_material_or_for_all() {
    use heml::law::Volumetric;
    link();
    let scene = |material: &str, solver: &str| {
        format!(
            "[mesh]\ngenerate = {{ kind = \"box\", size = [0.02, 0.01, 0.01], cells = [2, 1, 1] }}\n\
             [[material]]\nlaw = \"neo_hookean\"\nparams = {{ E = 3e3, nu = 0.49 }}\n{material}\n\
             [[fix]]\nbox = {{ min = [0, 0, 0], max = [0, 0.01, 0.01] }}\n\
             [solver]\nduration = 0.001\n{solver}\n"
        )
    };
    let volumetric_of = |text: String| {
        let sim = Scene::from_toml_str(&text, ".").unwrap().build().unwrap();
        sim.system.regions()[0].material().volumetric()
    };
    assert_eq!(volumetric_of(scene("", "")), Volumetric::Element);
    assert_eq!(volumetric_of(scene("volumetric = \"nodal\"", "")), Volumetric::nodal());
    assert_eq!(
        volumetric_of(scene("", "volumetric = \"nodal\"\nvolumetric_stabilization = 0.5")),
        Volumetric::Nodal { stabilization: 0.5 }
    );
    assert_eq!(
        volumetric_of(scene("volumetric = \"patch\"\nvolumetric_stabilization = 0.2", "")),
        Volumetric::Patch {
            size: heml::force::patch_volume::DEFAULT_PATCH_SIZE,
            stabilization: 0.2
        }
    );
    // the material's own key wins over [solver]'s
    assert_eq!(
        volumetric_of(scene("volumetric = \"element\"", "volumetric = \"nodal\"")),
        Volumetric::Element
    );
    let e = err_of(&scene("volumetric = \"nodel\"", ""));
    assert!(e.contains("nodel") && e.contains("\"nodal\""), "{e}");
    let e = err_of(&scene("volumetric = \"nodal\"\nvolumetric_stabilization = -1.0", ""));
    assert!(e.contains("volumetric_stabilization = -1"), "{e}");
    let e = err_of(&scene("volumetric_stabilization = 0.2", ""));
    assert!(e.contains("volumetric = \"nodal\" or \"patch\" is not"), "{e}");
    let e = err_of(&scene("", "volumetric = \"nodal\"").replace(
        "law = \"neo_hookean\"\nparams = { E = 3e3, nu = 0.49 }",
        "law = \"mass_spring\"\nparams = { k = 10.0 }",
    ));
    assert!(e.contains("mass_spring") && e.contains("link law"), "{e}");
}

/// The example scene as a user runs it (`heml run scenes/example.toml`), to its end:
/// its cut at t = 0.3 s meets the sagged beam and notches it at x = 51 mm (the
/// blade once sat at the rest top, 2 cm above the sagged beam, and the documented
/// command failed there; the reduced-duration test above stops before the cut).
#[test]
fn example_scene_runs_to_its_end_and_its_cut_notches_the_sagged_beam() {
    link();
    let mut scene = Scene::from_file(scenes_dir().join("example.toml")).unwrap();
    let dir = temp_dir("example-full");
    scene.output.dir = Some(dir.to_string_lossy().into_owned());
    let mut sim = scene.build().unwrap();
    let before = sim.system.n_tets_alive();
    let summary = sim.run(|_| {}).unwrap();
    assert!((summary.time - scene.solver.duration).abs() < 1e-12 && !summary.stopped);
    let after = sim.system.n_tets_alive();
    // a notch, not a severed beam: some tets, far fewer than a cross-section's worth
    // times the beam's 20 cells
    assert!(after < before && before - after < before / 10, "{before} -> {after}");
    // every removed tet has a corner within one cell (5 mm) of the blade's x = 51 mm
    let removed: Vec<usize> = (0..before).filter(|&t| !sim.system.tet_alive(t)).collect();
    let rest = sim.system.rest_positions();
    for &t in &removed {
        let near = sim.system.mesh().tets()[t]
            .iter()
            .any(|&i| (rest[i as usize].x - 0.051).abs() <= 0.005 + 1e-12);
        assert!(near, "tet {t} removed away from the blade");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An adaptive run lands on its output times in equal steps: the step is constant
/// while the controller's is. It used to take full steps then a shorter last one,
/// so with a CSV row every base step it alternated two sizes, and that periodic
/// modulation pumped the modes it resonates with: a poked, damped body never came
/// to rest. Here a block poked by 6 mm and released: the step may change at most
/// once per controller check (20 steps).
#[test]
fn an_adaptive_run_lands_on_its_rows_without_pumping_the_tissue() {
    link();
    let text = r#"
[mesh]
generate = { kind = "box", size = [0.04, 0.03, 0.025], cells = [8, 6, 5], split = "six" }
[[material]]
law = "neo_hookean"
params = { E = 8.0e3, nu = 0.45 }
density = 1000.0
[[fix]]
plane = { point = [0.0, 0.0, 0.0], normal = [1.0, 0.0, 0.0] }
[[prescribe]]
box = { min = [0.015, 0.01, 0.025], max = [0.025, 0.02, 0.025] }
keyframes = [[0.1, 0.0, 0.0, -0.006], [0.2, 0.0, 0.0, 0.0]]
[damping]
mass = 20.0
[solver]
duration = 1.7
[output]
vtu = false
csv_every = 1
"#;
    let dir = temp_dir("adaptive-landing");
    let mut scene = Scene::from_toml_str(text, ".").unwrap();
    scene.output.dir = Some(dir.to_string_lossy().into_owned());
    let mut sim = scene.build().unwrap();
    assert_eq!(sim.dt_policy, TimeStepPolicy::Adapt);
    // every step's end time, from the progress callback
    let mut times = vec![0.0];
    let summary = sim.run(|p| times.push(p.time)).unwrap();
    let steps: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    // the controller decides at most once per check (20 steps); landing on a row
    // time no longer changes the step in between
    let changes = steps.windows(2).filter(|w| ((w[1] - w[0]) / w[0]).abs() > 1e-9).count();
    eprintln!("landing: {changes} step changes in {} steps; {summary}", steps.len());
    assert!(
        changes <= steps.len() / 20 + 1,
        "the step changed {changes} times in {} steps",
        steps.len()
    );
    // and back at rest after the 6 mm poke (measured 3.2e-10 m; this box's motion
    // settles either way, the kidney of `kidney_crush_and_release_at_default_settings`
    // did not: the step count above is the check that tells the two landings apart,
    // 8 changes against 309)
    assert!(summary.max_displacement < 1e-8, "{summary}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A link planted where the run writes `energy.csv` is replaced, not followed: the
/// file it points to keeps its contents (a plain create overwrote it with the CSV).
#[cfg(unix)]
#[test]
fn a_link_at_the_csv_path_is_not_followed() {
    link();
    let dir = temp_dir("csv-link");
    std::fs::create_dir_all(&dir).unwrap();
    let victim = dir.join("victim.txt");
    std::fs::write(&victim, "keep me").unwrap();
    std::os::unix::fs::symlink(&victim, dir.join("energy.csv")).unwrap();
    let mut scene = Scene::from_toml_str(&demo_block("duration = 0.001", "vtu = false"), ".").unwrap();
    scene.output.dir = Some(dir.to_string_lossy().into_owned());
    scene.build().unwrap().run(|_| {}).unwrap();
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep me");
    let csv = dir.join("energy.csv");
    assert!(!std::fs::symlink_metadata(&csv).unwrap().file_type().is_symlink());
    assert!(std::fs::read_to_string(&csv)
        .unwrap()
        .starts_with(heml::scene::CSV_HEADER));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `run_until` ends a run when its callback says so, after writing the state it
/// stopped at as a last frame and CSV row, and the summary says it stopped.
#[test]
fn a_run_stops_when_its_callback_says_so() {
    link();
    let dir = temp_dir("run-until");
    let mut scene = Scene::from_toml_str(&demo_block("duration = 1.0", "frame_interval = 0.5"), ".").unwrap();
    scene.output.dir = Some(dir.to_string_lossy().into_owned());
    let mut sim = scene.build().unwrap();
    let summary = sim
        .run_until(|p| {
            if p.step >= 25 {
                std::ops::ControlFlow::Break(())
            } else {
                std::ops::ControlFlow::Continue(())
            }
        })
        .unwrap();
    assert!(summary.stopped && summary.steps == 25, "{summary}");
    assert!(summary.to_string().starts_with("stopped early: 25 steps"), "{summary}");
    // frame 0 and the stopped state (the 0.5 s frame interval is far off)
    let frames = read_pvd(&dir.join("frames.pvd")).unwrap();
    assert_eq!(frames.len(), 2);
    assert!((frames[1].0 - summary.time).abs() < 1e-12, "{:?}", frames[1]);
    let csv = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    let last: f64 = csv.lines().last().unwrap().split(',').next().unwrap().parse().unwrap();
    assert!((last - summary.time).abs() < 1e-12);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The held (not free) nodes of a built scene by the file's ids, sorted.
fn held_file_ids(sim: &heml::scene::Simulation) -> Vec<usize> {
    let file_id = |internal: usize| sim.node_order.as_ref().map_or(internal, |p| p.new_to_old[internal]);
    let n = sim.system.positions().len();
    let mut held: Vec<usize> = (0..n).filter(|&i| !sim.system.is_free(i)).map(file_id).collect();
    held.sort_unstable();
    held
}

/// A mesh file's node set (an OpenSurgSim `.ply`'s boundary conditions) is a
/// selection: `node_set = "boundary_condition"` fixes exactly those nodes (by the
/// file's ids, whatever the internal renumbering), and a name the file lacks is an
/// error listing the file's sets (or saying it has none).
#[test]
fn node_sets_of_the_mesh_file_are_selections() {
    link();
    let dir = temp_dir("node-set");
    let mesh =
        heml::mesh::generate::box_mesh([0.04, 0.01, 0.01], [8, 2, 2], heml::mesh::generate::HexSplit::Six).unwrap();
    let end: Vec<usize> = (0..mesh.n_nodes()).filter(|&i| mesh.nodes()[i].x == 0.0).collect();
    assert_eq!(end.len(), 9);
    let ply = mesh.clone().with_node_set("boundary_condition", end.clone()).unwrap();
    write_mesh(&dir.join("body.ply"), &ply).unwrap();
    write_mesh(&dir.join("body.msh"), &mesh).unwrap();
    let scene = |file: &str, set: &str| {
        format!(
            "[mesh]\nfile = \"{file}\"\n[[material]]\nlaw = \"neo_hookean\"\nparams = {{ E = 3e3, nu = 0.45 }}\n\
             [[fix]]\nnode_set = \"{set}\"\n[loads]\ngravity = [0.0, 0.0, -9.81]\n[solver]\nduration = 0.02\n[output]\nvtu = false\ncsv = false\n"
        )
    };
    let mut sim = Scene::from_toml_str(&scene("body.ply", "boundary_condition"), &dir)
        .unwrap()
        .build()
        .unwrap();
    assert_eq!(held_file_ids(&sim), end);
    sim.run(|_| {}).unwrap();
    let x = file_positions(&sim);
    // held nodes stay at rest exactly; the free end sags under gravity
    assert!(end.iter().all(|&i| x[i] == mesh.nodes()[i]));
    let tip = (0..mesh.n_nodes()).find(|&i| mesh.nodes()[i].x == 0.04).unwrap();
    assert!(
        x[tip].z < mesh.nodes()[tip].z - 1e-6,
        "the tip did not sag: {:?}",
        x[tip]
    );

    let e = err_of_in(&scene("body.ply", "clamp"), &dir);
    assert!(
        e.contains("[[fix]]") && e.contains("node set 'clamp'") && e.contains("[\"boundary_condition\"]"),
        "{e}"
    );
    let e = err_of_in(&scene("body.msh", "boundary_condition"), &dir);
    assert!(e.contains("the mesh file has no node sets"), "{e}");
    let e = err_of_in(
        &scene("body.ply", "boundary_condition").replace("node_set", "tag = 0\nnode_set"),
        &dir,
    );
    assert!(e.contains("several selectors (tag, node_set)"), "{e}");
    // a Gmsh physical surface by its name (a file written by Gmsh 4.15.2: the unit
    // cube's face z = 0 is the group "clamp")
    let gmsh = Path::new(env!("CARGO_MANIFEST_DIR")).join("../heml-core/tests/data/gmsh_groups_v41.msh");
    let text = scene(gmsh.to_str().unwrap(), "clamp");
    let sim = Scene::from_toml_str(&text, &dir).unwrap().build().unwrap();
    let (cube, _) = heml::io::read_mesh(&gmsh).unwrap();
    let bottom: Vec<usize> = (0..cube.n_nodes())
        .filter(|&i| cube.nodes()[i].z.abs() < 1e-12)
        .collect();
    assert_eq!(held_file_ids(&sim), bottom);
    std::fs::remove_dir_all(&dir).unwrap();
}
