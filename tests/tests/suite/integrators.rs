//! Integrators and the simulation layer through the `heml` facade: registry lookups,
//! laws picked by name, and a hanging body whose support reactions carry its weight.

use heml::mesh::generate::{box_mesh, HexSplit};
use heml::prelude::*;
use heml::system::{PronyTerm, Ramp, System};

/// Registry lookups made directly in heml-core (as `System::builder` does) need the
/// member crates linked; any facade lookup guarantees it.
fn link() {
    let _ = heml::integrators_list();
}

#[test]
fn all_three_integrators_are_registered() {
    link();
    let names: Vec<&str> = heml::integrators_list().iter().map(|e| e.name).collect();
    for name in ["explicit_euler", "symplectic_euler", "velocity_verlet"] {
        assert!(names.contains(&name), "{name} missing from {names:?}");
        let entry = heml::integrators_list().into_iter().find(|e| e.name == name).unwrap();
        assert_eq!(heml::integrator(name).unwrap().name(), name);
        assert!(
            !entry.doc.is_empty() && entry.doc.contains("order"),
            "{name}: {}",
            entry.doc
        );
    }
    let e = heml::integrator("symplectic_eulr").err().unwrap().to_string();
    assert!(
        e.contains("did you mean 'symplectic_euler'") && e.contains("velocity_verlet"),
        "{e}"
    );
}

#[test]
fn hanging_body_reactions_carry_its_weight() {
    // A 10 cm gel cube hanging from its top face, damped to rest with each symplectic
    // scheme: at equilibrium the sum of the reactions balances the weight. The residual
    // is the inertia Σ m a of the free nodes. With α = 100/s every mode is underdamped
    // (the fundamental ω1 ≈ 80 rad/s > α/2) and decays like e^(−αt/2) = e^(−50) after
    // 1 s; heavier damping would be slower (overdamped modes decay like e^(−ω²t/α)).
    // 1e-6 of the weight leaves ample room for round-off.
    link();
    let g = Vec3::new(0.0, 0.0, -9.81);
    for name in ["symplectic_euler", "velocity_verlet"] {
        let mesh = box_mesh([0.1, 0.1, 0.1], [3, 3, 3], HexSplit::Six).unwrap();
        let mut sys = System::builder(mesh)
            .material("neo_hookean", Params::from([("E", 3e4), ("nu", 0.4)]))
            .unwrap()
            .density(1050.0)
            .gravity(g)
            .fix_where(|p| p.z > 0.1 - 1e-9)
            .rayleigh(100.0, 0.0)
            .energy_every(0)
            .build()
            .unwrap();
        let mut integ = heml::integrator(name).unwrap();
        let dt = 0.8 * sys.stable_dt();
        while sys.time() < 1.0 {
            integ.step(&mut sys, dt).unwrap();
        }
        let weight = sys.total_mass() * g;
        let r = sys.total_reaction();
        assert!(
            (r + weight).norm() < 1e-6 * weight.norm(),
            "{name}: reaction {r:?} vs weight {weight:?}"
        );
        // fixed nodes never moved
        for &i in &sys.constraints().fixed {
            assert_eq!(sys.positions()[i], sys.rest_positions()[i]);
        }
        // it sagged
        assert!(sys.displacements().iter().all(|u| u.z <= 1e-12));
        assert!(sys.warnings().is_empty(), "{:?}", sys.warnings());
    }
}

#[test]
fn prony_relaxation_through_registered_law() {
    // Step strain held on every node: the reaction relaxes towards the long-term value
    // 1 − Σα_i; after 10 τ_max the discrete series is within 1e-3 of it (its error is
    // α_i e^(−t/τ) t Δt/(2τ²) < 1e-6 there).
    link();
    let terms = [PronyTerm::new(0.25, 0.02), PronyTerm::new(0.15, 0.05)];
    let mesh = box_mesh([1.0, 1.0, 1.0], [1, 1, 1], HexSplit::Six).unwrap();
    let all: Vec<usize> = (0..mesh.n_nodes()).collect();
    let mut sys = System::builder(mesh)
        .material("mooney_rivlin", mooney_params())
        .unwrap()
        .prony(&terms)
        .prescribe_with(&all, |p| Vec3::new(0.05 * p.x, 0.0, -0.02 * p.z), Ramp::Step)
        .build()
        .unwrap();
    let mut integ = heml::integrator("velocity_verlet").unwrap();
    let first = integ.step(&mut sys, 1e-3).unwrap();
    assert_eq!(first.step, 1);
    let r_start = sys.reactions()[7];
    while sys.time() < 0.5 {
        integ.step(&mut sys, 1e-3).unwrap();
    }
    let ratio = sys.reactions()[7].dot(&r_start) / r_start.norm_squared();
    let alpha_end = heml::system::relaxation(&terms, sys.time());
    let alpha_start = heml::system::relaxation(&terms, 1e-3);
    // r_start was measured at t = Δt (Verlet evaluates at the end of the step)
    assert!(
        (ratio - alpha_end / alpha_start).abs() < 2e-3,
        "{ratio} vs {}",
        alpha_end / alpha_start
    );
}

fn mooney_params() -> Params {
    let entry = heml::find_material("mooney_rivlin").unwrap();
    // give every declared parameter a plausible positive value (names vary by law)
    let mut p = Params::new();
    for info in entry.params {
        p.set(info.name, 1e3);
    }
    p
}

#[test]
fn bad_inputs_are_errors_naming_the_culprit() {
    link();
    let mesh = box_mesh([1.0, 1.0, 1.0], [1, 1, 1], HexSplit::Six).unwrap();
    let e = System::builder(mesh.clone())
        .material("neo_hookean", Params::from([("mu", 1.0), ("lambda", 1.0)]))
        .unwrap()
        .fix_nodes([0, 42, 7])
        .build()
        .unwrap_err()
        .to_string();
    assert!(e.contains("node id 42"), "{e}");
    let e = System::builder(mesh.clone())
        .material("neo_hokean", Params::new())
        .unwrap_err()
        .to_string();
    assert!(e.contains("did you mean 'neo_hookean'"), "{e}");
    let mut sys = System::builder(mesh)
        .material("neo_hookean", Params::from([("mu", 1.0), ("lambda", 1.0)]))
        .unwrap()
        .build()
        .unwrap();
    let mut integ = heml::integrator("symplectic_euler").unwrap();
    let e = integ.step(&mut sys, -1.0).unwrap_err().to_string();
    assert!(e.contains("dt = -1"), "{e}");
}
