//! The public settings and outcome of a quasi-static solve, and the single-coordinate
//! supports it accepts.

use crate::system::LinearSolver;
#[cfg(doc)]
use crate::system::System;

/// One coordinate of a node held at a given value while the other two move freely:
/// a frictionless roller or symmetry-plane support, used by
/// [`System::solve_static_with`] (e.g. the unconstrained uniaxial test, whose
/// loaded faces must slide laterally).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slider {
    /// Node id.
    pub node: usize,
    /// Axis (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// The value the coordinate is held at.
    pub value: f64,
}

/// Settings of [`System::solve_static`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticOptions {
    /// Relative residual tolerance: converged when max |f_i| over the free nodes is
    /// at most `tol` × the load scale (default 1e-6).
    pub tol: f64,
    /// Absolute residual (N) below which the solve counts as converged whatever the
    /// load scale (default 0: off; useful for unloaded systems).
    pub abs_tol: f64,
    /// Iteration (force evaluation) cap (default 500 000).
    pub max_iterations: usize,
    /// Log the residual (`log::info!`, target `heml_core::system::statics`) every
    /// this many iterations (0: silent, default). Every Newton iteration is logged
    /// when this is non-zero, since there are few of them.
    pub progress_every: usize,
    /// The linear solver of the Newton iterations: `None` (default) the banded LDLᵀ
    /// when its band fits in memory and every law's volume term is per element, else
    /// conjugate gradients on the generated (projected) tangent; `Some` forces
    /// conjugate gradients or a sparse Cholesky factorisation (refactored at every
    /// Newton iteration; its fill is capped at the implicit integrators' default
    /// [`crate::system::ImplicitSettings::max_factor_nonzeros`]) on that tangent.
    pub linear_solver: Option<LinearSolver>,
}

impl Default for StaticOptions {
    fn default() -> Self {
        StaticOptions {
            tol: 1e-6,
            abs_tol: 0.0,
            max_iterations: 500_000,
            progress_every: 0,
            linear_solver: None,
        }
    }
}

/// What a quasi-static solve reached.
#[derive(Debug, Clone, PartialEq)]
pub struct StaticReport {
    /// Whether the criterion was met (always true in an `Ok` result).
    pub converged: bool,
    /// Iterations (force evaluations) used.
    pub iterations: usize,
    /// Final max |f_i| over the free nodes.
    pub residual: f64,
    /// Final load scale: max over nodes of |external load| and |reaction|.
    pub load_scale: f64,
    /// The relative tolerance asked for.
    pub tol: f64,
    /// The round-off level of the residual (N; see the [module docs](super)): a
    /// residual at or below it counts as converged whatever the load scale.
    pub roundoff: f64,
    /// Reaction force component on each slider of [`System::solve_static_with`], in
    /// the order given (empty for [`System::solve_static`]).
    pub slider_reactions: Vec<f64>,
}

impl StaticReport {
    /// residual / load scale (0 when both vanish).
    pub fn relative_residual(&self) -> f64 {
        if self.load_scale > 0.0 {
            self.residual / self.load_scale
        } else if self.residual == 0.0 {
            0.0
        } else {
            f64::INFINITY
        }
    }

    /// The criterion in words, with the values reached, e.g.
    /// `max|f_free| / max|load| = 3.1e-7 (tolerance 1e-6: met; 1234 it.)`. The
    /// outcome is said in words, so that a line never reads as a false inequality.
    /// A solve that converged by the round-off level or [`StaticOptions::abs_tol`] (an
    /// unloaded body, whose load scale is only the round-off of its reactions) says
    /// so rather than "not met".
    pub fn criterion(&self) -> String {
        let ratio = self.relative_residual();
        let outcome = if ratio <= self.tol {
            "met".to_string()
        } else if self.converged && self.residual <= self.roundoff {
            format!(
                "not met, but max|f_free| = {:.1e} N is at the round-off level ({:.1e} N)",
                self.residual, self.roundoff
            )
        } else if self.converged {
            format!(
                "not met, but max|f_free| = {:.1e} N is within the absolute tolerance",
                self.residual
            )
        } else {
            "not met".to_string()
        };
        format!(
            "max|f_free| / max|load| = {ratio:.1e} (tolerance {:.0e}: {outcome}; {} it.)",
            self.tol, self.iterations
        )
    }
}

#[cfg(test)]
mod tests {
    use super::StaticReport;

    fn report(residual: f64, converged: bool) -> StaticReport {
        StaticReport {
            converged,
            iterations: 7,
            residual,
            load_scale: 1.0,
            tol: 1e-6,
            roundoff: 1e-3,
            slider_reactions: Vec::new(),
        }
    }

    /// The criterion line says the outcome in words from the numbers it prints (it
    /// once read "1.7e-1 <= 1e-6", a false inequality).
    #[test]
    fn the_criterion_line_never_reads_as_a_false_inequality() {
        assert_eq!(
            report(3.1e-7, true).criterion(),
            "max|f_free| / max|load| = 3.1e-7 (tolerance 1e-6: met; 7 it.)"
        );
        let failed = report(0.17, false).criterion();
        assert!(failed.contains("= 1.7e-1 (tolerance 1e-6: not met;"), "{failed}");
        assert!(!failed.contains("<="), "{failed}");
        // converged by the absolute tolerance: the line says which criterion held
        let absolute = report(0.17, true).criterion();
        assert!(
            absolute.contains("not met, but max|f_free| = 1.7e-1 N is within the absolute tolerance"),
            "{absolute}"
        );
        // converged at rest with no load: the round-off level is named
        let rest = report(2e-4, true).criterion();
        assert!(
            rest.contains("not met, but max|f_free| = 2.0e-4 N is at the round-off level (1.0e-3 N)"),
            "{rest}"
        );
    }
}
