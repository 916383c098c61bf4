//! The mass–spring law is the degenerate HEML case: its link forces are the
//! classical spring forces k(|v| − L)·v/|v|, one spring per tet edge.

use heml::prelude::*;
use heml_tests::*;

#[test]
fn mass_spring_reproduces_classical_spring_forces() {
    let mut rng = rng(11);
    let k = 3.7;
    let law = heml::material("mass_spring", &Params::from([("k", k)])).unwrap();
    for _ in 0..20 {
        let mesh = jittered_box(&mut rng, [2, 1, 1]);
        let x = random_deformation(&mut rng, &mesh, 0.5, 1.8, 0.1);
        let (energy, f) = law
            .force_field(&mesh, None, &ForceOptions::default())
            .unwrap()
            .forces(&x)
            .unwrap();
        let mut expected = vec![Vec3::zeros(); mesh.n_nodes()];
        let mut expected_energy = 0.0;
        for tet in mesh.tets() {
            for (a, b) in heml::rest::EDGES {
                let (p, q) = (tet[a] as usize, tet[b] as usize);
                let rest = (mesh.nodes()[q] - mesh.nodes()[p]).norm();
                let v = x[q] - x[p];
                let spring = v * (k * (v.norm() - rest) / v.norm());
                expected[p] += spring;
                expected[q] -= spring;
                expected_energy += 0.5 * k * (v.norm() - rest).powi(2);
            }
        }
        // Same formula up to rearrangement (√l·√l vs |v|²): a few ulps of the largest force.
        let scale = max_norm(&expected);
        assert!(
            max_diff(&f, &expected) <= 1e-13 * scale,
            "difference {:e}",
            max_diff(&f, &expected)
        );
        assert!((energy - expected_energy).abs() <= 1e-13 * expected_energy);
    }
}
