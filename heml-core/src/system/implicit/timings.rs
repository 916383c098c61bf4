//! Where the time of an implicit step goes, for benchmarks and tuning, and the
//! accuracy its linear solves reached.

/// Wall-clock seconds spent in the phases of the last implicit step
/// ([`super::ImplicitSolver::last_phase_times`]); `total` is the whole step, the
/// rest of it (line-search bookkeeping, constraints, energies) is not itemised.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhaseTimes {
    /// Force (residual) evaluations and line-search merits.
    pub forces: f64,
    /// Per-tet tangent stiffness updates (Hessians and PSD projection).
    pub tangent: f64,
    /// Filling the assembled system matrix and its preconditioner.
    pub assembly: f64,
    /// The linear solves: conjugate-gradient iterations, or the triangular solves of
    /// a Cholesky factor.
    pub cg: f64,
    /// Sparse Cholesky factorisations (symbolic analysis included the first time).
    pub factor: f64,
    /// The whole step.
    pub total: f64,
    /// Not a time: the largest relative residual ‖b − A x‖/‖b‖ the step's CG solves
    /// stopped at (the accuracy bought by the `cg` time; 0 without a solve).
    pub cg_residual: f64,
    /// Not a time: the numeric Cholesky factorisations of the step (0 with CG; fewer
    /// than the Newton iterations when the factor is reused).
    pub factorizations: usize,
    /// Not a time: the columns of low-rank contact corrections the step solved for
    /// on a kept factor (one pair of triangular solves each; their time is in
    /// `factor`), instead of refactoring for contacts made or released.
    pub correction_columns: usize,
    /// Not a time: the residual norm at the end of the step over its value before
    /// the step's last linear solve (how much that Newton or chord iteration
    /// contracted it; 0 without a solve). With one iteration per step it is what
    /// the step solved: a fresh factor (or a converged CG) leaves the
    /// nonlinearity's share, a stale factor more.
    pub contraction: f64,
    /// Not a time: the residual norm at the end of the step over its norm at the
    /// start (0 when the step took no solve): what the step left of its equations.
    /// With the Cholesky factor it is at most 0.25 (or `refactor_contraction`)
    /// unless the step reached its cap of iterations or factorisations.
    pub leftover: f64,
}
