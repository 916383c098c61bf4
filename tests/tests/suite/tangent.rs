//! The exact tangent stiffness (`Material::tangent`, from the generated second
//! derivatives) against finite differences of the generated forces, for every
//! registered law, on random deformed meshes with inverted tets (J < J0 exercises the
//! Taylor extension); its symmetry, its rigid-body null space at rest, and the
//! positive semi-definite projection.

use heml::force::TangentOperator;
use heml::law::*;
use heml::prelude::*;
use heml_tests::*;
use proptest::prelude::*;
use rand::Rng;

fn tangent(law: &dyn Material, mesh: &TetMesh, x: &[Vec3], project: bool) -> Box<dyn TangentOperator> {
    let mut k = law
        .tangent(mesh, None, &ForceOptions::default(), project)
        .unwrap()
        .expect("every built-in law kind has a tangent");
    k.update(x).unwrap();
    k
}

fn product(k: &dyn TangentOperator, dx: &[Vec3]) -> Vec<Vec3> {
    let mut y = vec![Vec3::zeros(); dx.len()];
    k.add_product(dx, &mut y).unwrap();
    y
}

/// K·dx against −(f(x + h dx) − f(x − h dx))/(2h), and every tet's K symmetric.
///
/// Tolerance: the central difference errs by h²/6·|f'''| (truncation) plus
/// ~ε·|f|/h (round-off of the force difference). With h = 1e-6 relative to the size
/// of x and dx (both O(1) here) the round-off term is ~2e-10·|f| and the truncation
/// ~1e-13·|f'''|; exponential laws on deeply inverted tets have |f'''|/|f| up to ~1e4
/// (see forces.rs), still ≤ 1e-9. A bound of 1e-6 relative to the largest of |K dx|
/// and |f| keeps a margin of ≥ 1e3 over both, while any missing or wrong second-
/// derivative term shows up at O(1). Two kinds of sample break those estimates; they
/// get the fallbacks of [`fd_agrees`].
fn check_law(name: &str, law: &dyn Material, mesh: &TetMesh, x: &[Vec3], dx: &[Vec3]) {
    let field = law.force_field(mesh, None, &ForceOptions::default()).unwrap();
    let (e, f) = field.forces(x).unwrap();
    if beyond_the_law(name, e, &f) {
        return;
    }
    let k = tangent(law, mesh, x, false);
    let kdx = product(k.as_ref(), dx);
    let size = max_norm(x).max(1.0);
    let h = 1e-6 * size / max_norm(dx);
    let forces_at = |s: f64| -> Vec<Vec3> {
        let shifted: Vec<Vec3> = x.iter().zip(dx).map(|(p, d)| p + d * s).collect();
        field.forces(&shifted).unwrap().1
    };
    let scale = max_norm(&kdx).max(max_norm(&f) / size).max(1e-12);
    let shifted = [forces_at(-2.0 * h), forces_at(-h), forces_at(h), forces_at(2.0 * h)];
    if let Err(msg) = fd_agrees(&kdx, &f, &shifted, h, scale) {
        panic!("{name}: {msg}");
    }
    for t in 0..k.tet_ids().len() {
        let m = k.tet_stiffness(t);
        let asym = (m - m.transpose()).amax();
        // each entry is a sum of O(50) products of size ≤ max|K|: round-off ~1e-14; the
        // principal-stretch laws build K from eigenvectors, whose round-off grows like
        // 1/gap between nearly coincident eigenvalues (an Ogden tet on a random inverted
        // case showed 2e-10): 1e-9 still catches any missing or transposed term (O(1)).
        assert!(
            asym <= 1e-9 * m.amax(),
            "{name}: tet {t} asymmetry {asym:e} of {:e}",
            m.amax()
        );
    }
}

fn random_dx(rng: &mut TestRng, n: usize) -> Vec<Vec3> {
    (0..n).map(|_| Vec3::from_fn(|_, _| rng.gen_range(-1.0..1.0))).collect()
}

proptest! {
    #![proptest_config(proptest_config(16))]

    #[test]
    fn hessian_vector_product_is_the_derivative_of_the_forces(seed in any::<u64>(), depth in 0.1f64..1.5, invert in any::<bool>()) {
        let mut rng = rng(seed);
        let mesh = if seed.is_multiple_of(3) { random_tet(&mut rng) } else { jittered_box(&mut rng, [2, 1, 1]) };
        let mut x = random_deformation(&mut rng, &mesh, 0.6, 1.6, 0.05);
        if invert {
            invert_first_tet(&mesh, &mut x, depth);
        }
        let dx = random_dx(&mut rng, mesh.n_nodes());
        for (name, law) in all_laws_on(&mesh, &mut rng) {
            check_law(name, law.as_ref(), &mesh, &x, &dx);
        }
    }
}

/// Tets compressed to J in (0, J0) and inverted (J < 0): both sides of the extension
/// threshold, for every law, with the tet's J checked.
#[test]
fn hessian_is_exact_below_j0_and_for_inverted_tets() {
    let mut rng = rng(11);
    for depth in [-0.3, -0.1, 0.2, 1.0] {
        // the node keeps a fraction −depth of its height over the opposite face: J ≈ −depth·J_before
        let mesh = random_tet(&mut rng);
        let mut x = random_deformation(&mut rng, &mesh, 0.9, 1.1, 0.01);
        invert_first_tet(&mesh, &mut x, depth);
        let vol = |p: &[Vec3]| (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) / 6.0;
        let j = vol(&x) / vol(mesh.nodes());
        assert!(j < 0.4, "J = {j} should be below J0 = 0.4");
        let dx = random_dx(&mut rng, mesh.n_nodes());
        for (name, law) in all_laws_on(&mesh, &mut rng) {
            check_law(name, law.as_ref(), &mesh, &x, &dx);
        }
    }
}

/// At rest (stress-free) K annihilates the six rigid-body modes: translations and
/// infinitesimal rotations ω × X. Bound: K's entries are O(max|K|) and the modes O(1)
/// (mesh of size ~1), so exact cancellation leaves ~1e-14·max|K|; 1e-10 is ample.
#[test]
fn stiffness_at_rest_has_the_rigid_body_null_modes() {
    let mut rng = rng(5);
    let mesh = jittered_box(&mut rng, [2, 2, 2]);
    let x = mesh.nodes().to_vec();
    for (name, law) in all_laws_on(&mesh, &mut rng) {
        for project in [false, true] {
            let k = tangent(law.as_ref(), &mesh, &x, project);
            let kmax = (0..k.tet_ids().len())
                .map(|t| k.tet_stiffness(t).amax())
                .fold(0.0, f64::max);
            assert!(kmax > 0.0, "{name}: zero stiffness at rest");
            let mut modes: Vec<Vec<Vec3>> = (0..3)
                .map(|a| vec![Vec3::from_fn(|i, _| f64::from(u8::from(i == a))); x.len()])
                .collect();
            for a in 0..3 {
                let w = Vec3::from_fn(|i, _| f64::from(u8::from(i == a)));
                modes.push(x.iter().map(|p| w.cross(p)).collect());
            }
            for (m, mode) in modes.iter().enumerate() {
                let r = max_norm(&product(k.as_ref(), mode));
                assert!(
                    r <= 1e-10 * kmax,
                    "{name} (projected: {project}): |K r_{m}| = {r:e}, max|K| = {kmax:e}"
                );
            }
        }
    }
}

/// The projected stiffness is positive semi-definite and equals the exact one where
/// that already is (at rest); deformed and inverted tets get a genuinely different,
/// semi-definite matrix. Bound on eigenvalues: the eigen-decomposition is backward
/// stable, so the reconstructed matrix has eigenvalues ≥ −1e-12·max|K|.
#[test]
fn projection_is_positive_semi_definite() {
    let mut rng = rng(9);
    let mesh = jittered_box(&mut rng, [2, 1, 1]);
    let mut x = random_deformation(&mut rng, &mesh, 0.6, 1.6, 0.05);
    invert_first_tet(&mesh, &mut x, 0.5);
    let mut changed_laws = 0;
    for (name, law) in all_laws_on(&mesh, &mut rng) {
        if name == "gent" {
            continue; // may be beyond its locking stretch in the inverted tet
        }
        let exact = tangent(law.as_ref(), &mesh, &x, false);
        let proj = tangent(law.as_ref(), &mesh, &x, true);
        let mut changed = false;
        for t in 0..exact.tet_ids().len() {
            let p = proj.tet_stiffness(t);
            let kmax = exact.tet_stiffness(t).amax();
            let min_eig = p.symmetric_eigenvalues().min();
            assert!(min_eig >= -1e-12 * kmax, "{name}: tet {t} eigenvalue {min_eig:e}");
            let exact_min = exact.tet_stiffness(t).symmetric_eigenvalues().min();
            if exact_min < -1e-9 * kmax {
                changed = true;
                assert!((p - exact.tet_stiffness(t)).amax() > 1e-9 * kmax);
            } else {
                assert!(
                    (p - exact.tet_stiffness(t)).amax() <= 1e-10 * kmax,
                    "{name}: tet {t} changed"
                );
            }
        }
        changed_laws += usize::from(changed);
    }
    // an inverted tet makes the exact stiffness indefinite for the laws in general
    assert!(
        changed_laws > 0,
        "no law had an indefinite stiffness on the inverted tet"
    );
    let rest = mesh.nodes().to_vec();
    for (name, law) in all_laws_on(&mesh, &mut rng) {
        let exact = tangent(law.as_ref(), &mesh, &rest, false);
        let proj = tangent(law.as_ref(), &mesh, &rest, true);
        for t in 0..exact.tet_ids().len() {
            let d = (proj.tet_stiffness(t) - exact.tet_stiffness(t)).amax();
            assert!(
                d <= 1e-10 * exact.tet_stiffness(t).amax(),
                "{name}: rest tet {t} projected away by {d:e}"
            );
        }
    }
}

/// The projection of every registered law (invariant laws: the closed-form
/// eigensystem of the isotropic energy; link laws: the 9×9 eigen-decomposition) on
/// random deformed meshes with an inverted tet: semi-definite, equal to the
/// eigen-projection [`project_psd`] of the exact stiffness where that is already
/// semi-definite, and above the exact stiffness (projected − exact semi-definite:
/// only negative curvature is removed, K₊ − K = |K₋|).
///
/// Bounds: the closed-form modes are orthonormal to round-off, so the reconstructed
/// matrices carry errors ~1e-14·max|K| per entry; 1e-10 relative (as in the
/// existing projection test) is a wide margin that an error in an eigenvalue
/// formula (an O(1) relative change of some entries) cannot meet.
#[test]
fn analytic_projection_matches_the_eigen_projection() {
    use heml::force::tangent::project_psd;
    let mut rng = rng(21);
    let (mut indefinite, mut definite) = (0, 0);
    for case in 0..6 {
        let mesh = jittered_box(&mut rng, [2, 1, 1]);
        let mut x = random_deformation(&mut rng, &mesh, 0.6, 1.6, 0.05);
        invert_first_tet(&mesh, &mut x, 0.2 + 0.2 * case as f64);
        for (name, law) in all_laws_on(&mesh, &mut rng) {
            let exact = tangent(law.as_ref(), &mesh, &x, false);
            let proj = tangent(law.as_ref(), &mesh, &x, true);
            for t in 0..exact.tet_ids().len() {
                let (k, p) = (exact.tet_stiffness(t), proj.tet_stiffness(t));
                if !k.iter().all(|c| c.is_finite()) {
                    continue; // Gent beyond its locking stretch: no energy there
                }
                let kmax = k.amax();
                let min = p.symmetric_eigenvalues().min();
                assert!(min >= -1e-10 * kmax, "{name}: tet {t} eigenvalue {min:e} of {kmax:e}");
                let gap = (p - k).symmetric_eigenvalues().min();
                assert!(
                    gap >= -1e-10 * kmax,
                    "{name}: tet {t}: projected − exact eigenvalue {gap:e}"
                );
                if k.symmetric_eigenvalues().min() >= -1e-12 * kmax {
                    definite += 1;
                    let d = (p - project_psd(&k)).amax();
                    assert!(d <= 1e-10 * kmax, "{name}: semi-definite tet {t} changed by {d:e}");
                } else {
                    indefinite += 1;
                }
            }
        }
    }
    assert!(
        indefinite > 10 && definite > 10,
        "{indefinite} indefinite, {definite} definite tets"
    );
}
