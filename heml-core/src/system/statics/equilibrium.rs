//! Static equilibrium as a [`NewtonProblem`]: the residual is the system's force
//! (elastic + gravity + loads, constraints and sliders imposed), the tangent the
//! elastic stiffness, the merit the total potential.

use super::banded::BandLdl;
use super::dofs::DofMap;
use super::newton::{newton, NewtonProblem};
use super::options::{Slider, StaticOptions, StaticReport};
use super::tangent::Stiffness;
use crate::error::Result;
use crate::system::System;
use crate::Vec3;

/// The static problem of one [`System::solve_static_with`] call.
struct Equilibrium<'a> {
    sliders: &'a [Slider],
    opts: &'a StaticOptions,
    stiffness: Stiffness,
    /// Reaction on each slider at the last evaluation.
    slider_reactions: Vec<f64>,
}

impl NewtonProblem for Equilibrium<'_> {
    type Report = StaticReport;

    fn evaluate(&mut self, sys: &mut System) -> Result<()> {
        sys.compute_forces()?;
        sys.slider_forces(self.sliders, &mut self.slider_reactions);
        Ok(())
    }

    fn residual<'s>(&'s self, sys: &'s System) -> &'s [Vec3] {
        &sys.force
    }

    fn converged(&self, sys: &System, it: usize, step: f64) -> Option<StaticReport> {
        let report = sys.static_report(&self.slider_reactions, self.opts, it);
        if self.opts.progress_every > 0 {
            log::info!(
                "quasi-static Newton (step {step}): iteration {it:>3}  residual {:.3e}  relative {:.3e}",
                report.residual,
                report.relative_residual()
            );
        }
        report.converged.then_some(report)
    }

    fn solve_linear(&mut self, sys: &System, dofs: &DofMap, rhs: &mut [f64]) -> Result<bool> {
        let mut k = BandLdl::new(dofs.len(), dofs.band());
        self.stiffness.add_to(sys, dofs, &mut k);
        if !k.factor() {
            return Ok(false);
        }
        k.solve(rhs);
        Ok(true)
    }

    fn merit(&self, sys: &System) -> Result<f64> {
        let e = sys.energies()?;
        Ok(e.elastic + e.gravity + e.loads)
    }
}

impl System {
    /// Newton iterations towards equilibrium; `Ok(None)` when not applicable (a law
    /// without stress, nothing free, a band too wide for memory) or stalled (then
    /// dynamic relaxation goes on from the current iterate).
    pub(super) fn static_newton(&mut self, sliders: &[Slider], opts: &StaticOptions) -> Result<Option<StaticReport>> {
        let Some(stiffness) = Stiffness::new(self) else {
            return Ok(None);
        };
        let t = self.t;
        let n = self.x.len();
        let mut held = vec![[false; 3]; n];
        for (i, h) in held.iter_mut().enumerate() {
            if self.constraints.is_constrained(i) {
                *h = [true; 3];
            }
        }
        for s in sliders {
            held[s.node][s.axis] = true;
        }
        let dofs = DofMap::new(&held, self.mesh.tets());
        if dofs.len() == 0 || !BandLdl::fits(dofs.len(), dofs.band()) {
            return Ok(None);
        }
        self.v.fill(Vec3::zeros());
        self.apply_constraints(t);
        self.apply_sliders(sliders);
        let mut problem = Equilibrium {
            sliders,
            opts,
            stiffness,
            slider_reactions: vec![0.0; sliders.len()],
        };
        newton(self, &dofs, &mut problem)
    }
}
