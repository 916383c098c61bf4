//! Static equilibrium as a [`NewtonProblem`]: the residual is the system's force
//! (elastic + gravity + loads, constraints and sliders imposed), the tangent the
//! elastic stiffness, the merit the total potential. The tangent system is solved by
//! the banded LDLᵀ when the band fits in memory, else by the implicit integrators'
//! conjugate gradients on the generated (projected) tangent, or as
//! [`StaticOptions::linear_solver`] chooses (CG or a sparse Cholesky factor).

use super::banded::BandLdl;
use super::dofs::DofMap;
use super::newton::{newton, NewtonProblem};
use super::options::{Slider, StaticOptions, StaticReport};
use super::tangent::{add_operators, Stiffness};
use crate::error::Result;
use crate::force::TangentOperator;
use crate::system::implicit::linear::{SolveCache, TangentSolve};
use crate::system::implicit::{CgPreconditioner, ImplicitSettings, LinearSolver};
use crate::system::System;
use crate::Vec3;

/// How the tangent system of a static Newton step is solved.
enum Linear {
    /// Banded LDLᵀ of the assembled stiffness (fits in memory).
    Banded(Stiffness),
    /// Banded LDLᵀ of the exact generated tangents (per-tet blocks and the nodal
    /// volumetric couplings, which reach two links: a nodal-volume material whose
    /// band fits in memory).
    /// The half-bandwidth is the second field.
    BandedTangent(Vec<Box<dyn TangentOperator>>, usize),
    /// Preconditioned conjugate gradients, or a sparse Cholesky factorisation, of
    /// the assembled generated tangent (projected to positive semi-definite per tet).
    Cg(Vec<Box<dyn TangentOperator>>, Box<SolveCache>, LinearSolver),
}

/// CG relative tolerance of the static Newton steps: an inexact Newton step whose
/// error contracts the residual by ~1e-6 per iteration, ample for the 1e-6 criterion.
const CG_TOL: f64 = 1e-6;
/// CG iteration cap of the static Newton steps.
const CG_MAX_ITERATIONS: usize = 5000;

/// The static problem of one [`System::solve_static_with`] call.
struct Equilibrium<'a> {
    sliders: &'a [Slider],
    opts: &'a StaticOptions,
    linear: Linear,
    /// Reaction on each slider at the last evaluation.
    slider_reactions: Vec<f64>,
}

impl NewtonProblem for Equilibrium<'_> {
    type Report = StaticReport;

    fn evaluate(&mut self, sys: &mut System) -> Result<()> {
        // with the energy: the line search's merit reads it
        sys.compute_forces_with(true)?;
        sys.slider_forces(self.sliders, &mut self.slider_reactions);
        Ok(())
    }

    fn residual<'s>(&'s self, sys: &'s System) -> &'s [Vec3] {
        &sys.eval.force
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
        match &mut self.linear {
            Linear::Banded(stiffness) => {
                let mut k = BandLdl::new(dofs.len(), dofs.band());
                stiffness.add_to(sys, dofs, &mut k);
                Ok(solve_banded(sys, dofs, k, rhs))
            }
            Linear::BandedTangent(tangents, band) => {
                for t in tangents.iter_mut() {
                    t.update(&sys.state.x)?;
                }
                let mut k = BandLdl::new(dofs.len(), *band);
                add_operators(tangents, sys, dofs, &mut k);
                Ok(solve_banded(sys, dofs, k, rhs))
            }
            Linear::Cg(tangents, cache, linear_solver) => {
                let solve = TangentSolve {
                    ck: 1.0,
                    cm: 0.0,
                    cv: 0.0,
                    tol: CG_TOL,
                    max_iterations: CG_MAX_ITERATIONS,
                    preconditioner: CgPreconditioner::SymmetricGaussSeidel,
                    linear_solver: *linear_solver,
                    reuse_factor: false,
                    contact_corrections: false,
                    max_factor_nonzeros: ImplicitSettings::default().max_factor_nonzeros,
                    cholesky_ordering: ImplicitSettings::default().cholesky_ordering,
                    // f64: K alone has no mass term bounding its conditioning
                    factor_precision: ImplicitSettings::default().factor_precision,
                };
                let report = solve.solve(sys, tangents, cache, dofs, rhs, None)?;
                if self.opts.progress_every > 0 {
                    log::debug!(
                        "quasi-static Newton: CG {} iterations, relative residual {:.1e}",
                        report.iterations,
                        report.relative_residual
                    );
                }
                // a direct solve reports no iterations, but converged
                Ok((report.iterations > 0 || report.converged) && !rhs.iter().all(|v| *v == 0.0))
            }
        }
    }

    fn merit(&self, sys: &System) -> Result<f64> {
        let e = sys.energies()?;
        Ok(e.elastic + e.gravity + e.loads + sys.model.tools.energy())
    }
}

/// Adds the grasps' and contacts' stiffness to the banded tissue stiffness `k`, then
/// factors it and solves in place; false when `k` is not positive definite.
fn solve_banded(sys: &System, dofs: &DofMap, mut k: BandLdl, rhs: &mut [f64]) -> bool {
    add_grasp_stiffness(sys, dofs, &mut k);
    add_contact_stiffness(sys, dofs, &mut k);
    if !k.factor() {
        return false;
    }
    k.solve(rhs);
    true
}

/// Adds the grasp springs' stiffness (diagonal) on the free coordinates.
fn add_grasp_stiffness(sys: &System, dofs: &DofMap, k: &mut BandLdl) {
    if let Some(g) = sys.model.grasps.diagonal(sys.state.x.len(), 0.0) {
        for (i, d) in g.iter().enumerate().filter(|(_, d)| **d != 0.0) {
            for a in 0..3 {
                if let Some(j) = dofs.get(i, a) {
                    k.add(j, j, *d);
                }
            }
        }
    }
}

/// Adds the tool contacts' stiffness k n nᵀ (lower triangle) on the free
/// coordinates of every penetrating node.
fn add_contact_stiffness(sys: &System, dofs: &DofMap, k: &mut BandLdl) {
    for c in sys.model.tools.contacts() {
        for a in 0..3 {
            let Some(row) = dofs.get(c.node, a) else { continue };
            for b in 0..3 {
                match dofs.get(c.node, b) {
                    Some(col) if col <= row => k.add(row, col, c.stiffness * c.normal[a] * c.normal[b]),
                    _ => {}
                }
            }
        }
    }
}

impl System {
    /// Half-bandwidth of the stiffness with the volumetric terms' couplings: nodes
    /// two links apart (the nodal term) or within one patch (the patch term).
    fn coupled_band(&self, dofs: &DofMap) -> Result<usize> {
        let mut band = dofs.ring_band(self.model.mesh.tets());
        for r in &self.model.regions {
            if let Some(groups) = r.material.coupled_groups(&self.model.mesh, Some(r.field.tet_ids()))? {
                band = band.max(dofs.group_band(&groups));
            }
        }
        Ok(band)
    }

    /// Newton iterations towards equilibrium; `Ok(None)` when not applicable (a law
    /// without stress, nothing free) or stalled (then dynamic relaxation goes on from the
    /// current iterate).
    pub(super) fn static_newton(&mut self, sliders: &[Slider], opts: &StaticOptions) -> Result<Option<StaticReport>> {
        let t = self.state.t;
        let n = self.state.x.len();
        let mut held = vec![[false; 3]; n];
        for (i, h) in held.iter_mut().enumerate() {
            if self.model.constraints.is_constrained(i) {
                *h = [true; 3];
            }
        }
        for s in sliders {
            held[s.node][s.axis] = true;
        }
        let dofs = DofMap::new(&held, self.model.mesh.tets());
        if dofs.len() == 0 {
            return Ok(None);
        }
        // link laws (no stress) keep dynamic relaxation, as before
        let Some(stiffness) = Stiffness::new(self) else {
            return Ok(None);
        };
        // the banded stiffness is per element: a nodal volumetric term (which couples
        // beyond a tet) is assembled from its exact generated tangent with the wider
        // band it needs, or, when that does not fit, goes through CG on its own
        // (projected) tangent; a linear solver named in the options overrides both
        let nodal = self
            .model
            .regions
            .iter()
            .any(|r| r.material.volumetric() != crate::material::Volumetric::Element);
        let linear = if opts.linear_solver.is_none() && !nodal && BandLdl::fits(dofs.len(), dofs.band()) {
            Linear::Banded(stiffness)
        } else {
            let band = self.coupled_band(&dofs)?;
            let banded = opts.linear_solver.is_none() && nodal && BandLdl::fits(dofs.len(), band);
            let mut tangents = Vec::with_capacity(self.model.regions.len());
            for r in &self.model.regions {
                match r.material.tangent(
                    &self.model.mesh,
                    Some(r.field.tet_ids()),
                    &self.model.force_options,
                    !banded,
                )? {
                    Some(t) => tangents.push(t),
                    None => return Ok(None),
                }
            }
            if banded {
                Linear::BandedTangent(tangents, band)
            } else {
                Linear::Cg(tangents, Box::default(), opts.linear_solver.unwrap_or_default())
            }
        };
        self.state.v.fill(Vec3::zeros());
        self.apply_constraints(t);
        self.apply_sliders(sliders);
        let mut problem = Equilibrium {
            sliders,
            opts,
            linear,
            slider_reactions: vec![0.0; sliders.len()],
        };
        newton(self, &dofs, &mut problem)
    }
}
