//! Case `cantilever`: a 40 × 4 × 2 beam clamped at x = 0 sagging under gravity,
//! against Euler–Bernoulli theory (DESIGN §4.5):
//! u(x) = q/(EI)·(x⁴/24 − L x³/6 + L² x²/4), q = ρ g A, tip deflection q L⁴/(8EI).
//!
//! Neo-Hookean with ν = 0 (no Poisson coupling, as the beam theory assumes) and E, ρ
//! chosen for a tip deflection of 0.1 % of L, well inside linear theory. The beam is
//! meshed with the symmetric 24-tet split of cube-like cells (the 6-tet split is
//! markedly stiffer in bending) at several resolutions; each mesh is solved
//! quasi-statically and the tip deflection (mean over the nodes of the end face)
//! compared with the theory. Linear tets are stiff in bending (shear locking), so
//! coarse meshes under-predict; the error falls as O(h²) = O(DOF^(−2/3)) once the
//! thickness is resolved, and the Richardson extrapolation of the two finest meshes
//! with the observed order estimates the converged deflection. Shear deformation,
//! which Euler–Bernoulli neglects, adds ≈ (2/3)(h/L)²/κ ≈ 0.2 % to the exact 3D
//! deflection (Timoshenko, κ = 5/6), which bounds the agreement reachable.

use super::plot::{draw, Chart, Mark, Series};
use super::{fmt_num, worst_criterion, CaseReport, Options, Row, Status};
use heml::mesh::generate::{beam, HexSplit};
use heml::system::StaticOptions;
use heml::{Params, Result, Vec3};

const L: f64 = 40.0;
const WIDTH: f64 = 4.0;
const HEIGHT: f64 = 2.0;
const E: f64 = 1.0e6;
const G: f64 = 9.81;

fn inertia() -> f64 {
    WIDTH * HEIGHT.powi(3) / 12.0
}

/// Density giving a tip deflection of `ratio`·L.
fn density(ratio: f64) -> f64 {
    ratio * L * 8.0 * E * inertia() / (G * WIDTH * HEIGHT * L.powi(4))
}

/// Euler–Bernoulli deflection magnitude at x.
fn euler_bernoulli(x: f64, rho: f64) -> f64 {
    let q = rho * G * WIDTH * HEIGHT;
    q / (E * inertia()) * (x.powi(4) / 24.0 - L * x.powi(3) / 6.0 + L * L * x * x / 4.0)
}

struct Solved {
    dofs: usize,
    tets: usize,
    tip: f64,
    /// Mean sideways (y) displacement of the end face: zero for a split with the
    /// beam's mirror symmetry y → W − y.
    lateral: f64,
    profile: Vec<(f64, f64)>,
}

/// The beam with `n` cells along L cut by `split`, solved quasi-statically under
/// gravity; the solver's convergence goes into `report`'s worst criterion.
fn solve(n: usize, split: HexSplit, rho: f64, report: &mut CaseReport, worst: &mut f64) -> Result<Solved> {
    let mesh = beam(L, WIDTH, HEIGHT, n, split)?;
    let tets = mesh.n_tets();
    let mut sys = heml::system(mesh)
        .material("neo_hookean", Params::from([("E", E), ("nu", 0.0)]))?
        .density(rho)
        .gravity(Vec3::new(0.0, 0.0, -G))
        .fix_where(|p| p.x < 1e-9)
        .build()?;
    let free = (0..sys.mesh().n_nodes()).filter(|&i| sys.is_free(i)).count();
    let r = sys.solve_static(&StaticOptions {
        tol: 1e-7,
        ..StaticOptions::default()
    })?;
    worst_criterion(report, &r, worst);
    let u = sys.displacements();
    let rest = sys.rest_positions();
    let end: Vec<usize> = (0..rest.len()).filter(|&i| (rest[i].x - L).abs() < 1e-9).collect();
    let tip = -end.iter().map(|&i| u[i].z).sum::<f64>() / end.len() as f64;
    let lateral = end.iter().map(|&i| u[i].y).sum::<f64>() / end.len() as f64;
    // centre-line profile: mean deflection of the nodes of each cross-section
    let mut sections: Vec<(f64, f64, usize)> = Vec::new();
    for (p, d) in rest.iter().zip(&u) {
        match sections.iter_mut().find(|s| (s.0 - p.x).abs() < 1e-9) {
            Some(s) => {
                s.1 -= d.z;
                s.2 += 1;
            }
            None => sections.push((p.x, -d.z, 1)),
        }
    }
    sections.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(Solved {
        dofs: 3 * free,
        tets,
        tip,
        lateral,
        profile: sections.iter().map(|s| (s.0, s.1 / s.2 as f64)).collect(),
    })
}

pub(crate) fn run(opts: &Options, report: &mut CaseReport) -> Result<()> {
    let series: &[usize] = if opts.quick {
        &[20, 40, 60]
    } else {
        &[10, 20, 40, 60, 80]
    };
    let rho = density(1e-3);
    let tip_ref = euler_bernoulli(L, rho);
    let mut worst = 0.0;
    let mut results = Vec::new();
    for &n in series {
        results.push(solve(n, HexSplit::TwentyFour, rho, report, &mut worst)?);
    }
    report.notes.push(format!(
        "beam {L} x {WIDTH} x {HEIGHT}, neo-Hookean E = {E:e} Pa, nu = 0, rho = {} (tip deflection {:.3} = 0.1 % of L), meshes {:?} cells along L (symmetric 24-tet split)",
        fmt_num(rho),
        tip_ref,
        series
    ));
    let errors: Vec<f64> = results.iter().map(|s| (s.tip - tip_ref).abs() / tip_ref).collect();
    for (s, e) in results.iter().zip(&errors) {
        report.rows.push(Row {
            status: Status::Info,
            tolerance: "-".into(),
            ..Row::check(
                format!("tip deflection, {} tets, {} DOF", s.tets, s.dofs),
                fmt_num(s.tip),
                fmt_num(tip_ref),
                *e,
                f64::INFINITY,
            )
        });
    }
    let last = errors.len() - 1;
    report.rows.push(Row::info(
        "tip deflection, finest mesh (relative error in error column)",
        fmt_num(results[last].tip),
        fmt_num(tip_ref),
    ));
    if let Some(r) = report.rows.last_mut() {
        r.error = Some(errors[last]);
    }
    // observed order in h from the two finest meshes: DOF ~ h^-3
    let (a, b) = (&results[last - 1], &results[last]);
    let order = -3.0 * (errors[last] / errors[last - 1]).ln() / ((b.dofs as f64) / (a.dofs as f64)).ln();
    // P1 displacements converge as h²; the coarse meshes of the quick series (one or
    // two cells through the thickness) are pre-asymptotic, hence the wider band.
    let band = if opts.quick { (1.2, 3.0) } else { (1.5, 3.0) };
    report.rows.push(Row {
        tolerance: format!("in [{}, {}]", band.0, band.1),
        status: if (band.0..=band.1).contains(&order) {
            Status::Pass
        } else {
            Status::Fail
        },
        ..Row::info(
            "observed convergence order in h (two finest)",
            format!("{order:.2}"),
            "2".into(),
        )
    });
    // Richardson extrapolation without the reference: the order p_s that fits the
    // three finest tip deflections δ_i = δ∞ − C h_i^p (bisection), then
    // δ∞ ≈ δ_3 + (δ_3 − δ_2)/((h_2/h_3)^p_s − 1).
    let h: Vec<f64> = results.iter().map(|s| (s.dofs as f64).powf(-1.0 / 3.0)).collect();
    let (d1, d2, d3) = (results[last - 2].tip, results[last - 1].tip, results[last].tip);
    let (h1, h2, h3) = (h[last - 2], h[last - 1], h[last]);
    let target = (d3 - d2) / (d2 - d1);
    let fit = |p: f64| (h2.powf(p) - h3.powf(p)) / (h1.powf(p) - h2.powf(p)) - target;
    let (mut lo, mut hi) = (0.1, 6.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if fit(lo) * fit(mid) <= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let p_self = 0.5 * (lo + hi);
    let extrapolated = d3 + (d3 - d2) / ((h2 / h3).powf(p_self) - 1.0);
    // Full series: within 1 % (0.2 % shear effect + extrapolation error of a
    // near-asymptotic triple). Quick series (20/40/60 cells, 1–3 cells through the
    // thickness): the triple is pre-asymptotic, its fitted order (~1.4) is below 2
    // and the extrapolation overshoots by ~5 %, hence 8 %.
    let tol = if opts.quick { 0.08 } else { 0.01 };
    report.rows.push(Row::check(
        format!("tip deflection, Richardson-extrapolated (self-fitted order {p_self:.2})"),
        fmt_num(extrapolated),
        fmt_num(tip_ref),
        (extrapolated - tip_ref).abs() / tip_ref,
        tol,
    ));

    // The splits side by side at the same cells: tip deflection relative to theory,
    // and the sideways drift of the tip (the problem is symmetric under y → W − y;
    // a split without that mirror symmetry bends the beam sideways a little).
    let compare: &[usize] = if opts.quick { &[20] } else { &[20, 40] };
    for &n in compare {
        for split in [HexSplit::Five, HexSplit::Six, HexSplit::Ten, HexSplit::TwentyFour] {
            let fresh;
            let s = match series.iter().position(|&m| m == n) {
                Some(k) if split == HexSplit::TwentyFour => &results[k],
                _ => {
                    fresh = solve(n, split, rho, report, &mut worst)?;
                    &fresh
                }
            };
            let name = format!("{split:?}").to_lowercase();
            report.rows.push(Row::info(
                format!("tip / theory, {name} split, {n} cells along L ({} tets)", s.tets),
                format!("{:.4}", s.tip / tip_ref),
                "-".into(),
            ));
            let drift = s.lateral.abs() / s.tip;
            if split == HexSplit::Ten {
                // mirror-symmetric mesh and problem: the solution is symmetric up to
                // the static solve's tolerance (1e-7 of the load; measured 2e-11)
                report.rows.push(Row::check(
                    format!("sideways tip drift / tip, ten split, {n} cells"),
                    format!("{drift:.1e}"),
                    "0".into(),
                    drift,
                    1e-9,
                ));
            } else {
                report.rows.push(Row::info(
                    format!("sideways tip drift / tip, {name} split, {n} cells"),
                    format!("{drift:.1e}"),
                    "0".into(),
                ));
            }
        }
    }

    if let Some(path) = opts.plot_path("cantilever")? {
        let finest = &results[last];
        let fine: Vec<(f64, f64)> = (0..=200)
            .map(|k| {
                let x = L * k as f64 / 200.0;
                (x, euler_bernoulli(x, rho))
            })
            .collect();
        let profile = Chart::xy(
            "deflection along the beam",
            "x",
            "downward deflection",
            vec![
                Series::new("Euler-Bernoulli", fine, Mark::Line),
                Series::new(
                    format!("HEML, {} tets", finest.tets),
                    finest.profile.clone(),
                    Mark::Points,
                ),
            ],
        );
        let pts: Vec<(f64, f64)> = results.iter().zip(&errors).map(|(s, e)| (s.dofs as f64, *e)).collect();
        let (d0, e0) = pts[last];
        let slope: Vec<(f64, f64)> = [pts[0].0, d0]
            .iter()
            .map(|&d| (d, e0 * (d / d0).powf(-2.0 / 3.0)))
            .collect();
        let conv = Chart::xy(
            "tip error vs degrees of freedom",
            "degrees of freedom",
            "relative tip error",
            vec![
                Series::new("HEML vs Euler-Bernoulli", pts, Mark::LinePoints),
                Series::new("slope h^2 (DOF^-2/3)", slope, Mark::Line),
            ],
        )
        .log_log();
        draw(&path, "cantilever under gravity", &[profile, conv])?;
        report.plot = Some(path);
    }
    Ok(())
}
