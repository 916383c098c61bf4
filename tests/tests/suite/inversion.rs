//! The J0 extension (DESIGN §1): below J0 each law is replaced by its second-order
//! Taylor polynomial in J, built symbolically. It must join the law with matching
//! value, gradient (including ∂/∂I1, ∂/∂I2, which involve third derivatives of w) and
//! ∂²/∂J², and stay finite for J <= 0.

use heml::law::*;
use heml::nalgebra::Matrix3;
use heml::prelude::*;
use heml_tests::*;

/// Value, gradient and Hessian of the extension equal the law's at J = J0.
/// Bound: both evaluate the same closed forms at the same point; the extension adds
/// terms multiplied by (J − J0) = 0 exactly, so only re-association round-off
/// (~1e-15 relative) remains.
fn check_join<M: InvariantLaw>(law: M) {
    assert!(M::INVERSION_FIX, "{} should use the extension", M::NAME);
    for (i1, i2) in [(3.0, 3.0), (3.7, 4.1), (5.0, 7.5)] {
        for j0 in [0.2, 0.4, 0.7] {
            let a = law.dw(i1, i2, j0);
            let b = law.dw_ext(i1, i2, j0, j0);
            let close = |x: f64, y: f64| (x - y).abs() <= 1e-13 * (1.0 + x.abs());
            assert!(close(a.w, b.w), "{}: w {} vs {}", M::NAME, a.w, b.w);
            for k in 0..3 {
                assert!(close(a.d[k], b.d[k]), "{}: d[{k}] {} vs {}", M::NAME, a.d[k], b.d[k]);
            }
            let (ha, hb) = (law.d2w(i1, i2, j0), law.d2w_ext(i1, i2, j0, j0));
            assert!(
                close(ha[2][2], hb[2][2]),
                "{}: wJJ {} vs {}",
                M::NAME,
                ha[2][2],
                hb[2][2]
            );
            assert!(close(law.w_ext(i1, i2, j0, j0), a.w));
        }
    }
}

#[test]
fn extension_joins_the_law_at_j0() {
    check_join(NeoHookean { mu: 1.3, lambda: 4.0 });
    check_join(MooneyRivlin {
        c10: 0.7,
        c01: 0.2,
        kappa: 5.0,
    });
    check_join(FungDemiray {
        a: 1.0,
        b: 0.8,
        kappa: 5.0,
    });
    check_join(Gent {
        mu: 1.0,
        jm: 50.0,
        kappa: 5.0,
    });
    check_join(ArrudaBoyce {
        mu: 1.0,
        lm: 3.0,
        kappa: 5.0,
    });
    check_join(VerondaWestmann {
        c1: 1.0,
        c2: 0.5,
        kappa: 5.0,
    });
    check_join(Yeoh {
        c1: 1.0,
        c2: -0.1,
        c3: 0.05,
        kappa: 5.0,
    });
    check_join(TestQuartic {
        c1: 1.0,
        c2: 0.3,
        c3: 0.1,
        kappa: 3.0,
    });
}

// Stable neo-Hookean opts out (finite for J <= 0); SVK does not use J at all.
const _: () = assert!(!StableNeoHookean::INVERSION_FIX && !SaintVenantKirchhoff::INVERSION_FIX);

/// Every law gives finite energy and stress through flat (J = 0) and inverted
/// elements, and the energy and stress are continuous across J0 (steps of 1e-8
/// change them by O(1e-8), not O(1)).
#[test]
fn every_law_is_finite_through_inversion_and_continuous_at_j0() {
    let mut rng = rng(3);
    let opts = ForceOptions::default();
    for entry in heml::materials_list() {
        let law = entry.instantiate(&sample_params(entry, &mut rng)).unwrap();
        let Some(_) = law.stress(&Matrix3::identity(), &opts) else {
            continue;
        };
        let at = |jz: f64| {
            law.stress(&Matrix3::from_diagonal(&Vec3::new(1.05, 0.95, jz)), &opts)
                .unwrap()
        };
        for jz in [0.3, 0.1, 0.0, -0.2, -1.0] {
            let (w, p) = at(jz);
            assert!(
                w.is_finite() && p.iter().all(|v| v.is_finite()),
                "{}: J = {jz}: w = {w}, P = {p}",
                entry.name
            );
        }
        let jz0 = opts.j0 / (1.05 * 0.95);
        let (wa, pa) = at(jz0 - 1e-8);
        let (wb, pb) = at(jz0 + 1e-8);
        let scale = pa.norm().max(1.0);
        assert!(
            (wa - wb).abs() <= 1e-6 * scale,
            "{}: energy jumps at J0 by {:e}",
            entry.name,
            (wa - wb).abs()
        );
        assert!(
            (pa - pb).norm() <= 1e-6 * scale,
            "{}: stress jumps at J0 by {:e}",
            entry.name,
            (pa - pb).norm()
        );
    }
}

#[test]
fn mesh_forces_stay_finite_for_flat_and_inverted_tets() {
    let mut rng = rng(5);
    let mesh = random_tet(&mut rng);
    for depth in [0.0, 0.5, 2.0] {
        let mut x = mesh.nodes().to_vec();
        invert_first_tet(&mesh, &mut x, depth);
        for entry in heml::materials_list() {
            let law = fibred(
                entry.instantiate(&sample_params(entry, &mut rng)).unwrap(),
                &mesh,
                &mut rng,
            );
            let (e, f) = law
                .force_field(&mesh, None, &ForceOptions::default())
                .unwrap()
                .forces(&x)
                .unwrap();
            assert!(
                e.is_finite() && f.iter().all(|v| v.iter().all(|c| c.is_finite())),
                "{} at depth {depth}",
                entry.name
            );
        }
    }
}
