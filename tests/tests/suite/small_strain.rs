//! Every constructor from Lamé constants linearises to linear elasticity:
//! dP/dε at F = I + εH equals λ·tr(H)·I + μ·(H + Hᵀ). This pins down the
//! parameter mappings (bulk modulus, stable neo-Hookean's reparametrisation, …).

use heml::law::Invariant;
use heml::law::*;
use heml::nalgebra::Matrix3;
use heml::prelude::*;

/// Central difference of P with ε = 1e-6: truncation ε²·|P'''| ~ 1e-12·(μ+λ) and
/// round-off ~1e-16·|P|/ε ~ 1e-10·(μ+λ); 1e-7 relative to μ + λ leaves margin and
/// still catches any wrong coefficient (which would be off by O(1)).
///
/// Generic rather than `&dyn Material`: a law coerced to a trait object needs its
/// whole vtable, every force field's kernels for that law, compiled into this test
/// crate (two minutes of the release build for these ten laws); called statically,
/// only `stress` is.
fn check<L: Material + ?Sized>(name: &str, law: &L, mu: f64, lambda: f64) {
    let opts = ForceOptions::default();
    let h = Matrix3::new(0.3, -0.2, 0.5, 0.1, -0.4, 0.2, -0.3, 0.6, 0.25);
    let eps = 1e-6;
    let p = |s: f64| law.stress(&(Matrix3::identity() + h * s), &opts).unwrap().1;
    let dp = (p(eps) - p(-eps)) / (2.0 * eps);
    let expected = Matrix3::identity() * (lambda * h.trace()) + (h + h.transpose()) * mu;
    let err = (dp - expected).norm();
    assert!(
        err <= 1e-7 * (mu + lambda),
        "{name}: dP = {dp}, expected {expected}, error {err:e}"
    );
}

#[test]
fn lame_constructors_match_linear_elasticity() {
    let (mu, lambda) = (1.7e3, 6.2e3);
    check("neo_hookean", &Invariant(NeoHookean::from_lame(mu, lambda)), mu, lambda);
    check(
        "svk",
        &Invariant(SaintVenantKirchhoff::from_lame(mu, lambda)),
        mu,
        lambda,
    );
    check(
        "stable_nh",
        &Invariant(StableNeoHookean::from_lame(mu, lambda)),
        mu,
        lambda,
    );
    check(
        "mooney_rivlin",
        &Invariant(MooneyRivlin::from_lame(mu, lambda, 0.3)),
        mu,
        lambda,
    );
    check(
        "fung_demiray",
        &Invariant(FungDemiray::from_lame(mu, lambda, 2.0)),
        mu,
        lambda,
    );
    check("gent", &Invariant(Gent::from_lame(mu, lambda, 30.0)), mu, lambda);
    let (mu_e, lambda_e) = heml::params::lame(5e3, 0.3);
    check(
        "neo_hookean (E, nu)",
        &Invariant(NeoHookean::from_young(5e3, 0.3)),
        mu_e,
        lambda_e,
    );
    check(
        "stable_nh (E, nu)",
        &Invariant(StableNeoHookean::from_young(5e3, 0.3)),
        mu_e,
        lambda_e,
    );
}

/// The documented small-strain shear moduli of the laws without a Lamé constructor.
#[test]
fn documented_small_strain_moduli_hold() {
    let kappa = 9.0e3;
    let bulk = |mu: f64| kappa - 2.0 * mu / 3.0;
    let (c1, c2) = (800.0, 1.5);
    check(
        "veronda_westmann",
        &Invariant(VerondaWestmann { c1, c2, kappa }),
        c1 * c2,
        bulk(c1 * c2),
    );
    check(
        "yeoh",
        &Invariant(Yeoh {
            c1: 600.0,
            c2: -50.0,
            c3: 10.0,
            kappa,
        }),
        1200.0,
        bulk(1200.0),
    );
    let (m, lm): (f64, f64) = (1000.0, 2.5);
    let mu0 = m
        * (1.0
            + 3.0 / (5.0 * lm.powi(2))
            + 99.0 / (175.0 * lm.powi(4))
            + 513.0 / (875.0 * lm.powi(6))
            + 42039.0 / (67375.0 * lm.powi(8)));
    check(
        "arruda_boyce",
        &Invariant(ArrudaBoyce { mu: m, lm, kappa }),
        mu0,
        bulk(mu0),
    );
}

/// `soft_tissue_params` gives every built-in invariant or stretch law the requested small-strain
/// moduli, so laws compared in benchmarks and validation are the same tissue.
#[test]
fn soft_tissue_params_match_the_requested_moduli() {
    let (e, nu) = (4.5e3, 0.42);
    let (mu, lambda) = heml::params::lame(e, nu);
    let mut checked = 0;
    for entry in heml::materials_list() {
        match heml_validation::fixtures::soft_tissue_params(entry.name, e, nu) {
            Some(p) => {
                check(entry.name, entry.instantiate(&p).unwrap().as_ref(), mu, lambda);
                checked += 1;
            }
            None => assert!(
                // fibre laws are anisotropic: no isotropic E/ν mapping
                entry.kind != LawKind::Invariant || entry.name.starts_with("test_"),
                "{} has no parameters",
                entry.name
            ),
        }
    }
    assert_eq!(checked, 10); // nine invariant laws and Ogden
}
