//! The public entry points of the quasi-static solver: validate the request, try
//! Newton, fall back on dynamic relaxation, and leave the system at rest.

use super::options::{Slider, StaticOptions, StaticReport};
use crate::error::{HemlError, Result};
use crate::system::System;
use crate::Vec3;

impl System {
    /// Moves the clock to `t` without any dynamics and imposes the constraints there
    /// (prescribed displacements follow their ramps): the load parameter of a
    /// quasi-static load-stepping loop. Velocities are zeroed.
    pub fn set_load_time(&mut self, t: f64) -> Result<()> {
        if !t.is_finite() {
            return Err(HemlError::Invalid(format!("load time {t} must be finite")));
        }
        self.state.t = t;
        self.state.v.fill(Vec3::zeros());
        self.invalidate();
        self.apply_constraints(t);
        Ok(())
    }

    /// Relaxes the system to static equilibrium at the current time (see the
    /// [module docs](crate::system::statics) for the method and the criterion).
    /// Rayleigh damping is switched off during the solve and restored afterwards;
    /// velocities end at zero.
    ///
    /// Errors: non-finite forces (with the node), or no convergence within
    /// `max_iterations` (the message states the residual reached; the system keeps
    /// the last iterate).
    pub fn solve_static(&mut self, opts: &StaticOptions) -> Result<StaticReport> {
        self.solve_static_with(&[], opts)
    }

    /// [`System::solve_static`] with additional single-coordinate supports
    /// ([`Slider`]s) on top of the system's constraints. Their reaction components
    /// are returned in [`StaticReport::slider_reactions`] and count in the load scale.
    pub fn solve_static_with(&mut self, sliders: &[Slider], opts: &StaticOptions) -> Result<StaticReport> {
        self.solve_static_until(sliders, opts, &mut || false)
    }

    /// [`System::solve_static_with`] that ends with an error as soon as `stop()`
    /// returns true, leaving the system at the last iterate. `stop` is asked between
    /// the dynamic-relaxation iterations (the Newton iterations before them are
    /// few), one force evaluation apart: say, a flag set by a signal handler or a
    /// user interface, or the time spent (a caller that must look elsewhere, like
    /// the Python bindings checking for Ctrl-C, does so at most every ~0.1 s).
    ///
    /// ```
    /// use heml_core::mesh::generate::{box_mesh, HexSplit};
    /// use heml_core::system::{StaticOptions, System};
    /// use heml_core::Vec3;
    /// let mesh = box_mesh([0.1, 0.02, 0.02], [10, 2, 2], HexSplit::Six)?;
    /// let law = heml_core::RuntimeLaw::from_energy(
    ///     "mu/2*(I1-3) - mu*ln(J) + lam/2*ln(J).powi(2)",
    ///     &heml_core::Params::from([("mu", 1e3), ("lam", 1e4)]),
    /// )?;
    /// let mut sys = System::builder(mesh)
    ///     .material_law(Box::new(law))
    ///     .gravity(Vec3::new(0.0, 0.0, -9.81))
    ///     .fix_where(|p| p.x < 1e-9)
    ///     .build()?;
    /// // a solve that may not outlast a deadline
    /// let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    /// let report = sys.solve_static_until(&[], &StaticOptions::default(), &mut || {
    ///     std::time::Instant::now() > deadline
    /// })?;
    /// assert!(report.converged && sys.displacements().iter().any(|d| d.z < 0.0));
    /// # Ok::<(), heml_core::HemlError>(())
    /// ```
    pub fn solve_static_until(
        &mut self,
        sliders: &[Slider],
        opts: &StaticOptions,
        stop: &mut dyn FnMut() -> bool,
    ) -> Result<StaticReport> {
        if let Some(s) = sliders
            .iter()
            .find(|s| s.node >= self.state.x.len() || s.axis > 2 || !s.value.is_finite())
        {
            return Err(HemlError::Invalid(format!(
                "slider on node {} axis {} at {}: node or axis out of range, or value not finite",
                s.node, s.axis, s.value
            )));
        }
        if !(opts.tol.is_finite() && opts.tol > 0.0 && opts.abs_tol.is_finite() && opts.abs_tol >= 0.0) {
            return Err(HemlError::Invalid(format!(
                "static tolerances tol = {}, abs_tol = {} must be finite, tol > 0, abs_tol >= 0",
                opts.tol, opts.abs_tol
            )));
        }
        let damping = std::mem::take(&mut self.model.damping);
        let result = match self.static_newton(sliders, opts) {
            Ok(Some(report)) => Ok(report),
            Ok(None) => self.fire(sliders, opts, stop),
            Err(e) => Err(e),
        };
        self.model.damping = damping;
        self.state.v.fill(Vec3::zeros());
        self.invalidate();
        result
    }
}
