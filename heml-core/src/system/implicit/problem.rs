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
//! potentials + ½ c_a |d − â/c_a|²_M + α/(2 c_v)·|v⁺|²_M + Σ c/(2 c_v)·|v⁺_i|² over
//! grasped nodes (the grasp dampers), whose gradient is −r with mass damping (with
//! stiffness damping, a decreasing residual norm is accepted too; the tool
//! contacts' dashpots, switched by the contact and clamped, are left out: their
//! c·c_v is small beside k in the intended use, e.g. 0.2 against 200 N/m).

use super::anderson::Anderson;
use super::linear::{SolveCache, TangentSolve};
use super::settings::{CgFailure, ImplicitSettings, LinearSolver};
use crate::error::{HemlError, Result};
use crate::force::TangentOperator;
use crate::system::statics::dofs::DofMap;
use crate::system::statics::newton::NewtonProblem;
use crate::system::System;
use crate::Vec3;

/// A chord iteration (on a kept factor) contracting the residual by this factor or
/// worse refactors whatever the cost prediction says: the factor has lost the
/// matrix (a contact or a fast motion), and the prediction of a slow geometric
/// contraction is not worth trusting.
pub(super) const MAX_CHORD_CONTRACTION: f64 = 0.9;

/// Chord iterations a step may add beyond its Newton iterations at most (the cost
/// rule normally stops far earlier, at [`REFACTOR_COST_IN_CHORDS`]).
pub(super) const MAX_CHORD_ITERATIONS: usize = 50;

/// What a refactorisation (tangent update, assembly, numeric factorisation) costs,
/// in chord iterations (forces, line search, two triangular solves, the Anderson
/// mixing): measured ~25 on the liver (1.7 ms against 0.07 ms) and ~15 on
/// gen_kidney_20k (`heml bench --implicit`, session 12). A constant rather than
/// times measured during the run, so that which steps refactor — and so the
/// trajectory, at the level of a step's chord goal — is the same on every run and
/// machine: a scene replays to the same bits.
pub(super) const REFACTOR_COST_IN_CHORDS: f64 = 20.0;

/// The most of its initial residual a step may leave with the Cholesky factor
/// (or θ = `refactor_contraction` when larger): the chord goal is never looser,
/// and a Newton iteration on a fresh factor that leaves more is followed by chord
/// iterations on that factor until the residual is below it. Why: with one Newton
/// iteration per step the leftover imbalance is carried into the next step, and
/// under a tool's contacts (stiff springs made and released within a step) it
/// grows: in gen_kidney_100k's press (`heml bench --implicit`'s long run, session
/// 13) fresh iterations left 0.29–0.78 of |r0| and once 2.3 (the line search
/// accepts a step that lowers the incremental potential, not the residual), each
/// leftover came back ×3–15 as the next step's |r0|, and the motion diverged
/// within ten steps. Smooth phases are not bound by it: there a fresh iteration
/// leaves 0.02–0.1 and the chord goal θ + (1 − θ)·c_fresh is 0.22–0.28.
pub(super) const MAX_STEP_LEFTOVER: f64 = 0.25;

/// Iterations on a fresh factor a step may add to its `newton_iterations` while
/// its residual is above [`MAX_STEP_LEFTOVER`] (chord iterations that stall
/// refactor): so a step factors at most this many times more than it would
/// (each factorisation of gen_kidney_100k costs ~1.3 s).
pub(super) const MAX_EXTRA_FACTORIZATIONS: usize = 2;

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
    /// The merit's inertia term at the positions of the last evaluation (taken by
    /// the merit; `None` once taken or after an evaluation that failed).
    pub inertia_at_eval: std::cell::Cell<Option<f64>>,
    /// The inverted tets at the predictor, when the predictor counted them.
    pub start_inverted: Option<usize>,
    /// Where the step starts, and the scheme's coefficients.
    pub start: StepStart<'a>,
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
    /// Iterations of this step on a fresh factor (every iteration with CG): the
    /// step's Newton iterations proper, capped by `newton_iterations`.
    pub fresh_iterations: usize,
    /// Iterations of this step on a kept factor (chord iterations).
    pub chord_iterations: usize,
    /// The Anderson mixing of the chord iterations: the secant pairs on the current
    /// factor (the step's own and those carried from earlier steps; the solver's).
    pub anderson: &'a mut Anderson,
}

/// Where a step starts: positions, velocities and â at the start of the step, the
/// step h and the scheme's coefficients c_a, c_v (see the module doc).
pub(super) struct StepStart<'a> {
    pub x0: &'a [Vec3],
    pub v0: &'a [Vec3],
    pub a0: &'a [Vec3],
    pub h: f64,
    pub ca: f64,
    pub cv: f64,
}

impl StepStart<'_> {
    /// d = x − x0 − h v0 of a free node at `x`, from its start `x0`, `v0`.
    #[inline]
    fn d(&self, x: &Vec3, x0: &Vec3, v0: &Vec3) -> Vec3 {
        x - x0 - v0 * self.h
    }

    /// a⁺ = c_a d − â.
    #[inline]
    fn a(&self, d: &Vec3, a0: &Vec3) -> Vec3 {
        d * self.ca - a0
    }

    /// v⁺ = v0 + c_v d.
    #[inline]
    fn v(&self, v0: &Vec3, d: &Vec3) -> Vec3 {
        v0 + d * self.cv
    }
}

impl<'a> ImplicitStep<'a> {
    /// The problem of a step from `start`, with no Newton history yet (no warm start
    /// and no inverted-tet count: the caller sets `guess` and `start_inverted`).
    pub fn new(
        settings: &'a ImplicitSettings,
        (tangents, cache, anderson): (&'a mut [Box<dyn TangentOperator>], &'a mut SolveCache, &'a mut Anderson),
        start: StepStart<'a>,
        load_norm: f64,
    ) -> Self {
        let n = start.x0.len();
        ImplicitStep {
            settings,
            tangents,
            cache,
            guess: None,
            first_dx: None,
            merit_time: std::cell::Cell::new(0.0),
            inertia_at_eval: std::cell::Cell::new(None),
            start_inverted: None,
            start,
            load_norm,
            r: vec![Vec3::zeros(); n],
            r0: None,
            cg_iterations: 0,
            warnings: Vec::new(),
            last_solve: None,
            reused: false,
            fresh_iterations: 0,
            chord_iterations: 0,
            anderson,
        }
    }
}

impl ImplicitStep<'_> {
    /// d_i = x_i − x0_i − h v0_i on a free node.
    #[inline]
    fn d(&self, sys: &System, i: usize) -> Vec3 {
        self.start.d(&sys.state.x[i], &self.start.x0[i], &self.start.v0[i])
    }

    /// v⁺_i = v0_i + c_v d_i on a free node.
    #[inline]
    fn v(&self, sys: &System, i: usize) -> Vec3 {
        self.v_of(i, self.d(sys, i))
    }

    /// v⁺_i from a d_i already computed ([`Self::d`]).
    #[inline]
    fn v_of(&self, i: usize, d: Vec3) -> Vec3 {
        self.start.v(&self.start.v0[i], &d)
    }

    /// v⁺ = v0 + c_v d on the free nodes (constrained ones keep their imposed
    /// velocity). The forces held stay current when no velocity changed: at the end
    /// of a step whose last evaluation was at the final iterate (the usual case),
    /// they are the forces of the end state, bit for bit, and `finish_step` need
    /// not compute them again (one force evaluation per step saved).
    pub fn set_velocities(&self, sys: &mut System) {
        let mut changed = false;
        // zipped slices (no bounds checks per node): the same operations as
        // [`Self::v`], node by node
        let (x, v) = (&sys.state.x, &mut sys.state.v);
        let start = self.start.x0.iter().zip(self.start.v0);
        for (((vi, xi), (x0, v0)), &im) in v.iter_mut().zip(x).zip(start).zip(&sys.model.inv_mass) {
            if im > 0.0 {
                let vn = self.start.v(v0, &self.start.d(xi, x0, v0));
                // `!=` is true for NaN, so a non-finite velocity always counts as new
                changed |= vn != *vi;
                *vi = vn;
            }
        }
        if changed {
            sys.eval.forces_current = false;
        }
    }

    /// The merit's inertia term Σ ½ m_i (|a⁺_i|²/c_a + α |v⁺_i|²/c_v) over the free
    /// nodes: the incremental potential of the inertia, and of the mass damping
    /// −α M v⁺ (whose gradient it is too).
    fn inertia(&self, sys: &System) -> f64 {
        let alpha = sys.model.damping.alpha;
        let mut inertia = 0.0;
        for i in (0..sys.state.x.len()).filter(|&i| sys.model.inv_mass[i] > 0.0) {
            let d = self.d(sys, i);
            let a = self.start.a(&d, &self.start.a0[i]);
            inertia += node_inertia(sys.model.mass[i], &a, &self.v_of(i, d), &self.start, alpha);
        }
        inertia
    }

    /// a⁺ = c_a d − â on the free nodes, zero on the constrained ones.
    pub fn accelerations(&self, sys: &System) -> Vec<Vec3> {
        (0..sys.state.x.len())
            .map(|i| {
                if sys.model.inv_mass[i] > 0.0 {
                    self.start.a(&self.d(sys, i), &self.start.a0[i])
                } else {
                    Vec3::zeros()
                }
            })
            .collect()
    }

    /// The residual norm a step's iterations on a kept factor must reach (0 with
    /// CG, whose every iteration is a Newton iteration). With one Newton iteration
    /// per step: what it would leave, |r0|·(θ + (1 − θ)·c_fresh) with θ =
    /// [`ImplicitSettings::refactor_contraction`] and c_fresh the contraction of
    /// the last iteration on a fresh factor. With more, the Newton tolerance: a
    /// power of that per-iteration contraction would not be what Newton's
    /// quadratic convergence reaches (0.96³⁰ ≈ 0.3 of |r0| in a contact phase,
    /// where the converged steps must reach 1e-9). Never below the tolerance.
    fn chord_goal(&self) -> f64 {
        if self.settings.linear_solver != LinearSolver::Cholesky {
            return 0.0;
        }
        let Some(r0) = self.r0 else { return 0.0 };
        let tolerance = self.tolerance();
        if self.settings.newton_iterations > 1 {
            return tolerance;
        }
        let theta = self.settings.refactor_contraction;
        let fraction = (theta + (1.0 - theta) * self.cache.fresh_contraction).min(self.max_leftover());
        (r0 * fraction).max(tolerance)
    }

    /// The most of |r0| a step on the Cholesky factor may leave
    /// ([`MAX_STEP_LEFTOVER`], or θ when larger).
    fn max_leftover(&self) -> f64 {
        MAX_STEP_LEFTOVER.max(self.settings.refactor_contraction)
    }

    /// Whether the residual `r` is at most what a step on the Cholesky factor may
    /// leave (always with CG, whose iterations are capped by `newton_iterations`).
    fn within_leftover(&self, r: f64) -> bool {
        if self.settings.linear_solver != LinearSolver::Cholesky {
            return true;
        }
        let Some(r0) = self.r0 else { return true };
        r <= (r0 * self.max_leftover()).max(self.tolerance())
    }

    /// The Newton tolerance of the step: `newton_tolerance`·max(|r0|, |loads|), at
    /// least the residual's round-off (a body at rest has nothing left to solve).
    fn tolerance(&self) -> f64 {
        let r0 = self.r0.unwrap_or_else(|| norm(&self.r));
        (self.settings.newton_tolerance * r0.max(self.load_norm)).max(self.cache.roundoff)
    }

    /// Records the contraction c = |r after| / |r before| of the last linear solve
    /// and, with the Cholesky factor, decides whether the next iteration keeps the
    /// factor (the cost rule of [`ImplicitSettings::refactor_contraction`]). An
    /// iteration on a fresh factor sets the reference c_fresh (what the
    /// nonlinearity leaves). After an iteration on a kept factor (a chord
    /// iteration) the step goes on with the factor when the residual reached the
    /// step's goal ([`Self::chord_goal`]), or when its contraction c < 0.9
    /// ([`MAX_CHORD_CONTRACTION`]) predicts reaching the goal in m = ⌈ln(goal/|r|)
    /// / ln c⌉ more chord iterations costing at most a refactorisation and the
    /// fresh iteration after it: m ≤ [`REFACTOR_COST_IN_CHORDS`] + 1 (a fixed
    /// cost ratio, so that runs replay). Otherwise the next solve refactors.
    pub fn check_contraction(&mut self) {
        let Some((before, reused)) = self.last_solve.take() else {
            return;
        };
        let r = norm(&self.r);
        let contraction = if before > 0.0 { r / before } else { 0.0 };
        self.cache.times.contraction = contraction;
        if !reused {
            self.cache.fresh_contraction = contraction.min(1.0);
            return;
        }
        let goal = self.chord_goal();
        let keep = r <= goal
            || (contraction < MAX_CHORD_CONTRACTION && {
                // both logarithms negative: m ≥ 1 more iterations
                let more = ((goal / r).ln() / contraction.ln()).ceil();
                more <= REFACTOR_COST_IN_CHORDS + 1.0
                    && self.chord_iterations.saturating_add(more as usize) <= MAX_CHORD_ITERATIONS
            });
        if !keep {
            self.cache.refactor = true;
        }
    }

    /// |r| / |r0| now (0 before the first solve).
    pub fn leftover(&self) -> f64 {
        match self.r0 {
            Some(r0) if r0 > 0.0 => norm(&self.r) / r0,
            _ => 0.0,
        }
    }

    /// Forgets the step's Newton history (the start residual, the last solve, the
    /// first correction, the reuse), to run its iterations again from the predictor.
    pub fn restart(&mut self) {
        self.r0 = None;
        self.last_solve = None;
        self.reused = false;
        self.first_dx = None;
        self.fresh_iterations = 0;
        self.chord_iterations = 0;
        self.anderson.clear();
    }

    /// Mass coefficient c_a + α c_v and stiffness coefficient 1 + β c_v.
    fn coefficients(&self, sys: &System) -> (f64, f64) {
        (
            self.start.ca + sys.model.damping.alpha * self.start.cv,
            1.0 + sys.model.damping.beta * self.start.cv,
        )
    }
}

/// One free node's term of the merit's inertia ([`ImplicitStep::inertia`]) at mass
/// `m`, a⁺ `a` and v⁺ `v`, with the step's c_a, c_v and the mass damping α.
#[inline]
fn node_inertia(m: f64, a: &Vec3, v: &Vec3, s: &StepStart, alpha: f64) -> f64 {
    0.5 * m * (a.norm_squared() / s.ca + alpha * v.norm_squared() / s.cv)
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
        // chord iterations end the step at the residual its Newton iterations would
        // leave; Newton iterations proper (on a fresh factor, or CG) at their cap,
        // once the residual is within what a step may leave (the Cholesky factor;
        // else chord iterations on the fresh factor, or more factorisations, follow)
        let fresh_cap = self.settings.newton_iterations;
        let done = r <= self.tolerance()
            || (self.chord_iterations > 0 && r <= self.chord_goal())
            || (self.fresh_iterations >= fresh_cap && self.within_leftover(r))
            || self.fresh_iterations >= fresh_cap + MAX_EXTRA_FACTORIZATIONS
            || it >= self.max_iterations();
        done.then_some(NewtonOutcome { iterations: it })
    }

    fn max_iterations(&self) -> usize {
        match self.settings.linear_solver {
            LinearSolver::Cg => self.settings.newton_iterations,
            LinearSolver::Cholesky => self.settings.newton_iterations + MAX_CHORD_ITERATIONS,
        }
    }

    fn solve_linear(&mut self, sys: &System, dofs: &DofMap, rhs: &mut [f64]) -> Result<bool> {
        let first = self.r0.is_none();
        if first {
            self.r0 = Some(norm(&self.r));
        }
        self.check_contraction();
        let (cm, ck) = self.coefficients(sys);
        let s = self.settings;
        let solve = TangentSolve {
            ck,
            cm,
            cv: self.start.cv,
            tol: s.cg_tolerance,
            max_iterations: s.cg_max_iterations,
            preconditioner: s.preconditioner,
            linear_solver: s.linear_solver,
            reuse_factor: !self.cache.refactor,
            contact_corrections: s.contact_corrections,
            max_factor_nonzeros: s.max_factor_nonzeros,
            cholesky_ordering: s.cholesky_ordering,
            factor_precision: s.factor_precision,
        };
        let guess = self.guess.take().filter(|g| first && g.len() == rhs.len());
        let (factorizations, corrections) = (self.cache.factorizations, self.cache.corrections);
        let direct = s.linear_solver == LinearSolver::Cholesky;
        let residual = direct.then(|| rhs.to_vec());
        let report = solve.solve(sys, self.tangents, self.cache, dofs, rhs, guess.as_deref())?;
        let reused = direct && self.cache.factorizations == factorizations;
        if let Some(r) = residual {
            // chord iterations mixed with the step's earlier iterates on this matrix
            // (factor and contact correction)
            if !reused || self.cache.corrections != corrections {
                self.anderson.clear();
            }
            self.anderson.mix(&dofs.gather(&sys.state.x), rhs, &r);
        }
        self.cache.refactor = false;
        self.reused |= reused;
        if reused {
            self.chord_iterations += 1;
        } else {
            self.fresh_iterations += 1;
        }
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
        // the evaluation at these positions summed it (the line search always
        // evaluates before it asks for the merit); computed here otherwise
        let inertia = self.inertia_at_eval.take().unwrap_or_else(|| self.inertia(sys));
        // the grasp dampers' −c v⁺ is the gradient of c/(2 c_v)·|v⁺|² (a constrained
        // node's imposed velocity does not depend on x⁺: a constant there)
        let v_plus = |i: usize| {
            if sys.model.inv_mass[i] > 0.0 {
                self.v(sys, i)
            } else {
                sys.state.v[i]
            }
        };
        let dampers = sys.model.grasps.damper_potential(v_plus, self.start.cv);
        Ok(e.elastic + e.gravity + e.loads + sys.model.tools.energy() + inertia + dampers)
    }

    /// The inverted tets: a Newton (or chord) step must not invert more. The
    /// laws' J0 extension keeps the energy finite through J = 0 (DESIGN §1), so the
    /// merit alone lets a step on a stale or projected tangent fold a tet over
    /// (on gen_kidney_100k's grasp after a press, one step took a tet from
    /// J = 0.43 to −2.95, and the motion diverged from there); halving the step
    /// until no new tet inverts keeps the iterates where the law is physical.
    fn infeasibility(&self, sys: &System) -> Option<usize> {
        Some(inverted_tets(sys, &sys.state.x))
    }

    fn starting_infeasibility(&self) -> Option<Option<usize>> {
        self.start_inverted.map(Some)
    }
}

/// The alive tets of `sys` whose signed volume at positions `x` (by node) is not
/// positive (rest tets are positively oriented, so these are the inverted ones):
/// only positions, ~a tenth of a force evaluation's work, in parallel.
pub(super) fn inverted_tets(sys: &System, x: &[Vec3]) -> usize {
    use rayon::prelude::*;
    let alive: Option<&[bool]> = sys.model.cut.topo.as_ref().map(|t| &t.alive[..]);
    // branch-free per tet (a count, not a filter): the liver's 596 tets are
    // counted about four times per implicit step
    let count = |first: usize, tets: &[[u32; 4]]| -> usize {
        let mut n = 0;
        for (k, idx) in tets.iter().enumerate() {
            let [a, b, c, d] = crate::mesh::corners(x, idx);
            let flipped = (b - a).cross(&(c - a)).dot(&(d - a)) <= 0.0;
            let live = alive.is_none_or(|al| al.get(first + k).copied().unwrap_or(true));
            n += usize::from(flipped & live);
        }
        n
    };
    let tets = sys.model.mesh.tets();
    if tets.len() < 2 * SEQUENTIAL_TETS {
        count(0, tets)
    } else {
        tets.par_chunks(SEQUENTIAL_TETS)
            .enumerate()
            .map(|(c, chunk)| count(c * SEQUENTIAL_TETS, chunk))
            .sum()
    }
}

/// Tets per parallel chunk of [`inverted_tets`]: below twice this it runs on the
/// calling thread.
const SEQUENTIAL_TETS: usize = 8192;

impl ImplicitStep<'_> {
    /// [`NewtonProblem::evaluate`] without the timing.
    fn evaluate_inner(&mut self, sys: &mut System) -> Result<()> {
        self.inertia_at_eval.set(None);
        self.set_velocities(sys);
        sys.invalidate();
        // no rollback here: a failed line-search trial must leave the step going
        sys.compute_forces_inner(true)?;
        // r = f − M a⁺ with a⁺ of [`Self::accelerations`] computed in place (the
        // same operations per node, so the same bits): no vector allocated and one
        // pass over the nodes less per evaluation (a chord step evaluates twice)
        // The merit's inertia term ½ m (|a⁺|²/c_a + α |v⁺|²/c_v) is summed in the same
        // pass, node by node in the same order as [`Self::inertia`] (so the same
        // bits): the line search asks for the merit right after each evaluation.
        let alpha = sys.model.damping.alpha;
        let mut inertia = 0.0;
        let start = self.start.x0.iter().zip(self.start.v0).zip(self.start.a0);
        let node = sys
            .state
            .x
            .iter()
            .zip(&sys.eval.force)
            .zip(sys.model.inv_mass.iter().zip(&sys.model.mass));
        for ((ri, ((x0, v0), a0)), ((xi, fi), (&im, &m))) in self.r.iter_mut().zip(start).zip(node) {
            *ri = if im > 0.0 {
                let d = self.start.d(xi, x0, v0);
                let a = self.start.a(&d, a0);
                inertia += node_inertia(m, &a, &self.start.v(v0, &d), &self.start, alpha);
                fi - a * m
            } else {
                Vec3::zeros()
            };
        }
        self.inertia_at_eval.set(Some(inertia));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::system::tests::{cube, neo};

    /// A damped, gravity-loaded cube with its bottom fixed, moved off its start, and
    /// an implicit step's problem on it (backward Euler, h = 10 ms).
    fn problem_at(sys: &mut System, h: f64) -> (Vec<Vec3>, Vec<Vec3>, Vec<Vec3>) {
        let n = sys.state.x.len();
        let x0 = sys.state.x.clone();
        let v0: Vec<Vec3> = (0..n).map(|i| Vec3::new(0.01 * i as f64, -0.02, 0.03)).collect();
        let free = sys.model.inv_mass.iter().map(|&im| im > 0.0);
        for (i, ((x, v), free)) in sys.state.x.iter_mut().zip(&v0).zip(free).enumerate() {
            if free {
                let s = i as f64;
                *x += v * h + Vec3::new(1e-3 * s.sin(), 2e-3 * s.cos(), -1e-3);
            }
        }
        (x0, v0, vec![Vec3::zeros(); n])
    }

    fn damped_cube() -> System {
        let bottom: Vec<usize> = (0..27).filter(|&i| cube().nodes()[i].z == 0.0).collect();
        System::builder(cube())
            .material_law(neo(1e3, 4e3))
            .density(1e3)
            .gravity(Vec3::new(0.0, 0.0, -9.81))
            .rayleigh(3.0, 0.0)
            .fix_nodes(bottom)
            .build()
            .unwrap()
    }

    /// The merit takes the inertia term the evaluation summed at the same positions
    /// (one pass over the nodes less per line-search trial): it must be the value the
    /// merit computes on its own, to the bit, and the merit's gradient must be −r
    /// (checked by central differences along one direction; tolerance: the
    /// difference quotient's truncation, O(ε²·|∇³merit|), and round-off
    /// |merit|·1e-16/ε, both far below 1e-6 of the directional derivative here).
    #[test]
    fn merit_inertia_from_the_evaluation_is_the_merits_own() {
        let h = 0.01;
        let mut sys = damped_cube();
        let (x0, v0, a0) = problem_at(&mut sys, h);
        let (settings, mut cache, mut anderson) =
            (ImplicitSettings::default(), SolveCache::default(), Anderson::default());
        let start = StepStart {
            x0: &x0,
            v0: &v0,
            a0: &a0,
            h,
            ca: 1.0 / (h * h),
            cv: 1.0 / h,
        };
        let mut p = ImplicitStep::new(&settings, (&mut [], &mut cache, &mut anderson), start, 1.0);
        let n = x0.len();
        p.evaluate(&mut sys).unwrap();
        assert!(p.inertia_at_eval.get().is_some_and(|e| e > 0.0));
        let fused = p.merit(&sys).unwrap();
        assert!(
            p.inertia_at_eval.get().is_none(),
            "the merit takes the evaluation's value"
        );
        let own = p.merit(&sys).unwrap();
        assert_eq!(fused.to_bits(), own.to_bits());

        // −∇merit = r along a direction on the free nodes
        let dir: Vec<Vec3> = (0..n)
            .map(|i| {
                let s = i as f64;
                if sys.model.inv_mass[i] > 0.0 {
                    Vec3::new((1.3 * s).cos(), (0.7 * s).sin(), 0.5)
                } else {
                    Vec3::zeros()
                }
            })
            .collect();
        let slope: f64 = -p.r.iter().zip(&dir).map(|(r, d)| r.dot(d)).sum::<f64>();
        let x = sys.state.x.clone();
        let eps = 1e-6;
        let mut merit_at = |t: f64| {
            for i in 0..n {
                sys.state.x[i] = x[i] + dir[i] * t;
            }
            p.evaluate(&mut sys).unwrap();
            p.merit(&sys).unwrap()
        };
        let fd = (merit_at(eps) - merit_at(-eps)) / (2.0 * eps);
        assert!((fd - slope).abs() <= 1e-6 * slope.abs(), "fd {fd} vs −r·dir {slope}");
    }
}
