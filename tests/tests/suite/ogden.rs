//! The Ogden law (principal stretches, `LawKind::Stretch`): forces = −∇energy on
//! random states and exactly at repeated eigenvalues of C (rest, equibiaxial,
//! uniaxial), HEML = P1 to round-off, the tangent against finite differences of the
//! forces there, N = 1 / α = 2 against the isochoric neo-Hookean closed form, and the
//! uniaxial stress against the closed form with Treloar's parameters.
//!
//! The registry-wide property suites (forces.rs, fem_equivalence.rs, tangent.rs,
//! inversion.rs, optimised_paths.rs, rest_check.rs) cover Ogden with random
//! parameters as well; this file pins the states where eigenvalues coincide.

use heml::law::*;
use heml::nalgebra::Matrix3;
use heml::prelude::*;
use heml_tests::*;
use rand::Rng;

/// Treloar's rubber (Ogden 1972), in Pa, with a bulk modulus `kappa`.
fn treloar(kappa: f64) -> Box<dyn Material> {
    heml::material(
        "ogden",
        &Params::from([
            ("mu1", 0.63e6),
            ("alpha1", 1.3),
            ("mu2", 0.0012e6),
            ("alpha2", 5.0),
            ("mu3", -0.01e6),
            ("alpha3", -2.0),
            ("kappa", kappa),
        ]),
    )
    .unwrap()
}

/// The small-strain shear modulus of [`treloar`]: ½ Σ μ_p α_p.
const MU0: f64 = 0.5 * (0.63e6 * 1.3 + 0.0012e6 * 5.0 + 0.01e6 * 2.0);

#[test]
fn treloar_parameters_match_the_validation_case() {
    let from_case = heml_validation::ogden::params(&heml_validation::ogden::TRELOAR, 1e8);
    assert_eq!(
        heml::material("ogden", &from_case).unwrap().param_values(),
        treloar(1e8).param_values()
    );
    assert!((heml_validation::ogden::shear_modulus(&heml_validation::ogden::TRELOAR) - MU0).abs() < 1e-9 * MU0);
}

/// Affine states R·diag(d)·X whose C = diag(d)² has repeated eigenvalues exactly
/// (up to the round-off of the positions), rotated off the axes by R.
fn repeated_states(rng: &mut TestRng) -> Vec<(&'static str, Matrix3<f64>)> {
    let r = random_rotation(rng);
    [
        ("rest", [1.0, 1.0, 1.0]),
        ("rotated rest", [1.0, 1.0, 1.0]),
        ("dilated", [1.1, 1.1, 1.1]),
        ("equibiaxial", [1.2, 1.2, 0.7]),
        ("uniaxial tension", [1.5, 0.82, 0.82]),
        ("uniaxial compression", [0.6, 1.25, 1.25]),
    ]
    .into_iter()
    .map(|(name, d)| {
        let rot = if name == "rest" { Matrix3::identity() } else { r };
        (name, rot * Matrix3::from_diagonal(&Vec3::from(d)))
    })
    .collect()
}

fn deform(mesh: &TetMesh, f: &Matrix3<f64>) -> Vec<Vec3> {
    mesh.nodes().iter().map(|p| f * p).collect()
}

/// Forces against central differences of the energy, relative to max|f| or, at
/// rest (no force), to the stiffness scale μ0·h_mesh².
///
/// Tolerance: the central difference with h = 1e-6 (the mesh is ~1 m, stretches
/// O(1)) errs by h²/6·|W'''| ≈ 1e-13·MU0 (truncation) plus ε·|W|/h ≈ 2e-10·W
/// (round-off of the energy difference, W ≲ MU0·1 m³): both ≪ 1e-6·scale, while any
/// wrong term in the spectral gradient is O(1) relative.
fn check_fd(name: &str, field: &dyn ElasticForces, x: &[Vec3]) {
    let (e, f) = field.forces(x).unwrap();
    assert!(
        e.is_finite() && f.iter().all(|v| v.iter().all(|c| c.is_finite())),
        "{name}"
    );
    let g = fd_gradient(x, 1e-6, |y| field.energy(y).unwrap());
    let minus_g: Vec<Vec3> = g.iter().map(|v| -v).collect();
    let scale = max_norm(&f).max(1e-3 * MU0 * 0.1);
    let err = max_diff(&f, &minus_g);
    assert!(err <= 1e-6 * scale, "{name}: |f + ∇W| = {err:e}, scale {scale:e}");
}

#[test]
fn forces_are_minus_the_energy_gradient_at_repeated_and_random_stretches() {
    let mut rng = rng(17);
    let mesh = jittered_box(&mut rng, [2, 2, 2]);
    let law = treloar(50.0 * MU0);
    let opts = ForceOptions::default();
    let field = law.force_field(&mesh, None, &opts).unwrap();
    for (name, f) in repeated_states(&mut rng) {
        check_fd(name, field.as_ref(), &deform(&mesh, &f));
    }
    for k in 0..4 {
        let x = random_deformation(&mut rng, &mesh, 0.6, 1.6, 0.03);
        check_fd(&format!("random state {k}"), field.as_ref(), &x);
    }
    // inverted tets: the J0 extension is an energy too
    let mut x = random_deformation(&mut rng, &mesh, 0.8, 1.2, 0.02);
    invert_first_tet(&mesh, &mut x, 0.7);
    check_fd("inverted tet", field.as_ref(), &x);
}

#[test]
fn rest_is_stress_and_energy_free() {
    let mut rng = rng(3);
    let mesh = jittered_box(&mut rng, [2, 2, 2]);
    let law = treloar(50.0 * MU0);
    let opts = ForceOptions::default();
    for (name, f) in repeated_states(&mut rng).into_iter().take(2) {
        let x = deform(&mesh, &f);
        for field in [
            law.force_field(&mesh, None, &opts).unwrap(),
            law.fem_field(&mesh, None, &opts).unwrap().unwrap(),
        ] {
            let (e, forces) = field.forces(&x).unwrap();
            // round-off of terms of size MU0·(tet volume ~ 1/48 m³)/(edge ~ 0.4 m):
            // ~1e-16·MU0·0.05 per term, summed over ≤ 24 tets per node: 1e-12·MU0 is
            // a margin of ~1e3, while a prestress would be O(MU0·area)
            assert!(
                max_norm(&forces) <= 1e-12 * MU0,
                "{name}: |f| = {:e}",
                max_norm(&forces)
            );
            assert!(e.abs() <= 1e-12 * MU0, "{name}: energy {e:e}");
        }
    }
    let (w, p) = law.stress(&Matrix3::identity(), &opts).unwrap();
    assert!(w.abs() <= 1e-12 * MU0 && p.amax() <= 1e-12 * MU0, "w = {w}, P = {p}");
}

#[test]
fn heml_equals_p1_to_round_off_at_repeated_and_random_stretches() {
    let mut rng = rng(5);
    let mesh = jittered_box(&mut rng, [2, 2, 2]);
    let law = treloar(20.0 * MU0);
    let opts = ForceOptions::default();
    let heml = law.force_field(&mesh, None, &opts).unwrap();
    let fem = law.fem_field(&mesh, None, &opts).unwrap().unwrap();
    let mut states: Vec<(String, Vec<Vec3>)> = repeated_states(&mut rng)
        .into_iter()
        .skip(2) // at rest both are zero (tested above)
        .map(|(n, f)| (n.to_string(), deform(&mesh, &f)))
        .collect();
    for k in 0..6 {
        let mut x = random_deformation(&mut rng, &mesh, 0.6, 1.6, 0.03);
        if k == 5 {
            invert_first_tet(&mesh, &mut x, 0.5);
        }
        states.push((format!("random {k}"), x));
    }
    for (name, x) in states {
        let (eh, fh) = heml.forces(&x).unwrap();
        let (ef, ff) = fem.forces(&x).unwrap();
        // 1e-12 as in fem_equivalence.rs: the same closed form reached through C from
        // the edge lengths (HEML) or from F (P1), each through the same eigensolver
        // whose results agree to a few ulp; strains of ≥ a few percent amplify the
        // ~1e-16 operation error by at most ~1e3
        let scale = max_norm(&ff);
        assert!(
            max_diff(&fh, &ff) <= 1e-12 * scale,
            "{name}: HEML − P1 = {:e} of {scale:e}",
            max_diff(&fh, &ff)
        );
        assert!((eh - ef).abs() <= 1e-12 * ef.abs(), "{name}: {eh} vs {ef}");
    }
}

#[test]
fn tangent_is_the_derivative_of_the_forces_and_finite_at_repeated_stretches() {
    let mut rng = rng(9);
    let mesh = jittered_box(&mut rng, [2, 2, 1]);
    let law = treloar(20.0 * MU0);
    let opts = ForceOptions::default();
    let field = law.force_field(&mesh, None, &opts).unwrap();
    let mut k = law.tangent(&mesh, None, &opts, false).unwrap().unwrap();
    let mut states: Vec<(String, Vec<Vec3>)> = repeated_states(&mut rng)
        .into_iter()
        .map(|(n, f)| (n.to_string(), deform(&mesh, &f)))
        .collect();
    let mut x = random_deformation(&mut rng, &mesh, 0.7, 1.4, 0.03);
    states.push(("random".into(), x.clone()));
    invert_first_tet(&mesh, &mut x, 0.5);
    states.push(("inverted tet".into(), x));
    for (name, x) in states {
        k.update(&x).unwrap(); // errors on a non-finite stiffness
        let dx: Vec<Vec3> = (0..x.len())
            .map(|_| Vec3::from_fn(|_, _| rng.gen_range(-1.0..1.0)))
            .collect();
        let mut kdx = vec![Vec3::zeros(); x.len()];
        k.add_product(&dx, &mut kdx).unwrap();
        let h = 1e-6 / max_norm(&dx);
        let shifted = |s: f64| -> Vec<Vec3> { x.iter().zip(&dx).map(|(p, d)| p + d * s).collect() };
        let (_, fp) = field.forces(&shifted(h)).unwrap();
        let (_, fm) = field.forces(&shifted(-h)).unwrap();
        let fd: Vec<Vec3> = fp.iter().zip(&fm).map(|(a, b)| -(a - b) / (2.0 * h)).collect();
        // as tangent.rs: truncation h²·|f'''| and round-off ε|f|/h both ≲ 1e-9 of the
        // scale; 1e-6 leaves a margin of 1e3 and any wrong Daleckii–Krein term is O(1)
        let scale = max_norm(&kdx).max(MU0 * 1e-3);
        let err = max_diff(&kdx, &fd);
        assert!(err <= 1e-6 * scale, "{name}: |K dx − FD| = {err:e} of {scale:e}");
        for t in 0..k.tet_ids().len() {
            let m = k.tet_stiffness(t);
            assert!(
                (m - m.transpose()).amax() <= 1e-12 * m.amax(),
                "{name}: tet {t} not symmetric"
            );
        }
    }
}

/// Ogden with one term, α = 2, is the isochoric neo-Hookean law
/// w = μ/2·(Ī1 − 3) + κ/2·(ln J)², whose stress is
/// P = μJ^(−2/3)(F − I1/3·F⁻ᵀ) + κ ln J·F⁻ᵀ: checked on the law's stress and,
/// through a law declared with that energy, on the HEML mesh forces.
#[heml::material(name = "test_isochoric_neo_hookean")]
#[energy(mu / 2.0 * (I1bar - 3.0) + kappa / 2.0 * J.ln().powi(2))]
pub struct IsochoricNeoHookean {
    /// Shear modulus (Pa).
    pub mu: f64,
    /// Bulk modulus (Pa).
    pub kappa: f64,
}

#[test]
fn one_term_with_alpha_two_is_the_isochoric_neo_hookean_law() {
    let (mu, kappa) = (3e3, 2e4);
    let ogden = heml::material(
        "ogden",
        &Params::from([
            ("mu1", mu),
            ("alpha1", 2.0),
            ("mu2", 0.0),
            ("alpha2", 1.0),
            ("mu3", 0.0),
            ("alpha3", 1.0),
            ("kappa", kappa),
        ]),
    )
    .unwrap();
    let nh = heml::material(
        "test_isochoric_neo_hookean",
        &Params::from([("mu", mu), ("kappa", kappa)]),
    )
    .unwrap();
    let mut rng = rng(21);
    let opts = ForceOptions::default();
    for _ in 0..50 {
        let f = random_rotation(&mut rng)
            * (Matrix3::from_diagonal(&Vec3::from_fn(|_, _| rng.gen_range(0.6..1.5)))
                + Matrix3::from_fn(|i, j| if i < j { rng.gen_range(-0.3..0.3) } else { 0.0 }));
        let j = f.determinant();
        if j < 0.5 {
            continue; // below J0 both laws use their (different) extensions
        }
        let finv_t = f.try_inverse().unwrap().transpose();
        let i1 = (f.transpose() * f).trace();
        let want = (f - finv_t * (i1 / 3.0)) * (mu * j.powf(-2.0 / 3.0)) + finv_t * (kappa * j.ln());
        let w_want = mu / 2.0 * (i1 * j.powf(-2.0 / 3.0) - 3.0) + kappa / 2.0 * j.ln().powi(2);
        let (w, p) = ogden.stress(&f, &opts).unwrap();
        // the same closed form by two routes (eigenvalues vs trace): a few dozen ulp
        // of the largest stress term (κ·|ln J|·|F⁻ᵀ| ≲ 1e5 here)
        let scale = want.amax().max(mu);
        let err = (p - want).amax();
        assert!(err <= 1e-12 * scale, "J = {j}: |P − P_nh| = {err:e} of {scale:e}");
        assert!((w - w_want).abs() <= 1e-12 * w_want.abs().max(mu), "{w} vs {w_want}");
    }
    let mesh = jittered_box(&mut rng, [2, 2, 2]);
    for (name, f) in repeated_states(&mut rng).into_iter().skip(2) {
        let x = deform(&mesh, &f);
        let (_, fo) = ogden.force_field(&mesh, None, &opts).unwrap().forces(&x).unwrap();
        let (_, fn_) = nh.force_field(&mesh, None, &opts).unwrap().forces(&x).unwrap();
        assert!(
            max_diff(&fo, &fn_) <= 1e-12 * max_norm(&fn_),
            "{name}: {:e}",
            max_diff(&fo, &fn_)
        );
    }
}

#[test]
fn uniaxial_stress_matches_the_closed_form_with_treloar_parameters() {
    let terms = heml_validation::ogden::TRELOAR;
    let kappa = 100.0 * MU0;
    let law = treloar(kappa);
    let opts = ForceOptions::default();
    let rot = random_rotation(&mut rng(2));
    for lambda in [0.5, 0.8, 1.0, 1.5, 2.5, 4.0, 7.0] {
        let (t, p11) = heml_validation::ogden::uniaxial(&terms, kappa, lambda);
        // rotated: P rotates with the current frame, P' = R P
        let f = rot * Matrix3::from_diagonal(&Vec3::new(lambda, t, t));
        let p = rot.transpose() * law.stress(&f, &opts).unwrap().1;
        // the bisection ends at ~1e-16 in t, whose residual is ~κ·1e-16; the stress
        // is a sum of terms ≲ κ|ln J| + Σ|μ_p|λ^α_p: 1e-10 relative to that size is
        // well above round-off (~1e-14) and far below a wrong term
        let size = MU0 * lambda.powf(5.0).max(1.0) + kappa * 1e-3;
        assert!(
            (p[(0, 0)] - p11).abs() <= 1e-10 * size,
            "λ = {lambda}: P11 {} vs {p11}",
            p[(0, 0)]
        );
        assert!(
            p[(1, 1)].abs() <= 1e-10 * size && p[(2, 2)].abs() <= 1e-10 * size,
            "λ = {lambda}: {p}"
        );
        // nearly incompressible: close to the classical Σ μ_p(λ^(α_p−1) − λ^(−α_p/2−1));
        // the compressibility correction grows like (stress/κ): ≲ 1 % of it up to
        // λ = 4 with κ = 100 μ0 (at λ = 7 the α = 5 term's stress reaches ~10 μ0)
        if lambda > 4.0 {
            continue;
        }
        let incompressible: f64 = terms
            .iter()
            .map(|(mu, a)| mu * (lambda.powf(a - 1.0) - lambda.powf(-a / 2.0 - 1.0)))
            .sum();
        assert!(
            (p11 - incompressible).abs() <= 0.03 * incompressible.abs().max(1e-2 * MU0),
            "λ = {lambda}: {p11} vs incompressible {incompressible}"
        );
    }
}

#[test]
fn ogden_is_registered_with_its_parameters_and_small_strain_mapping() {
    let e = heml::find_material("ogden").unwrap();
    assert_eq!(e.kind, LawKind::Stretch);
    let names: Vec<_> = e.params.iter().map(|p| p.name).collect();
    assert_eq!(names, ["mu1", "alpha1", "mu2", "alpha2", "mu3", "alpha3", "kappa"]);
    assert!(e.params[4].signed && !e.params[6].signed);
    let err = heml::material("ogden", &Params::from([("mu1", 1.0)]))
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing parameter(s)") && err.contains("alpha1"), "{err}");
    let law = treloar(1e8);
    assert_eq!(law.kind(), LawKind::Stretch);
    assert_eq!(law.param_values()[5], -2.0);
}

/// The batch kernels' four-lane law is the plain one lane by lane, to the bit (the
/// plain and batched force paths of a tet then agree exactly): Treloar's three terms,
/// lanes at and below J0 (extended), stretched and compressed.
#[test]
fn lanes_equal_the_plain_law_bit_for_bit() {
    let law = heml::materials::Ogden {
        mu1: 0.63e6,
        alpha1: 1.3,
        mu2: 0.0012e6,
        alpha2: 5.0,
        mu3: -0.01e6,
        alpha3: -2.0,
        kappa: 2e8,
    };
    let e = [[1.0, 1.44, 0.3, 2.5], [1.0, 0.8, 0.3, 0.04], [1.0, 0.81, 1.7, 1.1]];
    let j = [1.0, 0.97, 0.2, -0.1];
    let ext = [None, None, Some(0.25), Some(0.25)];
    let d = law.dw_lanes(&e, &j, &ext);
    for l in 0..4 {
        let plain = law.dw([e[0][l], e[1][l], e[2][l]], j[l], ext[l]);
        assert!(
            plain.w.is_finite() && plain.de.iter().all(|x| x.is_finite()),
            "lane {l}"
        );
        assert_eq!(d[l], plain, "lane {l}");
        for (a, b) in [(d[l].w, plain.w), (d[l].dj, plain.dj)] {
            assert_eq!(a.to_bits(), b.to_bits(), "lane {l}");
        }
    }
}
