//! Implicit time integration: backward Euler and Newmark (average acceleration) on
//! the Newton core the static solver uses, with preconditioned conjugate gradients
//! on the exact tangent stiffness generated from each law's second derivatives
//! ([`crate::force::tangent`]).
//!
//! Per step, Newton iterations (by default one, as SOFA's EulerImplicit) in the
//! end-of-step positions solve r(x⁺) = f(x⁺, v⁺) − M a⁺ = 0 (see `problem.rs` for
//! both schemes' a⁺ and v⁺); each linear system (1 + β c_v) K + (c_a + α c_v) M,
//! restricted to the free nodes (fixed and prescribed nodes are imposed by the
//! system and excluded), is assembled in 3×3 blocks by node pairs (`matrix.rs`:
//! pattern built once per mesh, values refilled in parallel, the same bits for any
//! thread count) and solved by conjugate gradients with a symmetric block
//! Gauss–Seidel preconditioner, by default swept in parallel in a separator
//! ordering (`matrix/gauss_seidel.rs`; sequential or 3×3 block-Jacobi by
//! [`CgPreconditioner`]), the dot products fused into the passes (`cg.rs`),
//! warm-started from the previous step's correction. Each tet's stiffness is
//! projected to positive semi-definite by default ([`ImplicitSettings::project_psd`]),
//! so the system matrix is positive definite and CG cannot break down; unprojected,
//! an indefinite tangent stops CG with a warning (or an error, by [`CgFailure`]). A
//! damped Newton line search on the incremental potential keeps large steps robust.
//! Non-finite states roll back exactly as for the explicit integrators.
//! [`ImplicitSettings::interactive`] caps the work per step for real-time use.
//!
//! [`LinearSolver::Cholesky`] replaces CG by a sparse Cholesky factor of the same
//! matrix (`cholesky.rs`, faer; symbolic analysis once per pattern, fill capped by
//! [`ImplicitSettings::max_factor_nonzeros`]) that the same Newton loop reuses across
//! iterations and steps (chord Newton): an iteration on a kept factor skips the
//! tangent update, the assembly and the factorisation, and is Anderson-mixed with
//! the step's earlier iterates on that factor (`anderson.rs`: a multisecant
//! quasi-Newton step on the same equations, recovering the modes the stale factor
//! misses). Such chord iterations go on until the residual reaches what one
//! fresh Newton iteration would leave (loosened by
//! [`ImplicitSettings::refactor_contraction`]; the Newton tolerance when a step
//! allows more than one); the factor is refreshed within the
//! step when their observed contraction (0.9 or worse, or a predicted count of
//! iterations to that goal costing more than a refactorisation, a fixed ratio so
//! that runs replay) says a refactorisation is cheaper, when a line search on it stalls, and
//! after a change of the matrix's coefficients or grasps (not after a grasp or tool
//! moved without changing the contacts, or a load changed). Tool contacts made,
//! released or turned since the factorisation are corrected exactly by low rank on
//! the kept factor (`woodbury.rs`, Sherman–Morrison–Woodbury: one pair of
//! triangular solves per contact changed) until that has cost a refactorisation.
//! A residual at round-off (a body at rest) is converged: such a step takes no
//! linear solve.

mod anderson;
pub mod cg;
mod cholesky;
pub(super) mod linear;
mod matrix;
mod ordering;
mod precision;
mod problem;
mod settings;
mod solver;
mod timings;
mod trisolve;
mod woodbury;

pub use ordering::{CholeskyOrdering, AUTO_NESTED_DISSECTION};
pub use precision::{FactorPrecision, AUTO_SINGLE};
pub use settings::{CgFailure, CgPreconditioner, ImplicitScheme, ImplicitSettings, LinearSolver};
pub use solver::ImplicitSolver;
pub use timings::PhaseTimes;
