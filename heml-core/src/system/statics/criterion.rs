//! The convergence test of a quasi-static solve: the largest force on a free degree
//! of freedom against the tolerance scaled by the largest load or reaction.

use super::options::{StaticOptions, StaticReport};
use crate::system::System;
use crate::Vec3;

impl System {
    /// Largest nodal external load |m_i g + f_nodal| and reaction |r_i| (reactions
    /// from the last force evaluation).
    fn load_scale(&self) -> f64 {
        let mut ext: Vec<Vec3> = self.model.mass.iter().map(|m| self.model.gravity * *m).collect();
        for &(i, f) in &self.model.nodal {
            ext[i] += f;
        }
        let loads = ext.iter().map(|f| f.norm()).fold(0.0, f64::max);
        let reactions = self
            .model
            .constrained_ids
            .iter()
            .map(|&i| self.eval.reaction[i].norm())
            .fold(0.0, f64::max);
        loads.max(reactions)
    }

    /// The round-off level of the residual (N): ε·λ_max·m_max·|x|_max, with λ_max
    /// = (2/Δt_crit)² the largest eigenvalue of M⁻¹K at rest, m_max the largest free
    /// nodal mass and |x|_max the largest coordinate. Forces computed from
    /// coordinates of size |x| carry errors of about ε|x| in the edge vectors times
    /// the stiffness ‖K‖ ≤ λ_max·m_max. Measured on unloaded boxes at rest (E = 3 kPa
    /// to 300 kPa, 1 cm to 10 m): residuals of 0.002–0.005 of this, so it bounds
    /// the round-off with a margin of ~200; against a gravity load it is 3·10⁻⁴ to
    /// 10⁻⁷ of the default tolerance's 10⁻⁶·m g, so a loaded solve is not ended by
    /// it. 0 when the step is not finite (nothing free, or no estimate).
    fn roundoff_floor(&self) -> f64 {
        let dt = self.stepping.critical_dt;
        if !(dt.is_finite() && dt > 0.0) {
            return 0.0;
        }
        let lambda = (2.0 / dt).powi(2);
        let mass = (0..self.state.x.len())
            .filter(|&i| self.model.inv_mass[i] > 0.0)
            .map(|i| self.model.mass[i])
            .fold(0.0, f64::max);
        let size = self.state.x.iter().map(|x| x.amax()).fold(0.0, f64::max);
        f64::EPSILON * lambda * mass * size
    }

    /// The convergence state after `it` iterations: the largest force on a free
    /// degree of freedom against the tolerance scaled by the largest load or slider
    /// reaction, the absolute tolerance or the round-off level, whichever is largest
    /// (the last so that an unloaded body, whose load scale is the round-off of its
    /// reactions, converges at rest instead of iterating to the cap).
    pub(super) fn static_report(&self, slider_reactions: &[f64], opts: &StaticOptions, it: usize) -> StaticReport {
        let residual = self.free_residual();
        let scale = slider_reactions.iter().fold(self.load_scale(), |m, r| m.max(r.abs()));
        let roundoff = self.roundoff_floor();
        StaticReport {
            converged: residual <= (opts.tol * scale).max(opts.abs_tol).max(roundoff),
            iterations: it,
            residual,
            load_scale: scale,
            tol: opts.tol,
            roundoff,
            slider_reactions: slider_reactions.to_vec(),
        }
    }

    /// max |f_i| over the nodes: the forces on constrained nodes (and on slider
    /// coordinates, see `slider_forces`) are zeroed, so this is the free residual.
    fn free_residual(&self) -> f64 {
        self.eval.force.iter().map(|f| f.norm()).fold(0.0, f64::max)
    }
}
