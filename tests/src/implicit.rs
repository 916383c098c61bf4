//! Shared set-ups of the implicit-integration tests (CG and sparse-Cholesky paths).

use heml::integrators::Newmark;
use heml::mesh::generate::{box_mesh, HexSplit};
use heml::prelude::*;
use heml::system::{ImplicitSettings, System, SystemBuilder};

/// Forces the registries' link sections into the test binary.
pub fn link() {
    let _ = (heml::integrators_list(), heml::materials_list());
}

/// max_i |a_i − b_i| / max_i |b_i|.
pub fn relative_error(a: &[Vec3], b: &[Vec3]) -> f64 {
    let scale = b.iter().map(|v| v.norm()).fold(0.0, f64::max);
    a.iter().zip(b).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max) / scale
}

/// Soft tissue on a `size` box of `cells` (six-tet split): neo-Hookean (Young's
/// modulus `e`, Poisson ratio `nu`), ρ = 1000, gravity, clamped at x = 0, mass
/// damping α = 15/s, no energy bookkeeping — the implicit tests' common scene.
pub fn tissue(size: [f64; 3], cells: [usize; 3], split: HexSplit, e: f64, nu: f64) -> SystemBuilder {
    link();
    let mesh = box_mesh(size, cells, split).unwrap();
    System::builder(mesh)
        .material("neo_hookean", Params::from([("E", e), ("nu", nu)]))
        .unwrap()
        .density(1000.0)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .fix_where(|p| p.x < 1e-9)
        .rayleigh(15.0, 0.0)
        .energy_every(0)
}

/// A 10 × 2 × 2 cm neo-Hookean cantilever (E = 100 kPa, ν = 0.3) clamped at x = 0,
/// plucked by an initial velocity growing as x² along it; energies every step.
pub fn plucked_cantilever() -> System {
    link();
    let mesh = box_mesh([0.1, 0.02, 0.02], [10, 2, 2], HexSplit::Six).unwrap();
    System::builder(mesh)
        .material("neo_hookean", Params::from([("E", 1e5), ("nu", 0.3)]))
        .unwrap()
        .density(1000.0)
        .fix_where(|p| p.x < 1e-9)
        .initial_velocity(|p| Vec3::new(0.0, 0.0, 0.1 * (p.x / 0.1).powi(2)))
        .energy_every(1)
        .build()
        .unwrap()
}

/// Steps `sys` undamped with Newmark at `dt` `steps` times; returns the worst
/// relative total-energy error and the largest tip amplitude |u_z| seen.
pub fn newmark_energy_drift(sys: &mut System, settings: ImplicitSettings, dt: f64, steps: usize) -> (f64, f64) {
    let e0 = sys.energies().unwrap().total;
    assert!(e0 > 0.0);
    let mut nm = Newmark::with_settings(settings);
    let (mut worst, mut max_tip) = (0.0f64, 0.0f64);
    for _ in 0..steps {
        let e = nm.step(sys, dt).unwrap().energies.unwrap().total;
        worst = worst.max((e - e0).abs() / e0);
        max_tip = sys.displacements().iter().map(|u| u.z.abs()).fold(max_tip, f64::max);
    }
    (worst, max_tip)
}
