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

    /// The convergence state after `it` iterations: the largest force on a free
    /// degree of freedom against the tolerance scaled by the largest load or slider
    /// reaction (or the absolute tolerance, whichever is larger).
    pub(super) fn static_report(&self, slider_reactions: &[f64], opts: &StaticOptions, it: usize) -> StaticReport {
        let residual = self.free_residual();
        let scale = slider_reactions.iter().fold(self.load_scale(), |m, r| m.max(r.abs()));
        StaticReport {
            converged: residual <= (opts.tol * scale).max(opts.abs_tol),
            iterations: it,
            residual,
            load_scale: scale,
            tol: opts.tol,
            slider_reactions: slider_reactions.to_vec(),
        }
    }

    /// max |f_i| over the nodes: the forces on constrained nodes (and on slider
    /// coordinates, see `slider_forces`) are zeroed, so this is the free residual.
    fn free_residual(&self) -> f64 {
        self.eval.force.iter().map(|f| f.norm()).fold(0.0, f64::max)
    }
}
