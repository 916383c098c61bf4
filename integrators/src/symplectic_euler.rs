use heml_core::system::{Integrator, IntegratorEntry, StepStats, System};
use heml_core::Result;

const DOC: &str = "Semi-explicit (symplectic) Euler: v += dt·a(x_n, v_n), then x += dt·v_{n+1}.

First order, the HEML seed's recommended scheme. Symplectic: undamped, stable for
dt < 2/ω_max (the stable_time_step estimate) and its energy oscillates with an O(ω dt)
amplitude around a conserved modified energy, with no secular drift. One force
evaluation per step.";

/// Semi-explicit (symplectic) Euler: v += dt·a(x_n, v_n), then x += dt·v_{n+1}.
///
/// First order, the seed's recommended scheme. Symplectic: stable for dt < 2/ω_max;
/// undamped, the energy oscillates by O(ω dt) around a conserved modified energy with
/// no drift. One force evaluation per step.
#[derive(Debug, Clone, Copy, Default)]
pub struct SymplecticEuler;

impl Integrator for SymplecticEuler {
    fn step(&mut self, sys: &mut System, dt: f64) -> Result<StepStats> {
        sys.begin_step(dt)?;
        sys.compute_forces()?;
        sys.kick_drift(dt); // v += dt f/m, then x += dt v, in one pass
        sys.finish_step()
    }
    fn name(&self) -> &'static str {
        "symplectic_euler"
    }
}

inventory::submit! {
    IntegratorEntry { name: "symplectic_euler", doc: DOC, module: module_path!(), build: || Box::new(SymplecticEuler) }
}
