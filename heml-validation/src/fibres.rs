//! Case `fibres`: unconstrained uniaxial loading of a cube of fibre-reinforced
//! material, along and across the fibres, against closed forms.
//!
//! As in case `uniaxial`, a unit cube on rollers is stretched along z to ε with the
//! lateral faces free; with both fibre families along z ("along") or along x
//! ("across") and no dispersion, the equilibrium is homogeneous, F = diag(a, a, ε),
//! represented exactly by P1 elements. With J = a²ε, Ī1 = J^(−2/3)(2a² + ε²),
//! Ī2 = J^(−4/3)(a⁴ + 2a²ε²) and, along, Ī4 = J^(−2/3)ε², the energy's chain rule
//! gives P_zz = ∂W/∂ε and the lateral condition ∂W/∂a = 0 (solved for a by
//! bisection). Across, the fibres (along x) are shortened in tension (a < 1 gives
//! Ī4 = J^(−2/3)a² < 1), so the tension-only switch leaves the matrix alone — the
//! closed form checks that they indeed carry nothing; along, compression switches
//! them off the same way. Laws: Holzapfel–Gasser–Ogden (two families) and the
//! transversely isotropic Mooney–Rivlin (one family).

use super::plot::{draw, linspace, Chart, Mark, Series};
use super::{fmt_num, worst_criterion, CaseReport, Options, Row};
use heml::heml_core::fibres::Fibres;
use heml::mesh::generate::{box_mesh, HexSplit};
use heml::system::{Slider, StaticOptions};
use heml::{Params, Result, Vec3};
use std::sync::Arc;

/// HGO parameters (Pa; k2 dimensionless): arterial-media–like, scaled to 10 kPa.
const HGO: [(&str, f64); 5] = [
    ("c", 3.0e3),
    ("k1", 2.0e3),
    ("k2", 0.8),
    ("dispersion", 0.0),
    ("kappa", 5.0e4),
];
/// TI Mooney–Rivlin parameters (Pa; c4 dimensionless), ligament-like, scaled.
const TIMR: [(&str, f64); 5] = [
    ("c1", 1.0e3),
    ("c2", 0.2e3),
    ("c3", 0.5e3),
    ("c4", 8.0),
    ("kappa", 5.0e4),
];

/// The strain-energy derivatives a closed form needs: ∂W/∂Ī1, ∂W/∂Ī2, ∂W/∂Ī4
/// (summed over the families along the fibres' axis) and ∂W/∂J.
struct Partials {
    w1: f64,
    w2: f64,
    w4: f64,
    wj: f64,
}

fn partials(law: &str, i4: f64, j: f64) -> Partials {
    let p = |name: &str, set: &[(&str, f64)]| set.iter().find(|(n, _)| *n == name).map(|(_, v)| *v).unwrap_or(0.0);
    match law {
        "holzapfel_gasser_ogden" => {
            let (c, k1, k2, kappa) = (p("c", &HGO), p("k1", &HGO), p("k2", &HGO), p("kappa", &HGO));
            let e = (i4 - 1.0).max(0.0);
            Partials {
                w1: c / 2.0,
                w2: 0.0,
                // two families, each k1·E·exp(k2·E²)
                w4: 2.0 * k1 * e * (k2 * e * e).exp(),
                wj: kappa / 2.0 * (j - 1.0 / j),
            }
        }
        _ => {
            let (c1, c2, c3, c4, kappa) = (
                p("c1", &TIMR),
                p("c2", &TIMR),
                p("c3", &TIMR),
                p("c4", &TIMR),
                p("kappa", &TIMR),
            );
            let s = i4.sqrt();
            let df = if s > 1.0 {
                c3 * ((c4 * (s - 1.0)).exp() - 1.0)
            } else {
                0.0
            };
            Partials {
                w1: c1,
                w2: c2,
                w4: df / (2.0 * s),
                wj: kappa * j.ln() / j,
            }
        }
    }
}

/// (∂W/∂ε, ∂W/∂a) at F = diag(a, a, ε); `along`: fibres along z, else along x (a
/// shortened fibre, checked by the caller to carry nothing).
fn derivatives(law: &str, along: bool, a: f64, eps: f64) -> (f64, f64) {
    let j = a * a * eps;
    let j23 = j.powf(-2.0 / 3.0);
    let j43 = j23 * j23;
    let i1 = j23 * (2.0 * a * a + eps * eps);
    let i2 = j43 * (a.powi(4) + 2.0 * a * a * eps * eps);
    let i4 = if along { j23 * eps * eps } else { j23 * a * a };
    let w = partials(law, i4, j);
    let (di1_de, di1_da) = (
        2.0 * eps * j23 - 2.0 / 3.0 * i1 / eps,
        4.0 * a * j23 - 4.0 / 3.0 * i1 / a,
    );
    let (di2_de, di2_da) = (
        4.0 * a * a * eps * j43 - 4.0 / 3.0 * i2 / eps,
        j43 * (4.0 * a.powi(3) + 4.0 * a * eps * eps) - 8.0 / 3.0 * i2 / a,
    );
    // Ī4 = J^(−2/3)ε² (along) or J^(−2/3)a² (across, one lateral direction only:
    // then ∂W/∂a of a = a_x = a_y is not the lateral stress, hence the caller's check)
    let (di4_de, di4_da) = if along {
        (4.0 / 3.0 * i4 / eps, -4.0 / 3.0 * i4 / a)
    } else {
        (-2.0 / 3.0 * i4 / eps, 2.0 / 3.0 * i4 / a)
    };
    (
        w.w1 * di1_de + w.w2 * di2_de + w.w4 * di4_de + w.wj * a * a,
        w.w1 * di1_da + w.w2 * di2_da + w.w4 * di4_da + w.wj * 2.0 * a * eps,
    )
}

/// The closed form: lateral stretch a (∂W/∂a = 0 by bisection; ∂W/∂a increases
/// with a) and P_zz. `None` across when the fibres would be stretched (then the
/// equilibrium is not transversely isotropic and this closed form does not apply).
pub(crate) fn closed_form(law: &str, along: bool, eps: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (1e-3, 1e3);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if derivatives(law, along, mid, eps).1 > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let a = 0.5 * (lo + hi);
    let i4_across = (a * a * eps).powf(-2.0 / 3.0) * a * a;
    if !along && i4_across > 1.0 {
        return None;
    }
    Some((a, derivatives(law, along, a, eps).0))
}

fn law_params(law: &str) -> Params {
    let set: &[(&str, f64)] = if law == "holzapfel_gasser_ogden" { &HGO } else { &TIMR };
    set.iter().fold(Params::new(), |p, (k, v)| p.with(k, *v))
}

/// P_zz of the cube at each stretch (static solves, continuation from rest).
fn sweep(
    law: &str,
    along: bool,
    stretches: &[f64],
    cells: usize,
    report: &mut CaseReport,
    worst: &mut f64,
) -> Result<Vec<f64>> {
    let mesh = box_mesh([1.0; 3], [cells; 3], HexSplit::Six)?;
    let nodes = mesh.nodes().to_vec();
    let dir = if along { Vec3::z() } else { Vec3::x() };
    let fibres = Arc::new(Fibres::uniform(mesh.n_tets(), &[dir, dir])?);
    let material = heml::material(law, &law_params(law))?.with_fibres(fibres)?;
    let mut sys = heml::system(mesh).material_law(material).build()?;
    let h = 1.0 / cells as f64;
    let opts = StaticOptions {
        tol: 1e-9,
        abs_tol: 1e-12 * 1e4 * h * h,
        ..StaticOptions::default()
    };
    let mut out = vec![0.0; stretches.len()];
    let mut order: Vec<usize> = (0..stretches.len()).collect();
    order.sort_by(|&a, &b| (stretches[a] - 1.0).abs().total_cmp(&(stretches[b] - 1.0).abs()));
    for branch in [false, true] {
        sys.positions_mut().copy_from_slice(&nodes);
        let mut prev = 1.0;
        for &k in order.iter().filter(|&&k| (stretches[k] > 1.0) == branch) {
            let eps = stretches[k];
            for p in sys.positions_mut() {
                p.z *= eps / prev;
            }
            prev = eps;
            let mut sliders = Vec::new();
            for (i, p) in nodes.iter().enumerate() {
                for axis in 0..3 {
                    if p[axis].abs() < 1e-9 {
                        sliders.push(Slider {
                            node: i,
                            axis,
                            value: 0.0,
                        });
                    }
                }
                if (p.z - 1.0).abs() < 1e-9 {
                    sliders.push(Slider {
                        node: i,
                        axis: 2,
                        value: eps,
                    });
                }
            }
            let r = sys.solve_static_with(&sliders, &opts)?;
            worst_criterion(report, &r, worst);
            out[k] = sliders
                .iter()
                .zip(&r.slider_reactions)
                .filter(|(s, _)| s.axis == 2 && s.value != 0.0)
                .map(|(_, f)| f)
                .sum();
        }
    }
    Ok(out)
}

/// The closed form (a line over the stretches' range, where it applies) and HEML's
/// P_zz `p` at `stretches` (points), in kPa, for a chart.
fn plot_series(law: &str, along: bool, stretches: &[f64], p: &[f64]) -> [Series; 2] {
    let (lo, hi) = stretches
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &e| (a.min(e), b.max(e)));
    let which = if along { "along" } else { "across" };
    let kpa = |v: f64| v / 1e3;
    let line = linspace(lo, hi, 120)
        .into_iter()
        .filter_map(|e| closed_form(law, along, e).map(|(_, pzz)| (e, kpa(pzz))))
        .collect();
    [
        Series::new(format!("{which}, closed form"), line, Mark::Line),
        Series::new(
            format!("{which}, HEML"),
            stretches.iter().zip(p).map(|(&e, &v)| (e, kpa(v))).collect(),
            Mark::Points,
        ),
    ]
}

pub(crate) fn run(opts: &Options, report: &mut CaseReport) -> Result<()> {
    let cells = if opts.quick { 2 } else { 3 };
    let along: Vec<f64> = [0.85, 0.9, 0.95, 1.05, 1.1, 1.15, 1.2].to_vec();
    let across: Vec<f64> = [1.05, 1.1, 1.15, 1.2, 1.3].to_vec();
    let mut worst_res = 0.0;
    let mut charts = Vec::new();
    for law in ["holzapfel_gasser_ogden", "ti_mooney_rivlin"] {
        let mut series = Vec::new();
        for (is_along, stretches) in [(true, &along), (false, &across)] {
            let p = sweep(law, is_along, stretches, cells, report, &mut worst_res)?;
            series.extend(plot_series(law, is_along, stretches, &p));
            let mut worst = (0, 0.0, 0.0);
            let scale = stretches
                .iter()
                .filter_map(|&e| closed_form(law, is_along, e))
                .fold(0.0_f64, |m, (_, pz)| m.max(pz.abs()));
            for (k, &eps) in stretches.iter().enumerate() {
                let Some((_, pzz)) = closed_form(law, is_along, eps) else {
                    continue;
                };
                let err = (p[k] - pzz).abs() / scale;
                if err >= worst.1 {
                    worst = (k, err, pzz);
                }
            }
            // Tolerance as in `uniaxial`: the solves stop at 1e-9 of the largest
            // reaction, far below 1e-6; a wrong fibre term or switch is off by O(1)
            // (along, the fibres roughly double the stiffness; across, any fibre
            // force in compression would show at the percent level).
            report.rows.push(Row::check(
                format!(
                    "{law} {} fibres P_zz (Pa), worst of {} stretches: at {:.2}",
                    if is_along { "along" } else { "across" },
                    stretches.len(),
                    stretches[worst.0]
                ),
                fmt_num(p[worst.0]),
                fmt_num(worst.2),
                worst.1,
                1e-6,
            ));
        }
        let title = if law == "holzapfel_gasser_ogden" {
            "Holzapfel-Gasser-Ogden (two families)"
        } else {
            "transversely isotropic Mooney-Rivlin"
        };
        charts.push(Chart::xy(title, "stretch along z", "nominal stress P_zz (kPa)", series));
    }
    if let Some(path) = opts.plot_path("fibres")? {
        draw(
            &path,
            "fibres: uniaxial along and across the fibres, HEML vs closed forms",
            &charts,
        )?;
        report.plot = Some(path);
    }
    super::fibre_tube::run(opts.quick, report)?;
    report.notes.push(format!(
        "unit cube, {cells}^3 cells x 6 tets; along: stretches {along:?} (compression switches the fibres off); \
         across: {across:?}; HGO {HGO:?}; TI-MR {TIMR:?}"
    ));
    Ok(())
}
