//! An organ simulation from a mesh file, as a scene: a kidney-shaped organ (a Gmsh
//! file in millimetres, `examples/data/gen_kidney_2k.msh`), its lower pole resting on
//! a support, sagging under its own weight. The scene is built through
//! `heml::scene::Scene` alone: the facade registers the built-in laws and
//! integrators itself.
//!
//! `cargo run --release --example organ_simulation`

use heml::prelude::*;

const SCENE: &str = r#"
[mesh]
file = "gen_kidney_2k.msh"
units = "mm"

[[material]]
law = "neo_hookean"
params = { E = 20e3, nu = 0.45 }
density = 1050.0

# the nodes within 5 mm of the lowest point (z = -54.7 mm) are held
[[fix]]
box = { min = [-1, -1, -1], max = [1, 1, -0.0497] }

[loads]
gravity = [0, 0, -9.81]

[damping]
mass = 40.0

[solver]
integrator = "symplectic_euler"
duration = 0.05

[output]
vtu = false
csv = false
"#;

fn main() -> heml::Result<()> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data");
    let scene = Scene::from_toml_str_named(SCENE, &dir, "organ_simulation.rs")?;
    let mut sim = scene.build()?;
    println!(
        "{} nodes, {} tets, dt {:.2e} s, {} steps",
        sim.system.mesh().n_nodes(),
        sim.system.mesh().n_tets(),
        sim.dt,
        sim.steps
    );
    let summary = sim.run(|_| {})?;
    println!("{summary}");
    let u = sim.system.displacements();
    assert!(u.iter().all(|d| d.iter().all(|c| c.is_finite())));
    // it sags: the mean vertical displacement is downwards, and nothing moved
    // farther than the free fall distance ½ g t² over the run (12 mm)
    let mean_z = u.iter().map(|d| d.z).sum::<f64>() / u.len() as f64;
    assert!(mean_z < 0.0, "mean vertical displacement {mean_z}");
    assert!(
        summary.max_displacement < 0.5 * 9.81 * 0.05f64.powi(2),
        "{}",
        summary.max_displacement
    );
    Ok(())
}

#[test]
fn organ_simulation() {
    main().unwrap();
}
