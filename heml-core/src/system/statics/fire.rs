//! Dynamic relaxation with FIRE 2.0 damping: the quasi-static fallback that works
//! for every law (see the [module docs](super) for the method).

use super::options::{Slider, StaticOptions, StaticReport};
use crate::error::{HemlError, Result};
use crate::system::System;
use crate::Vec3;

// FIRE 2.0 parameters (Guénolé et al. 2020, table 1).
const N_DELAY: usize = 20;
const F_INC: f64 = 1.1;
const F_DEC: f64 = 0.5;
const ALPHA0: f64 = 0.25;
const F_ALPHA: f64 = 0.99;

impl System {
    /// Relaxes from the current positions until the criterion holds, `stop()`
    /// returns true or `opts.max_iterations` force evaluations are spent (both
    /// errors).
    pub(super) fn fire(
        &mut self,
        sliders: &[Slider],
        opts: &StaticOptions,
        stop: &mut dyn FnMut() -> bool,
    ) -> Result<StaticReport> {
        let t = self.state.t;
        self.state.v.fill(Vec3::zeros());
        self.apply_constraints(t);
        self.apply_sliders(sliders);
        let mut slider_reactions = vec![0.0; sliders.len()];
        self.compute_forces()?;
        self.slider_forces(sliders, &mut slider_reactions);
        // at equilibrium already (nothing free, or nothing loaded): no step needed
        let start = self.static_report(&slider_reactions, opts, 0);
        if start.converged {
            return Ok(start);
        }
        let dt_max = self.stepping.stable_dt;
        if !(dt_max.is_finite() && dt_max > 0.0) {
            return Err(HemlError::Numerical(format!(
                "quasi-static solve: no usable stable time step ({dt_max})"
            )));
        }
        let dt_min = 0.02 * dt_max;
        let mut dt = 0.5 * dt_max;
        let mut alpha = ALPHA0;
        let mut n_pos = 0usize;
        let mut it = 0usize;
        loop {
            let report = self.static_report(&slider_reactions, opts, it);
            let (residual, scale) = (report.residual, report.load_scale);
            if opts.progress_every > 0 && (it.is_multiple_of(opts.progress_every) || report.converged) {
                log::info!(
                    "quasi-static: iteration {it:>7}  residual {residual:.3e}  relative {:.3e}  dt {dt:.2e}",
                    report.relative_residual()
                );
            }
            if report.converged {
                return Ok(report);
            }
            let stopped = stop();
            if stopped || it >= opts.max_iterations {
                let why = if stopped {
                    "was stopped after"
                } else {
                    "did not converge in"
                };
                return Err(HemlError::Numerical(format!(
                    "quasi-static solve {why} {it} iterations: residual max|f_free| = {residual:.3e} N, \
                     {:.3e} of the load scale {scale:.3e} N (tolerance {:.1e}); the system keeps the last iterate",
                    report.relative_residual(),
                    opts.tol
                )));
            }
            it += 1;
            let power: f64 = self.eval.force.iter().zip(&self.state.v).map(|(f, v)| f.dot(v)).sum();
            if power > 0.0 {
                n_pos += 1;
                if n_pos > N_DELAY {
                    dt = (dt * F_INC).min(dt_max);
                    alpha *= F_ALPHA;
                }
            } else {
                n_pos = 0;
                dt = (dt * F_DEC).max(dt_min);
                alpha = ALPHA0;
                for (x, v) in self.state.x.iter_mut().zip(&mut self.state.v) {
                    *x -= *v * (0.5 * dt);
                    *v = Vec3::zeros();
                }
            }
            // semi-implicit Euler with FIRE mixing in mass-weighted coordinates:
            // v ← (1 − α) v + α (|√m v| / |f/√m|) f/m
            self.kick(dt);
            let (mut vv, mut ff) = (0.0, 0.0);
            for ((v, f), im) in self.state.v.iter().zip(&self.eval.force).zip(&self.model.inv_mass) {
                if *im > 0.0 {
                    vv += v.norm_squared() / im;
                    ff += f.norm_squared() * im;
                }
            }
            if ff > 0.0 {
                let c = alpha * (vv / ff).sqrt();
                for ((v, f), im) in self.state.v.iter_mut().zip(&self.eval.force).zip(&self.model.inv_mass) {
                    *v = *v * (1.0 - alpha) + f * (c * im);
                }
            }
            self.drift(dt);
            self.apply_constraints(t);
            self.apply_sliders(sliders);
            self.compute_forces()?;
            self.slider_forces(sliders, &mut slider_reactions);
        }
    }
}
