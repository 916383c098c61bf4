//! One implicit time step as a [`NewtonProblem`] in the end-of-step positions x⁺.
//!
//! Both schemes write the end-of-step acceleration and velocity as affine functions
//! of d = x⁺ − x − h v (free nodes): a⁺ = c_a d − â, v⁺ = v + c_v d, with
//! backward Euler c_a = 1/h², c_v = 1/h, â = 0 and Newmark (β = ¼, γ = ½)
//! c_a = 4/h², c_v = 2/h, â = a (the acceleration at the start of the step). The
//! residual is r = f(x⁺, v⁺) − M a⁺ — f the system's full force: elastic (viscous-
//! elastic), gravity, loads and Rayleigh damping −αMv − βKv — and the tangent
//! −∂r/∂x⁺ = (1 + β c_v) K + (c_a + α c_v) M + (k + c c_v) I on grasped nodes, with K
//! the elastic stiffness of [`crate::force::tangent`] and k, c the grasp springs and
//! dampers (so that a stiff grasp does not stall the Newton iteration), plus the tool
//! contacts' (k + c c_v) n nᵀ on every penetrating surface node (`system::contact`:
//! their forces depend on x⁺ and v⁺, and the residual includes them). The line-search
//! merit is the incremental potential W(x⁺) + gravity, load, grasp and contact
//! potentials + ½ c_a |d − â/c_a|²_M + α/(2 c_v)·|v⁺|²_M, whose gradient is −r with
//! mass damping (with stiffness damping, a decreasing residual norm is accepted too).

use super::linear::{SolveCache, TangentSolve};
use super::settings::{CgFailure, ImplicitSettings, LinearSolver};
use crate::error::{HemlError, Result};
use crate::force::TangentOperator;
use crate::system::statics::dofs::DofMap;
use crate::system::statics::newton::NewtonProblem;
use crate::system::System;
use crate::Vec3;

/// θ of the refactor rule for a chord iteration whose leftover imbalance is carried
/// into the next step (the last of a step ending at the iteration cap: with one
/// iteration per step, every one). Measured on the benchmark's long run on
/// gen_kidney_20k (`heml bench --implicit`, one iteration per step): with 0.5 chord
/// steps contracting by 0.3–0.5 (a fresh factor reached 0.06) piled up their
/// leftovers in the grasp phase until the motion diverged; with 0.2 the run
/// follows the CG run through all 200 steps.
pub(super) const CARRIED_CONTRACTION: f64 = 0.2;

/// How the Newton iterations of a step ended.
#[derive(Debug, Clone, Copy)]
pub(super) struct NewtonOutcome {
    /// Newton iterations done.
    pub iterations: usize,
}

/// The state of one implicit step.
pub(super) struct ImplicitStep<'a> {
    pub settings: &'a ImplicitSettings,
    pub tangents: &'a mut [Box<dyn TangentOperator>],
    /// The assembled matrix and phase times.
    pub cache: &'a mut SolveCache,
    /// CG's starting guess for the step's first Newton correction (by degree of
    /// freedom), taken (once) by the first solve.
    pub guess: Option<Vec<f64>>,
    /// The step's first Newton correction (the next step's guess).
    pub first_dx: Option<Vec<f64>>,
    /// Seconds spent in [`NewtonProblem::merit`] (a `&self` method).
    pub merit_time: std::cell::Cell<f64>,
    /// Positions, velocities and â at the start of the step.
    pub x0: &'a [Vec3],
    pub v0: &'a [Vec3],
    pub a0: &'a [Vec3],
    pub h: f64,
    pub ca: f64,
    pub cv: f64,
    /// Norm of the external loads on the free nodes (tolerance scale).
    pub load_norm: f64,
    /// Residual per node (zero on constrained nodes).
    pub r: Vec<Vec3>,
    /// Residual norm at the start of the step.
    pub r0: Option<f64>,
    /// CG iterations summed over the step.
    pub cg_iterations: usize,
    /// Messages of linear solves that missed their tolerance.
    pub warnings: Vec<String>,
    /// Cholesky: the residual norm before the last linear solve and whether that
    /// solve reused a factor (a chord iteration), to measure its contraction.
    pub last_solve: Option<(f64, bool)>,
    /// Cholesky: whether a solve of this step reused a factor.
    pub reused: bool,
}

impl ImplicitStep<'_> {
    /// d_i = x_i − x0_i − h v0_i on a free node.
    fn d(&self, sys: &System, i: usize) -> Vec3 {
        sys.state.x[i] - self.x0[i] - self.v0[i] * self.h
    }

    /// v⁺ = v0 + c_v d on the free nodes (constrained ones keep their imposed
    /// velocity).
    pub fn set_velocities(&self, sys: &mut System) {
        for i in 0..sys.state.x.len() {
            if sys.model.inv_mass[i] > 0.0 {
                sys.state.v[i] = self.v0[i] + self.d(sys, i) * self.cv;
            }
        }
        sys.eval.forces_current = false;
    }

    /// a⁺ = c_a d − â on the free nodes, zero on the constrained ones.
    pub fn accelerations(&self, sys: &System) -> Vec<Vec3> {
        (0..sys.state.x.len())
            .map(|i| {
                if sys.model.inv_mass[i] > 0.0 {
                    self.d(sys, i) * self.ca - self.a0[i]
                } else {
                    Vec3::zeros()
                }
            })
            .collect()
    }

    /// Records the contraction c = |r after| / |r before| of the last linear solve
    /// and, with the Cholesky factor, judges the factor by it: an iteration on a
    /// fresh factor sets the reference c_fresh (what the nonlinearity leaves), an
    /// iteration on a reused factor with c > θ + (1 − θ)·c_fresh, θ =
    /// [`ImplicitSettings::refactor_contraction`], makes the next solve refactor.
    /// The staleness is so measured against what a fresh factor achieved: with an
    /// exact fresh step (c_fresh = 0) the bound is θ; where even a fresh factor
    /// contracts little (a strongly nonlinear phase, with one iteration per step)
    /// the bound rises towards 1, as refactoring would buy little there.
    /// `carried`: the iteration was the step's last and the step ends at the
    /// iteration cap, so its leftover imbalance is carried into the next step; θ
    /// is then at most [`CARRIED_CONTRACTION`].
    /// Returns whether it asked for a refactorisation.
    pub fn check_contraction(&mut self, carried: bool) -> bool {
        let Some((before, reused)) = self.last_solve.take() else {
            return false;
        };
        let contraction = if before > 0.0 { norm(&self.r) / before } else { 0.0 };
        self.cache.times.contraction = contraction;
        if !reused {
            self.cache.fresh_contraction = contraction.min(1.0);
        } else {
            let theta = if carried {
                self.settings.refactor_contraction.min(CARRIED_CONTRACTION)
            } else {
                self.settings.refactor_contraction
            };
            if contraction > theta + (1.0 - theta) * self.cache.fresh_contraction {
                self.cache.refactor = true;
                return true;
            }
        }
        false
    }

    /// Forgets the step's Newton history (the start residual, the last solve, the
    /// first correction, the reuse), to run its iterations again from the predictor.
    pub fn restart(&mut self) {
        self.r0 = None;
        self.last_solve = None;
        self.reused = false;
        self.first_dx = None;
    }

    /// Mass coefficient c_a + α c_v and stiffness coefficient 1 + β c_v.
    fn coefficients(&self, sys: &System) -> (f64, f64) {
        (
            self.ca + sys.model.damping.alpha * self.cv,
            1.0 + sys.model.damping.beta * self.cv,
        )
    }
}

fn norm(f: &[Vec3]) -> f64 {
    f.iter().map(|v| v.norm_squared()).sum::<f64>().sqrt()
}

impl NewtonProblem for ImplicitStep<'_> {
    type Report = NewtonOutcome;

    fn evaluate(&mut self, sys: &mut System) -> Result<()> {
        let t0 = std::time::Instant::now();
        let out = self.evaluate_inner(sys);
        self.cache.times.forces += t0.elapsed().as_secs_f64();
        out
    }

    fn residual<'s>(&'s self, _: &'s System) -> &'s [Vec3] {
        &self.r
    }

    fn converged(&self, _: &System, it: usize, _: f64) -> Option<NewtonOutcome> {
        let r = norm(&self.r);
        let r0 = self.r0.unwrap_or(r);
        // at round-off (a body at rest) there is nothing left to solve
        let tolerance = (self.settings.newton_tolerance * r0.max(self.load_norm)).max(self.cache.roundoff);
        let done = r <= tolerance || it >= self.settings.newton_iterations;
        done.then_some(NewtonOutcome { iterations: it })
    }

    fn max_iterations(&self) -> usize {
        self.settings.newton_iterations
    }

    fn solve_linear(&mut self, sys: &System, dofs: &DofMap, rhs: &mut [f64]) -> Result<bool> {
        let first = self.r0.is_none();
        if first {
            self.r0 = Some(norm(&self.r));
        }
        self.check_contraction(false);
        let (cm, ck) = self.coefficients(sys);
        let s = self.settings;
        let solve = TangentSolve {
            ck,
            cm,
            cv: self.cv,
            tol: s.cg_tolerance,
            max_iterations: s.cg_max_iterations,
            preconditioner: s.preconditioner,
            linear_solver: s.linear_solver,
            reuse_factor: !self.cache.refactor,
            max_factor_nonzeros: s.max_factor_nonzeros,
        };
        let guess = self.guess.take().filter(|g| first && g.len() == rhs.len());
        let factorizations = self.cache.factorizations;
        let report = solve.solve(sys, self.tangents, self.cache, dofs, rhs, guess.as_deref())?;
        let reused = s.linear_solver == LinearSolver::Cholesky && self.cache.factorizations == factorizations;
        self.cache.refactor = false;
        self.reused |= reused;
        self.last_solve = Some((norm(&self.r), reused));
        if first {
            self.first_dx = Some(rhs.to_vec());
        }
        self.cg_iterations += report.iterations;
        if !report.converged && (report.breakdown || s.cg_failure != CgFailure::Continue) {
            let msg = format!(
                "step {}: conjugate gradients stopped at relative residual {:.2e} after {} iterations \
                 (tolerance {:.1e}, cap {}){}",
                sys.attempted_step(),
                report.relative_residual,
                report.iterations,
                s.cg_tolerance,
                s.cg_max_iterations,
                if report.breakdown {
                    "; the tangent is not positive definite (set project_psd)"
                } else {
                    ""
                }
            );
            match s.cg_failure {
                CgFailure::Refuse => return Err(HemlError::Numerical(msg)),
                CgFailure::Warn | CgFailure::Continue => self.warnings.push(msg),
            }
        }
        Ok(report.iterations > 0 || report.converged)
    }

    fn merit(&self, sys: &System) -> Result<f64> {
        let t0 = std::time::Instant::now();
        let e = sys.energies();
        self.merit_time.set(self.merit_time.get() + t0.elapsed().as_secs_f64());
        let e = e?;
        let alpha = sys.model.damping.alpha;
        let inertia: f64 = (0..sys.state.x.len())
            .filter(|&i| sys.model.inv_mass[i] > 0.0)
            .map(|i| {
                let d = self.d(sys, i);
                let a = d * self.ca - self.a0[i];
                // mass damping −α M v⁺ is the gradient of α/(2 c_v)·|v⁺|²_M too
                let v = self.v0[i] + d * self.cv;
                0.5 * sys.model.mass[i] * (a.norm_squared() / self.ca + alpha * v.norm_squared() / self.cv)
            })
            .sum();
        Ok(e.elastic + e.gravity + e.loads + sys.model.tools.energy() + inertia)
    }
}

impl ImplicitStep<'_> {
    /// [`NewtonProblem::evaluate`] without the timing.
    fn evaluate_inner(&mut self, sys: &mut System) -> Result<()> {
        self.set_velocities(sys);
        sys.invalidate();
        // no rollback here: a failed line-search trial must leave the step going
        sys.compute_forces_inner()?;
        let a = self.accelerations(sys);
        for (i, r) in self.r.iter_mut().enumerate() {
            *r = sys.eval.force[i] - a[i] * sys.model.mass[i];
            if sys.model.inv_mass[i] == 0.0 {
                *r = Vec3::zeros();
            }
        }
        Ok(())
    }
}
