//! The public settings of the implicit integrators.

use super::ordering::CholeskyOrdering;
use super::precision::FactorPrecision;
use crate::error::{HemlError, Result};

/// Which implicit scheme an [`super::ImplicitSolver`] steps with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImplicitScheme {
    /// Backward (implicit) Euler: M(v⁺ − v)/h = f(x + h v⁺, v⁺). First order,
    /// unconditionally stable, numerically dissipative (damps high frequencies).
    BackwardEuler,
    /// Newmark average acceleration (β = 1/4, γ = 1/2, the trapezoidal rule): second
    /// order, unconditionally stable, no numerical dissipation (undamped energy is
    /// conserved up to the Newton/CG tolerances for linear problems).
    Newmark,
}

/// What happens when conjugate gradients stop before their tolerance (iteration cap,
/// or an indefinite tangent when the projection is off).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CgFailure {
    /// Use the approximate solution and record a warning (step, residual) in
    /// [`crate::system::System::warnings`] (the default).
    #[default]
    Warn,
    /// Fail the step with an error (the system keeps its state before the step).
    Refuse,
    /// Use the approximate solution silently: the iteration cap is a work budget
    /// (the interactive preset, [`ImplicitSettings::interactive`]). An indefinite
    /// tangent (CG breakdown) still warns.
    Continue,
}

/// The preconditioner of the implicit integrators' conjugate gradients.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CgPreconditioner {
    /// The inverse of each node's 3×3 diagonal block: cheapest per iteration and
    /// parallel, but the iteration count grows with the mesh resolution.
    BlockJacobi,
    /// Symmetric block Gauss–Seidel (SSOR with ω = 1) on the assembled matrix: a
    /// forward and a backward sweep over all nodes per iteration (sequential), several
    /// times fewer iterations than block-Jacobi on soft, nearly incompressible tissue
    /// (the default: on the 2-core machine it was measured faster than the parallel
    /// variant below, whose fork–joins per iteration wait for a busy core).
    #[default]
    SymmetricGaussSeidel,
    /// Symmetric block Gauss–Seidel inside each of a fixed number of contiguous node
    /// ranges (up to 8, at least 512 nodes each; block-Jacobi between them), the
    /// ranges swept in parallel: nearly the sequential sweep's iteration count at a
    /// fraction of its time on several threads, the same bits for any thread count.
    ParallelGaussSeidel,
}

/// How the Newton steps of the implicit integrators solve their linear systems.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LinearSolver {
    /// Preconditioned conjugate gradients on the assembled tangent, refilled at every
    /// Newton iteration (the default): no fill-in, so memory stays linear in the
    /// mesh, and the interactive preset caps its work per step.
    #[default]
    Cg,
    /// Sparse Cholesky (LLᵀ, faer, the ordering of [`ImplicitSettings::cholesky_ordering`]) of the system
    /// matrix, factored once and reused across Newton iterations and steps (chord,
    /// or modified, Newton): a stale factor still gives a descent direction (it is
    /// positive definite), only the contraction per iteration drops, so a step
    /// may take several cheap iterations on it where a fresh factor would take
    /// one. It is refreshed when those iterations would cost more than a
    /// refactorisation (the rule of [`ImplicitSettings::refactor_contraction`]),
    /// after a failed step or a stalled line search, and after any change of the
    /// matrix: fixed nodes, cuts, a grasp made or opened, a tool contact made or
    /// released (or its normal turned by more than 5.7°), the step size or the
    /// scheme (not a grasp or tool moved without that, nor loads). The converged
    /// step is the same as with CG; what is saved is the tangent update, assembly
    /// and factorisation of every iteration that reuses the factor.
    Cholesky,
}

/// Settings of the implicit integrators (`backward_euler`, `newmark`).
///
/// The default is accurate (CG to 1e-6, up to 1000 iterations); [`Self::interactive`]
/// is the preset for real-time stepping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImplicitSettings {
    /// Newton iterations per step at most (default 1: one linearised solve per step,
    /// as SOFA's EulerImplicit does; the equilibrium of a steady state is reached
    /// exactly whatever the count). With [`LinearSolver::Cholesky`] these are the
    /// iterations on a fresh factor; iterations on a kept factor (chord iterations)
    /// come on top, until they reach what these would (see
    /// [`Self::refactor_contraction`]).
    pub newton_iterations: usize,
    /// Newton stops early when the residual norm is at most this fraction of the
    /// larger of its value at the start of the step and the norm of the external
    /// loads (default 1e-6), or at the residual's round-off (a body at rest without
    /// loads: then the step takes no linear solve at all).
    pub newton_tolerance: f64,
    /// Conjugate gradients stop when ‖b − A x‖ ≤ `cg_tolerance`·‖b‖ (default 1e-6).
    pub cg_tolerance: f64,
    /// Conjugate-gradient iterations per linear solve at most (default 1000).
    pub cg_max_iterations: usize,
    /// What a solve that misses its tolerance does (default: warn).
    pub cg_failure: CgFailure,
    /// Project each tet's stiffness to positive semi-definite (default true), so that
    /// the system matrix K + c·M stays positive definite and CG cannot break down.
    pub project_psd: bool,
    /// The CG preconditioner (default the sequential symmetric block Gauss–Seidel).
    pub preconditioner: CgPreconditioner,
    /// Start each step's first CG solve from the previous step's Newton correction
    /// (default true): in a smooth motion it is close to the new one, so fewer
    /// iterations reach the tolerance.
    pub warm_start: bool,
    /// The linear solver of the Newton steps (default conjugate gradients).
    pub linear_solver: LinearSolver,
    /// [`LinearSolver::Cholesky`]: θ of the factor-reuse rule, in (0, 1) (default
    /// 0.2). With c_fresh the residual contraction of the last iteration on a
    /// fresh factor (what one Newton iteration achieved), the iterations of a step
    /// on a kept factor (chord iterations, each a force evaluation and two
    /// triangular solves, Anderson-mixed) go on until the residual is at most
    /// |r0|·(θ + (1 − θ)·c_fresh) with one Newton iteration per step (the imbalance
    /// that iteration would leave, loosened by θ), or the Newton tolerance with
    /// more. They stop
    /// earlier and refactor when one contracts by 0.9 or worse, or when its
    /// contraction c predicts more iterations to that goal, ⌈ln(goal/|r|)/ln c⌉,
    /// than one refactorisation costs (tangent, assembly and factorisation, in
    /// chord iterations: a fixed 20, measured 15–25 on the benchmark's meshes, so
    /// that runs replay to the same bits): the step then goes on with a Newton
    /// iteration on the fresh factor. So a leftover carried into the next step is
    /// never a stale factor's: every step solves its equations to at least
    /// θ + (1 − θ)·c_fresh of its initial residual, and to at most a quarter of
    /// it (or θ when larger): a Newton iteration on a fresh factor that leaves
    /// more (a tool's contacts made within the step) is followed by chord
    /// iterations on that factor, and by at most two more factorisations, until
    /// it does (without that bound the one-iteration steps of a tool pressing on
    /// gen_kidney_100k left 0.3–2.3 of their residual and the motion diverged;
    /// [`super::PhaseTimes::leftover`] reports what each step left).
    /// The chord iterations converge to the exact step (the root of the step's
    /// equations, as Newton's do); with one Newton iteration per step (the
    /// presets) a step is stopped at the imbalance one Newton iteration leaves,
    /// plus θ·(1 − c_fresh) of its initial residual. θ = 0.2 was the bound a
    /// carried leftover needed on gen_kidney_20k's grasp (`heml bench --implicit`'s
    /// long run): at 0.5 chord steps contracting by 0.3–0.5 where a fresh factor
    /// reached 0.06 piled up their leftovers until the motion diverged.
    pub refactor_contraction: f64,
    /// [`LinearSolver::Cholesky`]: the most nonzeros the factor may hold (8 bytes
    /// each), checked after the symbolic analysis and before any allocation of the
    /// factor; a mesh whose factor would be larger fails the step with an error that
    /// names both numbers (default 5·10⁷, 400 MB).
    pub max_factor_nonzeros: usize,
    /// [`LinearSolver::Cholesky`]: correct a kept factor for the tool contacts made,
    /// released or turned since it was made by a low-rank (Sherman–Morrison–Woodbury)
    /// update, one pair of triangular solves per contact changed, instead of
    /// refactoring (default true). The contact springs then enter every solve
    /// exactly, over the kept factor's elastic part; after 20 such column solves on
    /// one factor (a refactorisation's fixed cost in chord iterations) a contact
    /// change refactors. On `heml bench --implicit`'s long run this took the
    /// liver's press phase from 28 factorisations to 4. False: every contact
    /// change refactors (the rule before session 16).
    pub contact_corrections: bool,
    /// [`LinearSolver::Cholesky`]: the fill-reducing ordering of the factor (default
    /// [`CholeskyOrdering::Auto`]: METIS nested dissection of the node graph from
    /// 3000 unknowns on, which on gen_kidney_20k's system holds 0.8× the fill of the
    /// AMD used before session 17 (gen_kidney_100k 0.63×); faer's AMD below).
    pub cholesky_ordering: CholeskyOrdering,
    /// [`LinearSolver::Cholesky`]: the precision of the factor (default
    /// [`FactorPrecision::Auto`]: f32 for time steps from 256 unknowns on, which on
    /// gen_kidney_20k factors ~2× and solves ~1.8× faster, the liver's long run
    /// 6–12 %; f64 for static solves and tiny systems). The factor preconditions iterations on exact f64 residuals, so
    /// the precision changes how fast a step converges, never what it converges to.
    pub factor_precision: FactorPrecision,
}

impl Default for ImplicitSettings {
    fn default() -> Self {
        ImplicitSettings {
            newton_iterations: 1,
            newton_tolerance: 1e-6,
            cg_tolerance: 1e-6,
            cg_max_iterations: 1000,
            cg_failure: CgFailure::Warn,
            project_psd: true,
            preconditioner: CgPreconditioner::SymmetricGaussSeidel,
            warm_start: true,
            linear_solver: LinearSolver::Cg,
            refactor_contraction: 0.2,
            max_factor_nonzeros: 50_000_000,
            contact_corrections: true,
            cholesky_ordering: CholeskyOrdering::Auto,
            factor_precision: FactorPrecision::Auto,
        }
    }
}

impl ImplicitSettings {
    /// The preset for interactive stepping (haptics, surgical simulation at 1–40 ms
    /// steps), as SOFA's EulerImplicit + CG is used: one Newton iteration, CG to a
    /// relative residual of 1e-3 or at most 30 iterations (warm-started from the
    /// previous step), a capped solve continuing silently. Each step then costs a
    /// bounded amount of work; the price is a small force imbalance per step, which
    /// the next steps keep correcting (the residual is always the exact one), so a
    /// steady state is still reached exactly — only the transient differs from the
    /// accurate default's. The cap usually binds before the tolerance: on a
    /// 20k-tet kidney at ν = 0.49 and 10 ms the 30 iterations reach a relative
    /// residual of ~1e-2 (6e-2 on 90k tets; [`super::PhaseTimes::cg_residual`] reports
    /// it per step), 1e-3 on the 596-tet SOFA liver.
    ///
    /// ```
    /// use heml_core::system::{CgFailure, ImplicitSettings};
    /// let s = ImplicitSettings::interactive();
    /// assert_eq!(s.cg_max_iterations, 30);
    /// assert_eq!(s.cg_failure, CgFailure::Continue);
    /// s.validate().unwrap();
    /// ```
    pub fn interactive() -> Self {
        ImplicitSettings {
            newton_iterations: 1,
            cg_tolerance: 1e-3,
            cg_max_iterations: 30,
            cg_failure: CgFailure::Continue,
            ..ImplicitSettings::default()
        }
    }

    /// Checks the ranges: at least one Newton and one CG iteration (at most 100 Newton
    /// iterations), a positive factor cap, tolerances and the refactor contraction finite and in (0, 1).
    pub fn validate(&self) -> Result<()> {
        if !(1..=100).contains(&self.newton_iterations) {
            return Err(HemlError::Invalid(format!(
                "newton_iterations = {} must lie in 1..=100",
                self.newton_iterations
            )));
        }
        if self.cg_max_iterations == 0 {
            return Err(HemlError::Invalid("cg_max_iterations must be at least 1".into()));
        }
        if self.max_factor_nonzeros == 0 {
            return Err(HemlError::Invalid("max_factor_nonzeros must be at least 1".into()));
        }
        for (name, v) in [
            ("newton_tolerance", self.newton_tolerance),
            ("cg_tolerance", self.cg_tolerance),
            ("refactor_contraction", self.refactor_contraction),
        ] {
            if !(v > 0.0 && v < 1.0) {
                return Err(HemlError::Invalid(format!("{name} = {v} must lie in (0, 1)")));
            }
        }
        Ok(())
    }
}
