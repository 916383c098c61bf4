//! Shared helpers for HEML's cross-crate tests: random meshes and deformations,
//! finite differences, and parameter ranges in which each law is well defined.
//!
//! This crate depends on the `heml` facade only, like a user's crate would.

pub mod grouped;
pub mod implicit;
pub mod laws;
pub mod warnings;

use heml::nalgebra::{Matrix3, Rotation3};
use heml::prelude::*;
use rand::Rng;

pub use laws::{all_laws, all_laws_on, fibred, random_unit, sample_params, TestQuartic};

/// The laws of the `materials` crate, by registry name, sorted.
pub const BUILT_IN: [&str; 11] = [
    "arruda_boyce",
    "fung_demiray",
    "gent",
    "mass_spring",
    "mooney_rivlin",
    "neo_hookean",
    "ogden",
    "saint_venant_kirchhoff",
    "stable_neo_hookean",
    "veronda_westmann",
    "yeoh",
];

/// Re-exported so that tests build their RNG the same way.
pub use rand_chacha::ChaCha8Rng as TestRng;

/// The property tests' configuration: `cases` random cases, and a failing case's
/// seed saved beside the test's source (`tests/<name>.proptest-regressions`, checked
/// in) and re-run first on every later run. Proptest's default looks for the crate's
/// `lib.rs` above the test file, which integration tests do not have: it then warns
/// and neither saves nor re-runs any case.
///
/// Long mode: `PROPTEST_CASES=N` (proptest's own variable) replaces every test's
/// quick-CI count with N, for soaking the suite for rare cases before a release.
pub fn proptest_config(cases: u32) -> proptest::test_runner::Config {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(cases);
    proptest::test_runner::Config {
        cases,
        failure_persistence: Some(Box::new(proptest::test_runner::FileFailurePersistence::WithSource(
            "proptest-regressions",
        ))),
        ..proptest::test_runner::Config::default()
    }
}

/// A deterministic RNG for `seed`.
pub fn rng(seed: u64) -> TestRng {
    use rand::SeedableRng;
    TestRng::seed_from_u64(seed)
}

/// A small jittered box mesh (`cells` per axis, six tets per cell) of size ~1, with
/// interior and boundary nodes moved by up to 15 % of a cell so that tets are
/// irregular, as in real meshes.
pub fn jittered_box(rng: &mut impl Rng, cells: [usize; 3]) -> TetMesh {
    let size = [1.0, 0.8, 0.6];
    let m = heml::mesh::generate::box_mesh(size, cells, heml::mesh::generate::HexSplit::Six).unwrap();
    let h = size
        .iter()
        .zip(&cells)
        .map(|(s, c)| s / *c as f64)
        .fold(f64::INFINITY, f64::min);
    let nodes: Vec<Vec3> = m
        .nodes()
        .iter()
        .map(|p| p + Vec3::from_fn(|_, _| rng.gen_range(-0.15..0.15) * h))
        .collect();
    let tets: Vec<[usize; 4]> = m.tets().iter().map(|t| t.map(|i| i as usize)).collect();
    TetMesh::new(nodes, tets).unwrap()
}

/// One random, reasonably shaped tet (rest volume bounded away from zero).
pub fn random_tet(rng: &mut impl Rng) -> TetMesh {
    loop {
        let base = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let nodes: Vec<[f64; 3]> = base
            .iter()
            .map(|p| {
                [
                    p[0] + rng.gen_range(-0.3..0.3),
                    p[1] + rng.gen_range(-0.3..0.3),
                    p[2] + rng.gen_range(-0.3..0.3),
                ]
            })
            .collect();
        if let Ok(m) = TetMesh::from_arrays(&nodes, &[[0, 1, 2, 3]]) {
            if m.tet_volume(0) > 0.05 {
                return m;
            }
        }
    }
}

/// A random rotation (uniform enough for testing: random axis, any angle).
pub fn random_rotation(rng: &mut impl Rng) -> Matrix3<f64> {
    let axis = Vec3::new(
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
    );
    let angle = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
    let axis = heml::nalgebra::Unit::try_new(axis, 1e-6).unwrap_or(Vec3::z_axis());
    *Rotation3::from_axis_angle(&axis, angle).matrix()
}

/// A random large deformation: rotation × (stretches in [`lo`, `hi`] with shear),
/// plus a translation and per-node noise of relative size `noise`.
pub fn random_deformation(rng: &mut impl Rng, mesh: &TetMesh, lo: f64, hi: f64, noise: f64) -> Vec<Vec3> {
    let stretch = Matrix3::from_diagonal(&Vec3::from_fn(|_, _| rng.gen_range(lo..hi)));
    let shear = Matrix3::from_fn(|i, j| if i < j { rng.gen_range(-0.3..0.3) } else { 0.0 });
    let f = random_rotation(rng) * (stretch + shear);
    let t = Vec3::from_fn(|_, _| rng.gen_range(-2.0..2.0));
    mesh.nodes()
        .iter()
        .map(|p| f * p + t + Vec3::from_fn(|_, _| rng.gen_range(-noise..noise)))
        .collect()
}

/// Moves one node of `mesh`'s first tet through the opposite face so that the tet
/// inverts (J < 0), keeping the rest of the deformation `x`.
pub fn invert_first_tet(mesh: &TetMesh, x: &mut [Vec3], depth: f64) {
    let t = mesh.tets()[0].map(|i| i as usize);
    let (a, b, c, d) = (x[t[0]], x[t[1]], x[t[2]], x[t[3]]);
    let n = (c - b).cross(&(d - b)).normalize();
    let dist = (a - b).dot(&n);
    x[t[0]] = a - n * (dist * (1.0 + depth));
}

/// Central finite difference of `energy` with respect to every coordinate.
pub fn fd_gradient(x: &[Vec3], h: f64, mut energy: impl FnMut(&[Vec3]) -> f64) -> Vec<Vec3> {
    let mut y = x.to_vec();
    let mut g = vec![Vec3::zeros(); x.len()];
    for i in 0..x.len() {
        for k in 0..3 {
            let x0 = y[i][k];
            y[i][k] = x0 + h;
            let ep = energy(&y);
            y[i][k] = x0 - h;
            let em = energy(&y);
            y[i][k] = x0;
            g[i][k] = (ep - em) / (2.0 * h);
        }
    }
    g
}

/// Whether the law `name` has no finite energy at this state, so that there is no
/// derivative to compare (asserting that the forces `f` say so too, so that a step
/// rolls back instead of moving on):
/// - Gent is undefined beyond its locking stretch (Ī1 − 3 ≥ Jm), which a deeply
///   inverted tet can reach (Ī1 is taken at J0 there);
/// - HGO's exp(k2·E²) exceeds f64 once k2·E² > 709.8: at k2 ≈ 1.7 that is E ≈ 20,
///   i.e. Ī4 ≈ 28 (at J0 = 0.4, a fibre stretched ~3.9×), which a neighbour of a
///   deeply inverted tet reaches (CI seed 18174480426871946383 of `forces.rs`,
///   depth 1.44).
///
/// Any other law with a non-finite energy fails.
pub fn beyond_the_law(name: &str, e: f64, f: &[Vec3]) -> bool {
    if e.is_finite() {
        return false;
    }
    assert!(matches!(name, "gent" | "holzapfel_gasser_ogden"), "{name}: energy {e}");
    if name == "holzapfel_gasser_ogden" {
        assert!(
            f.iter().any(|v| !v.iter().all(|c| c.is_finite())),
            "{name}: energy {e} but all forces finite"
        );
    }
    true
}

/// Whether `exact` is minus the derivative of a sampled function, given its value
/// `at_x` and `g` = [φ(−2h), φ(−h), φ(h), φ(2h)] (componentwise samples along the
/// direction(s) of differentiation: forces along dx for a tangent, the energy along
/// each coordinate for forces); else a message with the errors found.
///
/// First the central difference D(h) within 1e-6·`scale` (the callers justify h and
/// that bound). Then:
/// - A fibre switch max(I4 − 1, 0) within h of x makes D(h) straddle a kink (the
///   derivative there is the one-sided one of x's side); one of the second-order
///   one-sided differences (−3φ(0) + 4φ(±h) − φ(±2h))/(±2h) stays on x's side: same
///   truncation order h², same bound.
/// - Inverting one tet can leave a neighbour nearly flat (|J| ~ 1e-4, one eigenvalue
///   of C ~1e-9 of its trace). A principal-stretch law then has |φ‴|/|φ′| ~ λ_min⁻³
///   and values with relative round-off ~ε·e_max/e_min ~ 1e-7, so D(h) itself errs by
///   up to ~1e-3·scale (Ogden: 31 of 20 000 samples of the tangent test's generator,
///   1 of 3 000 of the forces test's; there the error fell ×80–100 per decade of h
///   down to a round-off floor — the difference's truncation, not a wrong
///   derivative). Then the Richardson extrapolation R = (4D(h) − D(2h))/3 (truncation
///   O(h⁴)) must agree within 1e-6·scale plus 2·|D(h) − D(2h)|, which measures the
///   difference's own error (3× D(h)'s truncation, plus the round-off of both). Taken
///   only while that estimate is below 1e-2·scale, so a missing or wrong term
///   (O(scale)) still fails.
pub fn fd_agrees(exact: &[Vec3], at_x: &[Vec3], g: &[Vec<Vec3>; 4], h: f64, scale: f64) -> Result<(), String> {
    let [fm2, fm, fp, fp2] = g;
    let central = |a: &[Vec3], b: &[Vec3], step: f64| -> Vec<Vec3> {
        a.iter().zip(b).map(|(p, m)| -(p - m) / (2.0 * step)).collect()
    };
    let d1 = central(fp, fm, h);
    let err = max_diff(exact, &d1);
    if err <= 1e-6 * scale {
        return Ok(());
    }
    let one_sided = |f1: &[Vec3], f2: &[Vec3], s: f64| -> Vec<Vec3> {
        at_x.iter()
            .zip(f1)
            .zip(f2)
            .map(|((a, b), c)| -(-3.0 * a + 4.0 * b - c) / (2.0 * h * s))
            .collect()
    };
    let kink = max_diff(exact, &one_sided(fp, fp2, 1.0)).min(max_diff(exact, &one_sided(fm, fm2, -1.0)));
    if kink <= 1e-6 * scale {
        return Ok(());
    }
    let d2 = central(fp2, fm2, 2.0 * h);
    let uncertainty = max_diff(&d1, &d2);
    let richardson: Vec<Vec3> = d1.iter().zip(&d2).map(|(a, b)| (a * 4.0 - b) / 3.0).collect();
    let extrapolated = max_diff(exact, &richardson);
    if uncertainty <= 1e-2 * scale && extrapolated <= 1e-6 * scale + 2.0 * uncertainty {
        return Ok(());
    }
    Err(format!(
        "|exact − FD| = {err:e} (one-sided {kink:e}, extrapolated {extrapolated:e} with FD \
         uncertainty {uncertainty:e}) vs scale {scale:e}"
    ))
}

/// The energy moved along every coordinate in turn: `[E(x + s·e_ic) for s in steps]`
/// (the samples [`fd_agrees`] takes to check forces = −∇E).
pub fn energy_samples<const N: usize>(
    x: &[Vec3],
    steps: [f64; N],
    mut energy: impl FnMut(&[Vec3]) -> f64,
) -> [Vec<Vec3>; N] {
    let mut y = x.to_vec();
    let mut out: [Vec<Vec3>; N] = std::array::from_fn(|_| vec![Vec3::zeros(); x.len()]);
    for i in 0..x.len() {
        for k in 0..3 {
            let x0 = y[i][k];
            for (o, s) in out.iter_mut().zip(steps) {
                y[i][k] = x0 + s;
                o[i][k] = energy(&y);
            }
            y[i][k] = x0;
        }
    }
    out
}

/// max_i |a_i − b_i|.
pub fn max_diff(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max)
}

/// max_i |a_i|.
pub fn max_norm(a: &[Vec3]) -> f64 {
    a.iter().map(|p| p.norm()).fold(0.0, f64::max)
}

/// The net force Σ f_i and net torque Σ x_i × f_i.
pub fn net_force_and_torque(x: &[Vec3], f: &[Vec3]) -> (Vec3, Vec3) {
    let force = f.iter().sum();
    let torque = x.iter().zip(f).map(|(p, q)| p.cross(q)).sum();
    (force, torque)
}
