//! A law the `materials` crate does not have, declared here through the facade only,
//! and the parameter ranges in which each registered law is well defined.

use heml::law::*;
use heml::prelude::*;
use rand::Rng;

/// A quartic test law, declared outside the workspace's `materials` crate to prove that
/// user crates depending only on `heml` can add laws: it mixes I1, I2 and J with a
/// `let` block, function and method calls, so every kernel branch is exercised.
#[heml::material(name = "test_quartic")]
#[energy({
    let a = I1bar - 3.0;
    let b = I2bar - 3.0;
    c1 * a + c2 * a * b + c3 * powi(a, 2) * a.powi(2) + kappa * (J - 1.0 - ln(J))
})]
pub struct TestQuartic {
    /// Linear term (Pa).
    pub c1: f64,
    /// Coupling of Ī1 and Ī2 (Pa).
    #[param(signed)]
    pub c2: f64,
    /// Quartic term (Pa).
    pub c3: f64,
    /// Volumetric stiffness (Pa).
    pub kappa: f64,
}

/// Random parameters for law `entry`, in ranges where the law is defined for the
/// deformations the tests use (stretches 0.6–1.6, some inverted tets): Gent's locking
/// parameter large enough that Ī1 − 3 < Jm, Arruda–Boyce's λm > 1, and so on.
pub fn sample_params(entry: &MaterialEntry, rng: &mut impl Rng) -> Params {
    let mut p = Params::new();
    for info in entry.params {
        let v = match (entry.name, info.name) {
            ("gent", "jm") => rng.gen_range(40.0..80.0),
            ("arruda_boyce", "lm") => rng.gen_range(2.0..6.0),
            ("fung_demiray", "b") | ("veronda_westmann", "c2") => rng.gen_range(0.2..1.5),
            // HGO's dispersion lies in [0, 1/3] (1/3: isotropic)
            ("holzapfel_gasser_ogden", "dispersion") => rng.gen_range(0.0..0.3),
            (_, "kappa") | (_, "lambda") => rng.gen_range(1.0..10.0),
            _ => rng.gen_range(0.3..2.0),
        };
        p.set(info.name, v);
    }
    p
}

/// `law` with random unit fibre directions in every tet of `mesh` when it is a
/// fibre law (unchanged otherwise): under the tests' random deformations (stretches
/// 0.6–1.6 along random axes) some fibres are stretched and some compressed, so
/// both sides of a tension-only switch are sampled (`tests/suite/fibres.rs` counts them).
pub fn fibred(law: Box<dyn Material>, mesh: &TetMesh, rng: &mut impl Rng) -> Box<dyn Material> {
    if law.fibre_families() == 0 {
        return law;
    }
    let dirs = (0..mesh.n_tets())
        .map(|_| [random_unit(rng), random_unit(rng)])
        .collect();
    let fibres = heml::heml_core::fibres::Fibres::new(2, dirs).unwrap();
    law.with_fibres(std::sync::Arc::new(fibres)).unwrap()
}

/// A unit vector uniform on the sphere.
pub fn random_unit(rng: &mut impl Rng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        );
        let n = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    }
}

/// [`all_laws`] with random fibres on `mesh` for the fibre laws ([`fibred`]).
pub fn all_laws_on(mesh: &TetMesh, rng: &mut impl Rng) -> Vec<(&'static str, Box<dyn Material>)> {
    all_laws(rng)
        .into_iter()
        .map(|(n, l)| (n, fibred(l, mesh, rng)))
        .collect()
}

/// Every registered law with random parameters from [`sample_params`], as
/// (name, law); asserts that the built-in laws and `test_quartic` are all there.
pub fn all_laws(rng: &mut impl Rng) -> Vec<(&'static str, Box<dyn Material>)> {
    let laws: Vec<_> = heml::materials_list()
        .into_iter()
        .map(|e| (e.name, e.instantiate(&sample_params(e, rng)).unwrap()))
        .collect();
    assert!(
        laws.len() >= 12,
        "expected the 11 built-in laws and test_quartic, got {}",
        laws.len()
    );
    laws
}
