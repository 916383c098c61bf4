//! The stepping trait and the integrator registry.
//!
//! Integrators are written against a small set of [`System`] operations, so that
//! constraints, loads, damping, Prony updates, NaN detection and the time-step
//! policy are implemented once, by the system:
//!
//! 1. [`System::begin_step`]`(dt)` — checks `dt`, applies the time-step policy and
//!    saves the state it rolls back to on failure;
//! 2. [`System::compute_forces`] — total nodal forces at the current state (once per
//!    new time also advances the Prony internal variables);
//! 3. [`System::kick`]`(h)` (v += h·f/m on free nodes) and [`System::drift`]`(h)`
//!    (x += h·v), in the order the scheme requires ([`System::kick_drift`]`(h)`:
//!    both in one pass, for symplectic Euler);
//! 4. [`System::advance_time`] — moves the clock to t + dt and imposes the constraints
//!    (needed before a mid-step force evaluation);
//! 5. [`System::finish_step`] — imposes the constraints at t + dt, counts the step,
//!    checks for NaN/∞ and returns the [`StepStats`].

use super::{ImplicitSettings, StepStats, System};
use crate::error::Result;
use crate::registry::find_by_name;

/// A time-stepping scheme.
pub trait Integrator: Send {
    /// Advances `sys` by `dt` (> 0). On error the system keeps its last good state.
    fn step(&mut self, sys: &mut System, dt: f64) -> Result<StepStats>;
    /// Registry name.
    fn name(&self) -> &'static str;
    /// The Newton/CG settings of an implicit integrator, to configure it (scene keys
    /// `cg_tolerance`, `cg_max_iterations`, `newton_iterations`); `None` for explicit
    /// integrators.
    fn implicit_settings_mut(&mut self) -> Option<&mut ImplicitSettings> {
        None
    }
    /// Builds what the steps of `sys` reuse and depends on its mesh and constraints
    /// only (an implicit integrator's tangent operators, matrix pattern and Cholesky
    /// symbolic analysis: [`super::ImplicitSolver::prepare`]), so that the first
    /// step pays only numeric work; a later change of mesh or constraints is
    /// prepared again by the step that meets it. Nothing to do for explicit
    /// integrators (the default).
    fn prepare(&mut self, sys: &System) -> Result<()> {
        let _ = sys;
        Ok(())
    }
}

/// A registered integrator.
#[derive(Debug)]
pub struct IntegratorEntry {
    /// Registry name, e.g. `"velocity_verlet"`.
    pub name: &'static str,
    /// Doc text: order, stability, energy behaviour.
    pub doc: &'static str,
    /// Module path of the registration (to report duplicate names).
    pub module: &'static str,
    /// Builds a fresh integrator.
    pub build: fn() -> Box<dyn Integrator>,
}

inventory::collect!(IntegratorEntry);

impl IntegratorEntry {
    /// A fresh integrator of this kind.
    pub fn instantiate(&self) -> Box<dyn Integrator> {
        (self.build)()
    }

    /// The first line of the doc text.
    pub fn title(&self) -> &'static str {
        self.doc.lines().map(str::trim).find(|l| !l.is_empty()).unwrap_or("")
    }
}

/// Every registered integrator, sorted by name.
///
/// Registrations of a crate that nothing references are dropped by the linker: call
/// this through the `heml` facade (or reference `heml_integrators` yourself).
pub fn integrators() -> Vec<&'static IntegratorEntry> {
    let mut all: Vec<_> = inventory::iter::<IntegratorEntry>.into_iter().collect();
    all.sort_by_key(|e| e.name);
    all
}

/// The integrator registered as `name`; the error suggests the closest name and lists
/// the known ones.
pub fn find_integrator(name: &str) -> Result<&'static IntegratorEntry> {
    let all = integrators();
    find_by_name("integrator", name, &all, |e| e.name, |e| e.module)
}
