//! Declaring a brand-new law in a program: one attribute and an energy. The macro
//! derives the exact gradient and Hessian symbolically, builds the inversion
//! extension and registers the law, which is then found by name like the built-in
//! ones — here it bends a clamped beam under gravity.
//!
//! `cargo run --release --example declare_a_law`

use heml::law::InvariantLaw;
use heml::mesh::generate::{beam, HexSplit};
use heml::prelude::*;

/// A Mooney–Rivlin-like law with a quadratic volumetric penalty, in isochoric
/// invariants.
#[heml::material(name = "example_isochoric_mr")]
#[energy(c1 * (I1bar - 3.0) + c2 * (I2bar - 3.0) + kappa / 2.0 * (J - 1.0).powi(2))]
pub struct IsochoricMr {
    /// First coefficient (Pa).
    pub c1: f64,
    /// Second coefficient (Pa).
    pub c2: f64,
    /// Bulk modulus (Pa).
    pub kappa: f64,
}

fn main() -> heml::Result<()> {
    // the registry knows it, with its parameters and energy text
    let entry = heml::find_material("example_isochoric_mr")?;
    println!(
        "{}: parameters {:?}",
        entry.name,
        entry.params.iter().map(|p| p.name).collect::<Vec<_>>()
    );

    // stress-free at rest: w and its gradient vanish at I1 = I2 = 3, J = 1
    let law = IsochoricMr {
        c1: 2e4,
        c2: 5e3,
        kappa: 5e5,
    };
    let d = law.dw(3.0, 3.0, 1.0);
    assert_eq!(d.w, 0.0);
    // the I1/I2 gradient is balanced by the J term: the rest stress is
    // 2(w1 + 2 w2) + wJ = 0 for an isochoric law (round-off of the cancellation)
    assert!((2.0 * (d.d[0] + 2.0 * d.d[1]) + d.d[2]).abs() < 1e-9 * law.c1, "{d:?}");

    // a 10 × 2 × 2 cm beam, clamped at x = 0, under gravity, to equilibrium
    let mesh = beam(0.1, 0.02, 0.02, 10, HexSplit::Six)?;
    let params = Params::from([("c1", 2e4), ("c2", 5e3), ("kappa", 5e5)]);
    let mut sys = heml::system(mesh)
        .material("example_isochoric_mr", &params)?
        .density(1000.0)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .fix_where(|p| p.x < 1e-9)
        .build()?;
    let report = sys.solve_static(&StaticOptions::default())?;
    let tip = sys.displacements().iter().map(|u| u.z).fold(0.0, f64::min);
    println!(
        "static solve: {}; tip deflection {:.3} mm",
        report.criterion(),
        -tip * 1e3
    );
    assert!(tip < 0.0, "the beam must sag");
    // the clamp carries the whole weight: reaction = m g
    let weight = sys.total_mass() * 9.81;
    let reaction = sys.total_reaction().z;
    assert!(
        (reaction - weight).abs() < 1e-6 * weight,
        "reaction {reaction} vs weight {weight}"
    );
    Ok(())
}

#[test]
fn declare_a_law() {
    main().unwrap();
}
