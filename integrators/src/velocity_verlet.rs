use heml_core::system::{Integrator, IntegratorEntry, StepStats, System};
use heml_core::Result;

const DOC: &str = "Velocity Verlet: v += dt/2·a_n; x += dt·v; a_{n+1} = a(x_{n+1}); v += dt/2·a_{n+1}.

Second order, symplectic and time-reversible (undamped): stable for dt < 2/ω_max, energy
error O((ω dt)²) bounded over long runs, no drift. One force evaluation per step: the
forces at the end of a step are kept by the system and reused by the next step unless the
system was changed in between. Velocity-dependent forces (damping) at the end of a step
use the half-step velocity.";

/// Velocity Verlet: half kick, drift, force, half kick.
///
/// Second order, symplectic, time-reversible: stable for dt < 2/ω_max; undamped, the
/// energy error is O((ω dt)²) and bounded. One force evaluation per step: the end-of-
/// step forces are reused by the next step while [`System::forces_current`] holds (any
/// edit of the system invalidates them). Damping forces at the end of a step use the
/// half-step velocity (first-order in the damping term, as usual for Verlet).
#[derive(Debug, Clone, Copy, Default)]
pub struct VelocityVerlet;

impl Integrator for VelocityVerlet {
    fn step(&mut self, sys: &mut System, dt: f64) -> Result<StepStats> {
        sys.begin_step(dt)?;
        if !sys.forces_current() {
            sys.compute_forces()?;
        }
        sys.kick(0.5 * dt);
        sys.drift(dt);
        sys.advance_time()?;
        sys.compute_forces()?;
        sys.kick(0.5 * dt);
        sys.finish_step()
    }
    fn name(&self) -> &'static str {
        "velocity_verlet"
    }
}

inventory::submit! {
    IntegratorEntry { name: "velocity_verlet", doc: DOC, module: module_path!(), build: || Box::new(VelocityVerlet) }
}
