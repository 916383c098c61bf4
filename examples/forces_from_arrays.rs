//! Forces from plain arrays: a mesh given as node and tet arrays, a law looked up by
//! name, energy and nodal forces at a deformed configuration — and the two facts
//! every HEML force field guarantees, checked: the internal forces have no net force
//! and no net torque, and they are minus the gradient of the energy.
//!
//! `cargo run --release --example forces_from_arrays`

use heml::prelude::*;

fn main() -> heml::Result<()> {
    // two tetrahedra sharing the face (1, 2, 3)
    let nodes = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
    ];
    let tets = [[0, 1, 2, 3], [1, 2, 4, 3]];
    let mesh = TetMesh::from_arrays(&nodes, &tets)?;

    let law = heml::material("neo_hookean", &Params::from([("E", 3e3), ("nu", 0.45)]))?;
    let field = law.force_field(&mesh, None, &ForceOptions::default())?;

    // stretch 10 % along x and shear a little
    let x: Vec<Vec3> = mesh
        .nodes()
        .iter()
        .map(|p| Vec3::new(1.1 * p.x + 0.05 * p.y, p.y, p.z))
        .collect();
    let (energy, forces) = field.forces(&x)?;
    println!("energy {energy:.6e} J");
    for (i, f) in forces.iter().enumerate() {
        println!("node {i}: f = ({:+.4e}, {:+.4e}, {:+.4e}) N", f.x, f.y, f.z);
    }

    // Newton and Euler: internal forces sum to zero force and zero torque
    let scale: f64 = forces.iter().map(|f| f.norm()).sum();
    let net: Vec3 = forces.iter().sum();
    let torque: Vec3 = x.iter().zip(&forces).map(|(p, f)| p.cross(f)).sum();
    // round-off of sums of O(scale) terms
    assert!(net.norm() <= 1e-12 * scale, "net force {net}");
    assert!(torque.norm() <= 1e-12 * scale, "net torque {torque}");

    // f = −∂W/∂x: a central difference of the energy along node 4's x
    let h = 1e-6;
    let mut xp = x.clone();
    let mut xm = x.clone();
    xp[4].x += h;
    xm[4].x -= h;
    let fd = -(field.energy(&xp)? - field.energy(&xm)?) / (2.0 * h);
    // the central difference's truncation error is O(h²·W''') ≈ 1e-9 of the force here
    assert!((fd - forces[4].x).abs() <= 1e-6 * scale, "fd {fd} vs {}", forces[4].x);
    println!(
        "net force {:.1e} N, net torque {:.1e} N·m, −∂W/∂x4 = {fd:+.6e} N",
        net.norm(),
        torque.norm()
    );
    Ok(())
}

#[test]
fn forces_from_arrays() {
    main().unwrap();
}
