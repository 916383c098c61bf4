//! Parameters of every built-in law for one soft tissue, given by its small-strain
//! Young's modulus and Poisson's ratio — so that laws can be compared, benchmarked
//! and swapped in a scene on an equal footing.

use heml_core::params::{lame, Params};

/// Parameters of the built-in invariant law `law` whose small-strain behaviour is
/// linear elasticity with Young's modulus `e` and Poisson's ratio `nu`.
///
/// The law-specific shape parameters are fixed at moderate soft-tissue values: Mooney–
/// Rivlin splits the shear modulus 70/30 between c10 and c01, Fung–Demiray and
/// Veronda–Westmann stiffen with exponent 1, Yeoh softens then stiffens
/// (c2 = −c1/10, c3 = c1/20), Gent locks at Jm = 50, Arruda–Boyce at λm = 3.
/// `None` for link laws (a spring stiffness depends on the mesh) and unknown names.
///
/// ```
/// use heml_materials::soft_tissue_params;
/// let p = soft_tissue_params("neo_hookean", 3e3, 0.45).unwrap();
/// assert!((p.get("mu").unwrap() - 3e3 / 2.9).abs() < 1e-9);
/// assert!(soft_tissue_params("mass_spring", 3e3, 0.45).is_none());
/// ```
pub fn soft_tissue_params(law: &str, e: f64, nu: f64) -> Option<Params> {
    let (mu, lambda) = lame(e, nu);
    let kappa = crate::bulk(mu, lambda);
    let p = |pairs: &[(&str, f64)]| Some(pairs.iter().fold(Params::new(), |p, (k, v)| p.with(k, *v)));
    match law {
        "neo_hookean" | "saint_venant_kirchhoff" => p(&[("mu", mu), ("lambda", lambda)]),
        "stable_neo_hookean" => {
            let s = crate::StableNeoHookean::from_lame(mu, lambda);
            p(&[("mu", s.mu), ("lambda", s.lambda)])
        }
        "mooney_rivlin" => p(&[("c10", 0.35 * mu), ("c01", 0.15 * mu), ("kappa", kappa)]),
        "fung_demiray" => p(&[("a", mu), ("b", 1.0), ("kappa", kappa)]),
        "veronda_westmann" => p(&[("c1", mu), ("c2", 1.0), ("kappa", kappa)]),
        "yeoh" => p(&[
            ("c1", mu / 2.0),
            ("c2", -mu / 20.0),
            ("c3", mu / 40.0),
            ("kappa", kappa),
        ]),
        "gent" => p(&[("mu", mu), ("jm", 50.0), ("kappa", kappa)]),
        "arruda_boyce" => {
            let lm: f64 = 3.0;
            let m2 = 1.0 / (lm * lm);
            // μ0 = μ·(1 + 3/5 m + 99/175 m² + 513/875 m³ + 42039/67375 m⁴), m = 1/λm²
            let factor = 1.0
                + 3.0 / 5.0 * m2
                + 99.0 / 175.0 * m2.powi(2)
                + 513.0 / 875.0 * m2.powi(3)
                + 42039.0 / 67375.0 * m2.powi(4);
            p(&[("mu", mu / factor), ("lm", lm), ("kappa", kappa)])
        }
        _ => None,
    }
}
