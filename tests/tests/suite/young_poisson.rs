//! Every registered law that accepts Young's modulus and Poisson's ratio, built from
//! E = 60 kPa, ν = 0.45 (plus its own shape parameters), has the small-strain shear
//! modulus μ = E/(2(1+ν)) and bulk modulus K = E/(3(1−2ν)) — whatever its parameters
//! mean. The registry is iterated, so a newly declared law is covered automatically
//! (a law with shape parameters needs an entry in `SHAPE`, or the test says so).

use heml::law::*;
use heml::nalgebra::Matrix3;
use heml::prelude::*;

const E: f64 = 60e3;
const NU: f64 = 0.45;

/// The parameters a law's small-strain mapping does not set, given alongside E/ν:
/// (law, parameter, value), moderate soft-tissue values.
const SHAPE: &[(&str, &str, f64)] = &[
    ("mooney_rivlin", "c01", 3e3),
    ("yeoh", "c2", -1e3),
    ("yeoh", "c3", 500.0),
    ("gent", "jm", 50.0),
    ("arruda_boyce", "lm", 3.0),
    ("fung_demiray", "b", 1.0),
    ("veronda_westmann", "c2", 1.0),
    ("ogden", "alpha1", 1.3),
    ("ogden", "mu2", 100.0),
    ("ogden", "alpha2", 5.0),
    ("ogden", "mu3", -800.0),
    ("ogden", "alpha3", -2.0),
];

/// (μ, K) of `law`, measured on its first Piola–Kirchhoff stress (from its generated
/// derivatives) under a tiny simple shear and a tiny dilation, by central differences
/// with step h = 1e-6:
/// μ = (P₁₂(γ=h) − P₁₂(−h))/(2h),  K = (P₁₁((1+h)I) − P₁₁((1−h)I))/(6h).
fn measured_moduli(law: &dyn Material) -> (f64, f64) {
    let opts = ForceOptions::default();
    let p = |f: Matrix3<f64>| {
        law.stress(&f, &opts)
            .expect("an invariant or stretch law has a stress")
            .1
    };
    let h = 1e-6;
    let shear = |g: f64| {
        let mut f = Matrix3::identity();
        f[(0, 1)] = g;
        p(f)[(0, 1)]
    };
    let dilation = |d: f64| p(Matrix3::identity() * (1.0 + d))[(0, 0)];
    let mu = (shear(h) - shear(-h)) / (2.0 * h);
    let k = (dilation(h) - dilation(-h)) / (6.0 * h);
    (mu, k)
}

#[test]
fn young_and_poisson_give_the_small_strain_moduli_of_every_law() {
    let mu0 = E / (2.0 * (1.0 + NU));
    let k0 = E / (3.0 * (1.0 - 2.0 * NU));
    let mut covered = Vec::new();
    for entry in heml::materials_list() {
        let Some(mapping) = entry.small_strain else {
            continue;
        };
        let mut params = Params::from([("E", E), ("nu", NU)]);
        for p in entry.params.iter().filter(|p| !mapping.fields.contains(&p.name)) {
            let (_, _, v) = SHAPE
                .iter()
                .find(|(law, name, _)| *law == entry.name && *name == p.name)
                .unwrap_or_else(|| panic!("add a value of '{}' for law '{}' to SHAPE", p.name, entry.name));
            params.set(p.name, *v);
        }
        let law = entry.instantiate(&params).unwrap();
        let (mu, k) = measured_moduli(law.as_ref());
        // Tolerance: the central differences leave O(h²) = 1e-12 of truncation (shear
        // stress is odd in γ; the stiffening of the exponential laws is O(1) relative),
        // and round-off of about ε·(μ + K)·10/h ≈ 2.2e-16·2.2e5·10/1e-6 ≈ 5e-4 Pa, i.e.
        // ≲ 3e-8 of μ: 1e-6 relative has a margin of 30 on round-off, while a wrong
        // mapping is off by a finite fraction (stable neo-Hookean was off by 25 %, 8 %).
        let (e_mu, e_k) = ((mu - mu0) / mu0, (k - k0) / k0);
        assert!(
            e_mu.abs() <= 1e-6 && e_k.abs() <= 1e-6,
            "{}: mu = {mu} ({:+.4} %), K = {k} ({:+.4} %), expected mu = {mu0}, K = {k0} (mapping `{}`)",
            entry.name,
            100.0 * e_mu,
            100.0 * e_k,
            mapping.text
        );
        covered.push(entry.name);
    }
    for law in heml_tests::BUILT_IN {
        if heml::find_material(law).unwrap().kind == LawKind::Link {
            continue;
        }
        assert!(covered.contains(&law), "{law} takes no E/nu: {covered:?}");
    }
}

/// The Lamé laws take E/ν for both parameters; every other built-in law names the
/// parameters still to give, and a link law refuses E/ν with its parameter list.
#[test]
fn young_and_poisson_require_the_shape_parameters_and_are_refused_without_a_mapping() {
    let young = Params::from([("E", E), ("nu", NU)]);
    assert!(heml::material("stable_neo_hookean", &young).is_ok());
    let err = heml::material("gent", &young).unwrap_err().to_string();
    assert!(err.contains("missing parameter(s) 'jm' besides E/nu"), "{err}");
    assert!(err.contains("mu, jm, kappa (or E, nu and jm)"), "{err}");
    let err = heml::material("mass_spring", &young).unwrap_err().to_string();
    assert!(
        err.contains("does not take Young's modulus") && err.contains("expected parameters: k"),
        "{err}"
    );
    let err = heml::material("neo_hookean", &young.clone().with("mu", 1.0))
        .unwrap_err()
        .to_string();
    assert!(err.contains("not both"), "{err}");
    // c10 = μ/2 − c01 < 0: the computed value is refused, with where it came from
    let err = heml::material("mooney_rivlin", &young.clone().with("c01", 20e3))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("'c10'") && err.contains("must not be negative") && err.contains("E = 60000"),
        "{err}"
    );
    let err = heml::material("veronda_westmann", &young.with("c2", 0.0))
        .unwrap_err()
        .to_string();
    assert!(err.contains("'c1' is inf"), "{err}");
}
