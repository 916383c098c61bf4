//! `heml bench --haptic`: the 1 kHz haptic loop (device, simulation and display
//! threads, `heml::system::contact::run_haptic_loop`) palpating the kidney meshes
//! gen_kidney_20k and gen_kidney_100k, with symplectic Euler (the explicit scheme
//! with one force evaluation per step, substepped at its stable step) and with
//! backward Euler (one step per device period).

use heml::integrators::{BackwardEuler, SymplecticEuler};
use heml::prelude::*;
use heml::system::contact::{run_haptic_loop, ContactLaw, HapticOptions, Palpation};
use heml::system::Integrator;
use std::path::PathBuf;

/// Device time of each run (s).
const SECONDS: f64 = 3.0;

/// The meshes: `mesh` alone, or the two kidneys of the shared collection.
fn meshes(mesh: Option<&PathBuf>) -> heml::Result<Vec<PathBuf>> {
    if let Some(m) = mesh {
        return Ok(vec![m.clone()]);
    }
    let dir = std::env::var_os("HEML_MESHES").map_or_else(|| PathBuf::from("../shared/meshes"), PathBuf::from);
    let list: Vec<PathBuf> = ["gen_kidney_20k.msh", "gen_kidney_100k.msh"]
        .iter()
        .map(|n| dir.join("msh").join(n))
        .collect();
    if let Some(missing) = list.iter().find(|p| !p.is_file()) {
        return Err(HemlError::Invalid(format!(
            "heml bench --haptic: {} not found (set HEML_MESHES to the shared mesh folder, or give --mesh)",
            missing.display()
        )));
    }
    Ok(list)
}

/// Runs the loop on each mesh with both integrators in `pool` and prints the reports.
pub fn run(mesh: Option<&PathBuf>, pool: &rayon::ThreadPool, threads: usize) -> heml::Result<()> {
    outln!("haptic loop: 1 kHz device, {SECONDS} s of device time per run, {threads} simulation thread(s)");
    for path in meshes(mesh)? {
        for explicit in [true, false] {
            let mut sys = Palpation::tissue(read_mesh(&path)?.0.scaled(1e-3)?)?; // millimetres
            let law = ContactLaw {
                stiffness: 200.0,
                damping: 0.002,
            };
            let (tool, palpation) = Palpation::on_top(&mut sys, 0.004, 0.01, law, 1.0)?;
            let (mut integrator, opts): (Box<dyn Integrator>, _) = if explicit {
                (Box::new(SymplecticEuler), HapticOptions::explicit(&sys, SECONDS))
            } else {
                (
                    Box::new(BackwardEuler::default()),
                    HapticOptions {
                        duration: SECONDS,
                        ..HapticOptions::default()
                    },
                )
            };
            let report =
                pool.install(|| run_haptic_loop(&mut sys, integrator.as_mut(), tool, |t| palpation.at(t), &opts))?;
            outln!(
                "{} ({} tets), {}: {report}",
                path.file_name()
                    .map_or(path.display().to_string(), |n| n.to_string_lossy().into()),
                sys.mesh().n_tets(),
                integrator.name()
            );
        }
    }
    Ok(())
}
