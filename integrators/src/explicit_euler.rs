use heml_core::system::{Integrator, IntegratorEntry, StepStats, System};
use heml_core::Result;

const DOC: &str = "Explicit (forward) Euler: x += dt·v_n, v += dt·a(x_n, v_n).

First order. Not symplectic: for an undamped oscillator of frequency ω each step multiplies
the energy by 1 + (ω dt)², so the energy grows without bound at any dt (a damping ratio
ξ > ω dt/2 is needed to tame it). Kept as the textbook reference; use symplectic_euler or
velocity_verlet for production runs.";

/// Explicit (forward) Euler: x += dt·v_n, v += dt·a(x_n, v_n).
///
/// First order. Not symplectic: on an undamped oscillator each step multiplies the
/// energy by 1 + (ω dt)², so energy grows at any dt; kept as the reference scheme.
/// One force evaluation per step.
#[derive(Debug, Clone, Copy, Default)]
pub struct ExplicitEuler;

impl Integrator for ExplicitEuler {
    fn step(&mut self, sys: &mut System, dt: f64) -> Result<StepStats> {
        sys.begin_step(dt)?;
        sys.compute_forces()?; // a(x_n, v_n)
        sys.drift(dt); // x_{n+1} = x_n + dt v_n
        sys.kick(dt); // v_{n+1} = v_n + dt a_n
        sys.finish_step()
    }
    fn name(&self) -> &'static str {
        "explicit_euler"
    }
}

inventory::submit! {
    IntegratorEntry { name: "explicit_euler", doc: DOC, module: module_path!(), build: || Box::new(ExplicitEuler) }
}
