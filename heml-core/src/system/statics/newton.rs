//! Damped Newton iterations over the free coordinates of a [`DofMap`], independent
//! of what the residual is and how the linear system is solved: the caller's
//! [`NewtonProblem`] evaluates the residual, solves its tangent system and gives the
//! line-search merit. The static equilibrium is one such problem (`equilibrium.rs`,
//! banded LDLᵀ); an implicit time step (`system::implicit`: residual f − M a,
//! tangent K + c M, merit the incremental potential, conjugate gradients) is another.
//!
//! Each iteration solves the tangent system for the full step and backtracks (halving, at most [`MAX_HALVINGS`] times) until the merit does not
//! increase or the residual norm decreases, on trial points no less feasible than
//! the iterate (no more inverted tets, for the implicit steps). A vanishing pivot, a failed line search
//! or [`MAX_ITERATIONS`] without convergence ends the iteration without an error, so
//! that the caller can go on with a more robust method from the current iterate.

use super::dofs::DofMap;
use crate::error::Result;
use crate::system::System;
use crate::Vec3;

/// Newton iterations before giving up (a converging Newton needs far fewer), unless
/// the problem sets its own cap ([`NewtonProblem::max_iterations`]).
const MAX_ITERATIONS: usize = 50;
/// Step halvings of the line search before giving up (2⁻¹² ≈ 2.4e-4 of the step).
const MAX_HALVINGS: usize = 12;

/// What a Newton solve needs from the problem it solves. The unknowns are the free
/// coordinates of the system's positions, numbered by the [`DofMap`] passed along.
pub(in crate::system) trait NewtonProblem {
    /// What a converged solve returns.
    type Report;

    /// Evaluates the residual at the system's current positions. An error makes a
    /// line-search trial fail (and, for the starting point, ends the solve with it).
    fn evaluate(&mut self, sys: &mut System) -> Result<()>;

    /// The out-of-balance force per node from the last [`NewtonProblem::evaluate`]:
    /// the Newton step solves K dx = residual.
    fn residual<'s>(&'s self, sys: &'s System) -> &'s [Vec3];

    /// `Some(report)` when the last evaluation meets the convergence criterion;
    /// `it` is the iteration count and `step` the line-search factor of the last
    /// step taken (0 before the first).
    fn converged(&self, sys: &System, it: usize, step: f64) -> Option<Self::Report>;

    /// Solves T dx = rhs in place, T = −∂residual/∂x the tangent at the current
    /// positions (`rhs` is the residual gathered by degree of freedom). `Ok(false)`
    /// when the tangent cannot be solved (the Newton iteration then gives up without
    /// an error); an error ends the solve with it.
    fn solve_linear(&mut self, sys: &System, dofs: &DofMap, rhs: &mut [f64]) -> Result<bool>;

    /// The cap on Newton iterations.
    fn max_iterations(&self) -> usize {
        MAX_ITERATIONS
    }

    /// The merit the line search must not increase (e.g. the total potential), at
    /// the current positions.
    fn merit(&self, sys: &System) -> Result<f64>;

    /// A count the line search must not increase (checked on every trial point,
    /// compared with the iterate the iteration starts from): e.g. the inverted
    /// tets. `None` (the default): no such check.
    fn infeasibility(&self, _sys: &System) -> Option<usize> {
        None
    }

    /// [`NewtonProblem::infeasibility`] at the starting positions when the problem
    /// already knows it (the implicit step's predictor counted its inverted tets),
    /// so that the first iteration does not count again. `None` (the default): it
    /// is computed.
    fn starting_infeasibility(&self) -> Option<Option<usize>> {
        None
    }
}

/// Runs damped Newton iterations from the system's current positions.
///
/// `Ok(Some(report))` when converged; `Ok(None)` when the tangent cannot be solved, the line search stalls (positions restored to the last iterate) or the
/// iterations run out (positions left at the last iterate). Errors come from the
/// first evaluation and from the merit.
pub(in crate::system) fn newton<P: NewtonProblem>(
    sys: &mut System,
    dofs: &DofMap,
    problem: &mut P,
) -> Result<Option<P::Report>> {
    let norm2 = |f: &[Vec3]| f.iter().map(|v| v.norm_squared()).sum::<f64>();
    problem.evaluate(sys)?;
    let mut step_taken = 0.0;
    // the merit at the iterate the last line search accepted: the next iteration
    // starts there (the linear solve changes no position), so it is not evaluated
    // again (same value, one merit less per iteration)
    let mut accepted_merit: Option<f64> = None;
    // likewise the infeasibility count of the accepted trial
    let mut accepted_infeasibility: Option<Option<usize>> = problem.starting_infeasibility();
    let max_iterations = problem.max_iterations();
    // the iterate a line search starts from (one buffer for all iterations)
    let mut x0: Vec<Vec3> = Vec::new();
    for it in 0..=max_iterations {
        if let Some(report) = problem.converged(sys, it, step_taken) {
            return Ok(Some(report));
        }
        if it == max_iterations {
            break;
        }
        let mut dx = dofs.gather(problem.residual(sys));
        if !problem.solve_linear(sys, dofs, &mut dx)? {
            return Ok(None);
        }
        x0.clone_from(&sys.state.x);
        let r0 = norm2(problem.residual(sys));
        let e0 = match accepted_merit.take() {
            Some(e) => e,
            None => problem.merit(sys)?,
        };
        let infeasible = match accepted_infeasibility.take() {
            Some(n) => n,
            None => problem.infeasibility(sys),
        };
        let mut step = 1.0;
        let mut accepted = false;
        for _ in 0..MAX_HALVINGS {
            dofs.step(&mut sys.state.x, &x0, &dx, step);
            sys.invalidate();
            // a trial that makes things less feasible (say, inverts a tet) is
            // halved before its forces are computed
            let trial = infeasible.and_then(|_| problem.infeasibility(sys));
            let feasible = infeasible.is_none_or(|base| trial.is_none_or(|n| n <= base));
            if feasible && problem.evaluate(sys).is_ok() {
                // the merit descends along the Newton step when K is positive
                // definite; else a smaller residual norm is progress too
                let e = problem.merit(sys)?;
                if e <= e0 + 1e-13 * e0.abs() || norm2(problem.residual(sys)) < r0 {
                    accepted = true;
                    accepted_merit = Some(e);
                    accepted_infeasibility = Some(trial);
                    step_taken = step;
                    break;
                }
            }
            step *= 0.5;
        }
        if !accepted {
            sys.state.x.copy_from_slice(&x0);
            sys.invalidate();
            return Ok(None);
        }
    }
    Ok(None)
}
