//! A haptic loop: a device thread at 1 kHz moves a capsule (a laparoscopic tip)
//! along a scripted palpation path over soft tissue, the simulation runs in real
//! time on its own thread, a display thread takes snapshots at 60 Hz; the device
//! records the force it feels and the loop's timing (p50/p99/max).
//!
//! The device never waits for the simulation: it renders, every millisecond, the
//! local model (force and stiffness around the tool's pose) the simulation
//! published with its newest state, and the report gives the device period, the
//! simulation rate, the model's age and its error.
//!
//! `cargo run --release --example haptic_loop` runs 0.2 s of device time on a
//! generated 6 × 6 × 3 cm block with symplectic Euler. `HEML_HAPTIC_LONG=1` runs 5 s on the kidney mesh
//! `msh/gen_kidney_20k.msh` of the shared mesh collection (`../shared/meshes`, or
//! `$HEML_MESHES`) with
//! symplectic Euler and backward Euler; `heml bench --haptic` measures the same.

use heml::integrators::{BackwardEuler, SymplecticEuler};
use heml::mesh::generate::{box_mesh, HexSplit};
use heml::prelude::*;
use heml::system::contact::{run_haptic_loop, ContactLaw, HapticOptions, Palpation};
use heml::system::Integrator;

/// Runs the loop for `seconds` of device time with `integrator`; returns the
/// largest tool force the simulation published.
fn palpate(mesh: TetMesh, integrator: &mut dyn Integrator, explicit: bool, seconds: f64) -> heml::Result<f64> {
    let mut sys = Palpation::tissue(mesh)?;
    // a 4 mm capsule, 2 cm long, palpates the highest surface point
    let law = ContactLaw {
        stiffness: 200.0,
        damping: 0.002,
    };
    let (tool, path) = Palpation::on_top(&mut sys, 0.004, 0.01, law, seconds.min(1.0))?;
    let opts = if explicit {
        HapticOptions::explicit(&sys, seconds)
    } else {
        HapticOptions {
            duration: seconds,
            ..HapticOptions::default()
        }
    };
    let report = run_haptic_loop(&mut sys, integrator, tool, |t| path.at(t), &opts)?;
    println!("{:<17} {} tets: {report}", integrator.name(), sys.mesh().n_tets());
    // the device renders the simulation's local model: finite, bounded, and felt
    assert!(report
        .forces
        .iter()
        .all(|(_, f)| f.iter().all(|c| c.is_finite()) && f.norm() <= opts.max_force));
    let felt = report.forces.iter().map(|(_, f)| f.norm()).fold(0.0, f64::max);
    Ok(report.peak_force.min(felt))
}

fn main() -> heml::Result<()> {
    if std::env::var_os("HEML_HAPTIC_LONG").is_some() {
        // the shared mesh collection next to the checkout (or a worktree's), or $HEML_MESHES
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let dir = std::env::var_os("HEML_MESHES").map_or_else(
            || {
                [root.join("../shared/meshes"), root.join("../../shared/meshes")]
                    .into_iter()
                    .find(|d| d.is_dir())
                    .unwrap_or_default()
            },
            Into::into,
        );
        let mesh = read_mesh(&dir.join("msh/gen_kidney_20k.msh"))?.0.scaled(1e-3)?; // millimetres
        palpate(mesh.clone(), &mut SymplecticEuler, true, 5.0)?;
        palpate(mesh, &mut BackwardEuler::default(), false, 5.0)?;
        return Ok(());
    }
    let mesh = box_mesh([0.06, 0.06, 0.03], [8, 8, 4], HexSplit::Six)?;
    let peak = palpate(mesh, &mut SymplecticEuler, true, 0.2)?;
    // the tip presses 4 mm into the tissue at mid-run (in contact from 0.045 s to
    // 0.155 s of device time): the tissue pushes back, in the simulation and on
    // the device
    assert!(peak > 0.0, "no contact force");
    Ok(())
}

#[test]
fn haptic_loop() {
    main().unwrap();
}
