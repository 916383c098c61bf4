//! Case `ogden`: unconstrained uniaxial tension and compression of a cube made of
//! Treloar's rubber, the Ogden law with Ogden's (1972) three-term fit — μ1 = 0.63 MPa,
//! α1 = 1.3, μ2 = 0.0012 MPa, α2 = 5.0, μ3 = −0.01 MPa, α3 = −2.0 — and a bulk modulus
//! κ = 100 μ0 (μ0 = ½ Σ μ_p α_p = 0.4225 MPa).
//!
//! The set-up is the `uniaxial` case's (rollers, top face held at stretch λ, lateral
//! faces free): the equilibrium is homogeneous, F = diag(t, t, λ), so the top reaction
//! per rest area must equal the closed form written directly in the principal
//! stretches ([`uniaxial`]), with the lateral stretch t from the lateral stress-free
//! condition. The kernel's route — C from the edge lengths, its eigenvalues in closed
//! form, the spectral gradient — shares nothing with it.

use super::plot::{draw, linspace, Chart, Mark, Series};
use super::uniaxial::{bisect, closed_form_rows, sweep};
use super::{fmt_num, CaseReport, Options};
use heml::{Params, Result};

/// Treloar's rubber (Ogden 1972): (μ_p in Pa, α_p).
pub const TRELOAR: [(f64, f64); 3] = [(0.63e6, 1.3), (0.0012e6, 5.0), (-0.01e6, -2.0)];

/// Small-strain shear modulus ½ Σ μ_p α_p of `terms`.
pub fn shear_modulus(terms: &[(f64, f64)]) -> f64 {
    0.5 * terms.iter().map(|(mu, a)| mu * a).sum::<f64>()
}

/// The `ogden` registry parameters of three `terms` and bulk modulus `kappa`.
pub fn params(terms: &[(f64, f64); 3], kappa: f64) -> Params {
    let mut p = Params::new().with("kappa", kappa);
    for (k, (mu, alpha)) in terms.iter().enumerate() {
        p.set(&format!("mu{}", k + 1), *mu);
        p.set(&format!("alpha{}", k + 1), *alpha);
    }
    p
}

/// ∂w/∂λ_k of the compressible Ogden law w = Σ_p μ_p/α_p (J^(−α_p/3) Σ_i λ_i^α_p − 3)
/// plus κ/2 (ln J)², at principal stretches `l` (J = λ₁λ₂λ₃):
/// Σ_p μ_p J^(−α_p/3)(λ_k^(α_p−1) − Σ_i λ_i^α_p/(3λ_k)) + κ ln J/λ_k.
pub fn principal_stress(terms: &[(f64, f64)], kappa: f64, l: [f64; 3], k: usize) -> f64 {
    let j = l[0] * l[1] * l[2];
    let mut s = kappa * j.ln() / l[k];
    for &(mu, alpha) in terms {
        let sum: f64 = l.iter().map(|x| x.powf(alpha)).sum();
        s += mu * j.powf(-alpha / 3.0) * (l[k].powf(alpha - 1.0) - sum / (3.0 * l[k]));
    }
    s
}

/// Unconstrained uniaxial loading at stretch `lambda` along the first axis: the lateral
/// stretch t solving ∂w/∂λ₂(λ, t, t) = 0 (bisection on [0.05, 20], where it changes
/// sign for any stable parameters and λ in [0.1, 10]), and P₁₁ = ∂w/∂λ₁(λ, t, t).
pub fn uniaxial(terms: &[(f64, f64)], kappa: f64, lambda: f64) -> (f64, f64) {
    let t = bisect(|t: f64| principal_stress(terms, kappa, [lambda, t, t], 1), 0.05, 20.0);
    (t, principal_stress(terms, kappa, [lambda, t, t], 0))
}

pub(crate) fn run(opts: &Options, report: &mut CaseReport) -> Result<()> {
    let (cells, stretches): (usize, Vec<f64>) = if opts.quick {
        (2, vec![0.5, 0.7, 0.9, 1.2, 1.6, 2.0])
    } else {
        (
            3,
            (1..=26)
                .map(|k| 0.4 + 0.1 * k as f64)
                .filter(|e| (e - 1.0).abs() > 1e-9)
                .collect(),
        )
    };
    let mu0 = shear_modulus(&TRELOAR);
    let kappa = 100.0 * mu0;
    let mut worst_res = 0.0;
    let s = sweep(
        "ogden",
        &params(&TRELOAR, kappa),
        mu0,
        &stretches,
        cells,
        report,
        &mut worst_res,
    )?;
    report.notes.push(format!(
        "unit cube, {cells}^3 cells x 6 tets, Treloar's rubber (Ogden 1972), kappa = 100 mu0 = {} Pa, {} stretches {}..{}",
        fmt_num(kappa),
        s.eps.len(),
        s.eps[0],
        s.eps[s.eps.len() - 1]
    ));
    let reference: Vec<(f64, f64)> = s.eps.iter().map(|&e| uniaxial(&TRELOAR, kappa, e)).collect();
    closed_form_rows(report, "Ogden", &s, &reference);
    if let Some(path) = opts.plot_path("ogden")? {
        let fine = linspace(s.eps[0], s.eps[s.eps.len() - 1], 200);
        let mpa = |v: f64| v / 1e6;
        let chart = Chart::xy(
            "Treloar's rubber, unconstrained uniaxial loading",
            "stretch (current / rest height)",
            "nominal stress P_zz (MPa)",
            vec![
                Series::new(
                    "Ogden (1972), closed form",
                    fine.iter().map(|&e| (e, mpa(uniaxial(&TRELOAR, kappa, e).1))).collect(),
                    Mark::Line,
                ),
                s.series("HEML", 1e6),
            ],
        );
        draw(&path, "ogden: HEML vs the closed form in principal stretches", &[chart])?;
        report.plot = Some(path);
    }
    Ok(())
}
