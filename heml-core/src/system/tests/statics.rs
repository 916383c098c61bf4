//! The quasi-static solver at its edges: nothing loaded, nothing free, stopped by
//! its caller.

use super::*;
use crate::system::StaticOptions;

/// An unloaded body at rest is at equilibrium: its residual is the round-off of
/// the rest forces, and its load scale the round-off of its reactions, so the
/// relative criterion alone cannot be met (it relaxed 500 000 iterations, ~30 s,
/// before failing); the round-off level ends it at once.
#[test]
fn an_unloaded_body_is_at_equilibrium_at_rest() {
    let mut sys = System::builder(box_mesh([0.1, 0.02, 0.02], [10, 2, 2], HexSplit::Six).unwrap())
        .material_law(neo(1e3, 1e4))
        .fix_where(|p| p.x < 1e-9)
        .build()
        .unwrap();
    let report = sys.solve_static(&StaticOptions::default()).unwrap();
    assert!(report.converged && report.iterations == 0, "{report:?}");
    assert!(
        report.residual <= report.roundoff && report.roundoff > 0.0,
        "{report:?}"
    );
    assert!(
        report.criterion().contains("at the round-off level"),
        "{}",
        report.criterion()
    );
    // the level is far below what a loaded solve must reach (1e-6 of the largest
    // nodal weight), so it does not end real solves early
    let weight = sys.model.mass.iter().fold(0.0, |m: f64, w| m.max(*w)) * 9.81;
    assert!(
        report.roundoff < 1e-3 * 1e-6 * weight,
        "{} vs {weight}",
        report.roundoff
    );
}

/// Nothing free: nothing to solve (dynamic relaxation used to refuse it for want of a
/// finite stable step).
#[test]
fn a_body_with_every_node_fixed_is_at_equilibrium() {
    let mut sys = System::builder(cube())
        .material_law(spring(1e3))
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .fix_where(|_| true)
        .build()
        .unwrap();
    let report = sys.solve_static(&StaticOptions::default()).unwrap();
    assert!(
        report.converged && report.iterations == 0 && report.residual == 0.0,
        "{report:?}"
    );
}

/// `solve_static_until` ends when asked, with the iterations done and the residual
/// reached, and the system at its last iterate (a spring network: no stress, so
/// dynamic relaxation does the work from the first iteration).
#[test]
fn a_static_solve_stops_when_its_caller_says_so() {
    let build = || {
        System::builder(cube())
            .material_law(spring(1e3))
            .gravity(Vec3::new(0.0, 0.0, -9.81))
            .fix_where(|p| p.z > 1.0 - 1e-9)
            .build()
            .unwrap()
    };
    let mut sys = build();
    let mut asked = 0;
    let e = sys
        .solve_static_until(&[], &StaticOptions::default(), &mut || {
            asked += 1;
            asked > 5
        })
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("was stopped after 5 iterations") && e.contains("residual"),
        "{e}"
    );
    assert!(sys.displacements().iter().any(|d| d.z < 0.0), "the iterate is kept");
    // never stopped, it converges as `solve_static` does
    let mut sys = build();
    let report = sys
        .solve_static_until(&[], &StaticOptions::default(), &mut || false)
        .unwrap();
    assert!(report.converged && report.relative_residual() <= 1e-6, "{report:?}");
}
