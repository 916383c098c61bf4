//! Convergence orders, energy behaviour and force caching of the three integrators.

use heml_core::mesh::generate::{box_mesh, HexSplit};
use heml_core::params::Params;
use heml_core::system::{Integrator, System};
use heml_core::{TetMesh, Vec3};
use heml_integrators::{ExplicitEuler, SymplecticEuler, VelocityVerlet};

/// Laws are taken by name (`SystemBuilder::material`), so that their fields are the
/// ones heml-materials compiled: `material_law(Box::new(Invariant(law)))` here would
/// instantiate every field of the law again in this test binary (~20 s of release
/// build). The reference keeps heml-materials, and its registrations, linked.
fn link_materials() {
    heml_materials::__link();
}

/// A regular tetrahedron of edge 1: base (nodes 0–2) in z = 0, apex (node 3) above.
fn regular_tet() -> TetMesh {
    let r = 1.0 / 3f64.sqrt();
    let h = (2.0f64 / 3.0).sqrt();
    TetMesh::from_arrays(
        &[
            [r, 0.0, 0.0],
            [-r / 2.0, 0.5, 0.0],
            [-r / 2.0, -0.5, 0.0],
            [0.0, 0.0, h],
        ],
        &[[0, 1, 2, 3]],
    )
    .unwrap()
}

/// Error at t = 1.125 periods of the apex oscillator (base fixed, three springs k on the
/// apex): by symmetry it moves along z only, with k_eff = 3k cos²θ = 2k, so
/// z(t) = A cos(ωt), ω² = 2k/m. A = 1e-6 (edge 1) keeps the spring nonlinearity
/// (relative O(A²) = 1e-12) far below the discretisation errors measured (> 1e-11).
fn oscillator_error(integrator: &mut dyn Integrator, steps: usize) -> f64 {
    let (k, rho, amp) = (40.0, 1000.0, 1e-6);
    let mesh = regular_tet();
    let m = rho * mesh.tet_volume(0) / 4.0;
    let omega = (2.0 * k / m).sqrt();
    link_materials();
    let mut sys = System::builder(mesh)
        .material("mass_spring", Params::from([("k", k)]))
        .unwrap()
        .density(rho)
        .fix_nodes([0, 1, 2])
        .energy_every(0)
        .build()
        .unwrap();
    sys.positions_mut()[3].z += amp;
    let t_end = 1.125 * 2.0 * std::f64::consts::PI / omega;
    let dt = t_end / steps as f64;
    for _ in 0..steps {
        integrator.step(&mut sys, dt).unwrap();
    }
    let z = sys.positions()[3].z - sys.rest_positions()[3].z;
    let lateral = sys.positions()[3].xy().norm();
    assert!(lateral < 1e-14, "apex left the axis by {lateral}");
    (z - amp * (omega * t_end).cos()).abs() / amp
}

fn observed_orders(make: fn() -> Box<dyn Integrator>) -> Vec<f64> {
    // ω dt = 2π·1.125/N = 0.018, 0.009, 0.0044: the asymptotic range of all three schemes
    let errs: Vec<f64> = [400, 800, 1600]
        .iter()
        .map(|&n| oscillator_error(&mut *make(), n))
        .collect();
    eprintln!("{}: relative errors {errs:?}", make().name());
    errs.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

#[test]
fn explicit_euler_is_first_order() {
    let p = observed_orders(|| Box::new(ExplicitEuler));
    eprintln!("explicit_euler orders {p:.3?}");
    assert!(p.iter().all(|p| (0.8..1.2).contains(p)), "{p:?}");
}

#[test]
fn symplectic_euler_is_first_order() {
    let p = observed_orders(|| Box::new(SymplecticEuler));
    eprintln!("symplectic_euler orders {p:.3?}");
    assert!(p.iter().all(|p| (0.8..1.2).contains(p)), "{p:?}");
}

#[test]
fn velocity_verlet_is_second_order() {
    let p = observed_orders(|| Box::new(VelocityVerlet));
    eprintln!("velocity_verlet orders {p:.3?}");
    assert!(p.iter().all(|p| (1.8..2.2).contains(p)), "{p:?}");
}

/// A clamped neo-Hookean bar set swinging by an initial velocity field, undamped.
/// Returns the relative energy excursions (max |E − E0|/E0, final (E − E0)/E0).
fn energy_run(integrator: &mut dyn Integrator, dt_fraction: f64, steps: usize) -> (f64, f64) {
    let mesh = box_mesh([1.0, 0.25, 0.25], [6, 2, 2], HexSplit::Six).unwrap();
    let (mu, lambda) = heml_core::params::lame(1e4, 0.3);
    link_materials();
    let mut sys = System::builder(mesh)
        .material("neo_hookean", Params::from([("mu", mu), ("lambda", lambda)]))
        .unwrap()
        .density(1000.0)
        .fix_where(|p| p.x < 1e-9)
        .initial_velocity(|p| Vec3::new(0.0, 0.2 * p.x * p.x, 0.3 * p.x))
        .build()
        .unwrap();
    let e0 = sys.energies().unwrap().total;
    let dt = dt_fraction * sys.stable_dt();
    let mut worst: f64 = 0.0;
    let mut last = e0;
    for _ in 0..steps {
        last = integrator.step(&mut sys, dt).unwrap().energies.unwrap().total;
        worst = worst.max((last - e0).abs() / e0);
    }
    (worst, (last - e0) / e0)
}

#[test]
fn symplectic_schemes_keep_energy_bounded() {
    // 5000 steps at half the stable step ≈ 25 periods of the fundamental mode.
    // Symplectic Euler's energy oscillates by O(ω dt) of the excited modes: the
    // initial field is smooth (low modes, ω dt ≲ 0.05), so ≲ 2 %; Verlet's error is
    // O((ω dt)²), well below 0.5 %. Neither may drift: the final error is no larger
    // than the oscillation amplitude.
    let (worst, end) = energy_run(&mut SymplecticEuler, 0.5, 5000);
    eprintln!("symplectic_euler: max |ΔE|/E0 = {worst:.3e}, final {end:.3e}");
    assert!(worst < 0.02, "{worst}");
    let (worst, end) = energy_run(&mut VelocityVerlet, 0.5, 5000);
    eprintln!("velocity_verlet: max |ΔE|/E0 = {worst:.3e}, final {end:.3e}");
    assert!(worst < 0.005, "{worst}");
}

#[test]
fn explicit_euler_gains_energy() {
    // Each step multiplies a mode's energy by 1 + (ω dt)²: at a tenth of the stable step
    // the energy grows steadily (measured +1.35 % after 250 steps, +5.2 % after 500; the
    // stiffest modes, growing by ~3 % per step, overflow to NaN near step 1000), while
    // the symplectic schemes stay within 0.7 % over 5000 steps at 5x the step.
    let (_, half) = energy_run(&mut ExplicitEuler, 0.1, 250);
    let (_, end) = energy_run(&mut ExplicitEuler, 0.1, 500);
    eprintln!("explicit_euler: (E − E0)/E0 = {half:.3e} after 250 steps, {end:.3e} after 500");
    assert!(half > 0.0 && end > 2.0 * half && end > 0.03, "{half} {end}");
}

#[test]
fn verlet_recomputes_forces_after_the_system_is_edited() {
    // Step, edit the positions, step: must equal a fresh system given the edited state
    // and stepped once (stale cached forces would differ).
    let build = || {
        let mesh = box_mesh([1.0, 0.3, 0.3], [3, 1, 1], HexSplit::Six).unwrap();
        let (mu, lambda) = heml_core::params::lame(1e4, 0.3);
        link_materials();
        System::builder(mesh)
            .material("neo_hookean", Params::from([("mu", mu), ("lambda", lambda)]))
            .unwrap()
            .fix_where(|p| p.x < 1e-9)
            .build()
            .unwrap()
    };
    let mut a = build();
    let dt = 0.5 * a.stable_dt();
    let mut verlet = VelocityVerlet;
    a.positions_mut()[15].z += 0.01;
    verlet.step(&mut a, dt).unwrap();
    assert!(a.forces_current());
    a.positions_mut()[12].y -= 0.02;
    assert!(!a.forces_current());
    let (x, v) = (a.positions().to_vec(), a.velocities().to_vec());
    verlet.step(&mut a, dt).unwrap();
    let mut b = build();
    b.positions_mut().copy_from_slice(&x);
    b.velocities_mut().copy_from_slice(&v);
    verlet.step(&mut b, dt).unwrap();
    assert_eq!(a.positions(), b.positions());
    assert_eq!(a.velocities(), b.velocities());
}
