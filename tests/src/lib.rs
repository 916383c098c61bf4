//! Shared helpers for HEML's cross-crate tests: random meshes and deformations,
//! finite differences, and parameter ranges in which each law is well defined.
//!
//! This crate depends on the `heml` facade only, like a user's crate would.

pub mod implicit;
pub mod laws;

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
