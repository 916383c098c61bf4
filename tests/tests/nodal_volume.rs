//! The anti-locking (nodal-J) volumetric formulation: forces are minus the energy
//! gradient for every invariant law, its tangent is the forces' derivative, the same
//! bits for any thread count, no spurious modes, bounded energy, and no locking.

use heml::law::{LawKind, Volumetric};
use heml::prelude::*;
use heml_tests::*;
use heml_validation::locking::{six_tet_beam, tip_ratio, Bar};

/// Every invariant law (sampled parameters) with the nodal volumetric term.
fn nodal_laws(rng: &mut TestRng) -> Vec<(&'static str, Box<dyn Material>)> {
    all_laws(rng)
        .into_iter()
        .filter(|(_, l)| l.kind() == LawKind::Invariant)
        .map(|(n, l)| (n, l.with_volumetric(Volumetric::nodal()).unwrap()))
        .collect()
}

#[test]
fn nodal_forces_are_minus_the_energy_gradient_for_every_invariant_law() {
    for seed in 0..4u64 {
        let mut rng = rng(seed);
        let mesh = jittered_box(&mut rng, [2, 2, 1]);
        let mut x = random_deformation(&mut rng, &mesh, 0.6, 1.6, 0.05);
        if seed % 2 == 1 {
            invert_first_tet(&mesh, &mut x, 0.5);
        }
        for (name, law) in nodal_laws(&mut rng) {
            let field = law.force_field(&mesh, None, &ForceOptions::default()).unwrap();
            let (e, f) = field.forces(&x).unwrap();
            if name == "gent" && !e.is_finite() {
                continue;
            }
            assert!(e.is_finite(), "{name}: energy {e}");
            let g = fd_gradient(&x, 1e-6, |y| field.energy(y).unwrap());
            let minus_g: Vec<Vec3> = g.iter().map(|v| -v).collect();
            let scale = max_norm(&f).max(1.0);
            let err = max_diff(&f, &minus_g);
            // as tests/forces.rs: h = 1e-6 central differences, 1e-6 of the largest force
            assert!(err <= 1e-6 * scale, "{name} seed {seed}: |f + ∇E| = {err:e} vs {scale:e}");
            // the P1 oracle of the same split agrees with the HEML kernels
            let fem = law.fem_field(&mesh, None, &ForceOptions::default()).unwrap().unwrap();
            let (ep, fp) = fem.forces(&x).unwrap();
            assert!((ep - e).abs() <= 1e-9 * e.abs().max(1.0), "{name}: energy {e} vs P1 {ep}");
            assert!(max_diff(&f, &fp) <= 1e-9 * scale, "{name}: forces vs P1");
        }
    }
}
