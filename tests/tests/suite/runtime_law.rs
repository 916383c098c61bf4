//! Laws declared at run time (`RuntimeLaw::from_energy`) against the compiled laws
//! with the same energy text, on every evaluation path, and their errors.

use heml::force::{Assembly, HemlField, P1Field, TangentField, TangentOperator};
use heml::law::{InvariantLaw, Material, MaterialInfo, Volumetric};
use heml::materials::*;
use heml::nalgebra::Matrix3;
use heml::prelude::*;
use heml::RuntimeLaw;
use heml_tests::*;
use rand::Rng;

/// `n` independent random tets (four nodes each), rest and current positions:
/// random rest shapes, each deformed by its own random F (stretches 0.6–1.6,
/// shear, rotation), a fifth of them inverted through a face and a tenth squashed
/// into 0 < J < J0, where the inversion extension takes over.
fn random_tets(rng: &mut TestRng, n: usize) -> (TetMesh, Vec<Vec3>) {
    let (mut nodes, mut x, mut tets) = (Vec::new(), Vec::new(), Vec::new());
    for t in 0..n {
        let rest = random_tet(rng);
        let stretch = Matrix3::from_diagonal(&Vec3::from_fn(|_, _| rng.gen_range(0.6..1.6)));
        let shear = Matrix3::from_fn(|i, j| if i < j { rng.gen_range(-0.3..0.3) } else { 0.0 });
        let mut f = random_rotation(rng) * (stretch + shear);
        match rng.gen_range(0..10) {
            0 | 1 => f.set_column(0, &(-f.column(0))),
            2 => f.set_column(0, &(f.column(0) * rng.gen_range(0.05..0.35))),
            _ => {}
        }
        for p in rest.nodes() {
            nodes.push(*p);
            x.push(f * p + Vec3::from_fn(|_, _| rng.gen_range(-0.01..0.01)));
        }
        tets.push([4 * t, 4 * t + 1, 4 * t + 2, 4 * t + 3]);
    }
    (TetMesh::new(nodes, tets).unwrap(), x)
}

/// The compiled law `M` with registry parameters, and the runtime law of its
/// declared energy text with the same parameters (and inversion fix). The compiled
/// law is built through the registry, so its fields are the ones heml-materials
/// compiled (`Invariant<M>` builds `HemlField<M>`, `P1Field<M>` and
/// `TangentField::invariant` of `M`, the typed paths): instantiating them again in
/// this test binary cost about a minute of CI's release build.
fn pair<M: InvariantLaw>(rng: &mut TestRng) -> (Box<dyn Material>, RuntimeLaw) {
    let entry = heml::find_material(M::NAME).unwrap();
    let params = sample_params(entry, rng);
    let runtime = RuntimeLaw::with_inversion_fix(M::ENERGY, &params, M::INVERSION_FIX).unwrap();
    (entry.instantiate(&params).unwrap(), runtime)
}

/// Largest per-tet difference of `a` and `b` (four nodes per tet), relative to the
/// tet's largest force (at least 1e-300, so all-zero tets compare absolutely).
fn max_tet_relative(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.chunks(4)
        .zip(b.chunks(4))
        .map(|(a, b)| {
            let scale = a.iter().map(|v| v.norm()).fold(1e-300, f64::max);
            a.iter().zip(b).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max) / scale
        })
        .fold(0.0, f64::max)
}

/// Tolerance: the tape evaluates the graph the macro generates code from, with the
/// same functions on the same operands in the same order (fast kernels included),
/// so the forces agree to the bit in practice; 1e-13 relative per tet is the
/// issue's bound, leaving room for a compiler reassociating a product of the
/// generated code (one rounding, ~1e-16 relative, amplified by at most the ~100
/// terms of a tet's force).
const TOL: f64 = 1e-13;

fn check_equal<M: InvariantLaw>(seed: u64) {
    let mut rng = rng(seed);
    let (mesh, x) = random_tets(&mut rng, 10_000);
    let (compiled, runtime) = pair::<M>(&mut rng);
    // the adaptive step probes laws without the inversion fix at inverted states:
    // the runtime law says what it was built with (it answered true for all)
    assert_eq!(
        Material::inversion_fix(&runtime),
        compiled.inversion_fix(),
        "{}",
        M::NAME
    );
    let opts = ForceOptions::default();
    for assembly in [Assembly::Parallel, Assembly::Batched, Assembly::Reference] {
        let mut c = compiled.force_field(&mesh, None, &opts).unwrap();
        let mut r = HemlField::new(runtime, &mesh, opts).unwrap();
        c.set_assembly(assembly);
        r.set_assembly(assembly);
        let ((ec, fc), (er, fr)) = (c.forces(&x).unwrap(), r.forces(&x).unwrap());
        assert!(fc.iter().all(|f| f.iter().all(|v| v.is_finite())), "{}", M::NAME);
        let err = max_tet_relative(&fc, &fr);
        assert!(err <= TOL, "{} ({assembly:?}): forces differ by {err:e}", M::NAME);
        assert!((ec - er).abs() <= TOL * ec.abs(), "{}: energy {ec} vs {er}", M::NAME);
    }
    // the P1 FEM path and the tangent (second derivatives)
    let (_, fc) = compiled
        .fem_field(&mesh, None, &opts)
        .unwrap()
        .unwrap()
        .forces(&x)
        .unwrap();
    let (_, fr) = P1Field::on_tets(runtime, &mesh, None, opts)
        .unwrap()
        .forces(&x)
        .unwrap();
    let err = max_tet_relative(&fc, &fr);
    assert!(err <= TOL, "{} (P1): forces differ by {err:e}", M::NAME);
    let tets: Vec<usize> = (0..500).collect();
    let mut kc = compiled.tangent(&mesh, Some(&tets), &opts, false).unwrap().unwrap();
    let mut kr = TangentField::invariant(runtime, &mesh, Some(&tets), opts, false).unwrap();
    kc.update(&x).unwrap();
    kr.update(&x).unwrap();
    for k in 0..tets.len() {
        let (a, b) = (kc.tet_stiffness(k), kr.tet_stiffness(k));
        let err = (a - b).amax() / a.amax().max(1e-300);
        assert!(err <= TOL, "{} (tangent, tet {k}): differs by {err:e}", M::NAME);
    }
}

#[test]
fn runtime_neo_hookean_equals_the_compiled_law() {
    check_equal::<NeoHookean>(1);
}

#[test]
fn runtime_mooney_rivlin_equals_the_compiled_law() {
    // Ī1, Ī2 (powers in thirds: cube roots in the fast kernels), J0-extended
    check_equal::<MooneyRivlin>(2);
}

#[test]
fn runtime_gent_equals_the_compiled_law() {
    // Ī1 inside ln, J0-extended: the extension's I1 derivatives are third derivatives
    check_equal::<Gent>(3);
}

#[test]
fn runtime_laws_with_i2_blocks_exp_and_no_inversion_fix_equal_the_compiled_laws() {
    check_equal::<TestQuartic>(4); // `let` blocks, Ī1·Ī2
    check_equal::<VerondaWestmann>(5); // exp, Ī2
    check_equal::<SaintVenantKirchhoff>(6); // I2, no inversion fix
    check_equal::<StableNeoHookean>(7); // no inversion fix
}

/// Through the `Material` interface (scenes, Python, the CLI) a runtime law whose
/// energy has no I2 runs the kernels with their I2 terms off, as the compiled law
/// does, and one with I2 runs them on: the HEML and P1 forces still equal the
/// compiled law's (tolerance: [`TOL`]).
fn check_equal_as_material<M: InvariantLaw>(seed: u64) {
    let mut rng = rng(seed);
    let (mesh, x) = random_tets(&mut rng, 2_000);
    let (compiled, runtime) = pair::<M>(&mut rng);
    let opts = ForceOptions::default();
    let (c, r): (&dyn Material, &dyn Material) = (compiled.as_ref(), &runtime);
    let (_, fc) = c.force_field(&mesh, None, &opts).unwrap().forces(&x).unwrap();
    let (_, fr) = r.force_field(&mesh, None, &opts).unwrap().forces(&x).unwrap();
    let err = max_tet_relative(&fc, &fr);
    assert!(err <= TOL, "{} (as a Material): forces differ by {err:e}", M::NAME);
    let p1 = |m: &dyn Material| m.fem_field(&mesh, None, &opts).unwrap().unwrap().forces(&x).unwrap().1;
    let err = max_tet_relative(&p1(c), &p1(r));
    assert!(err <= TOL, "{} (P1, as a Material): forces differ by {err:e}", M::NAME);
}

#[test]
fn runtime_laws_as_materials_equal_the_compiled_laws() {
    assert!(
        !RuntimeLaw::from_energy(NeoHookean::ENERGY, &Params::from([("mu", 1.0), ("lambda", 1.0)]))
            .unwrap()
            .uses()
            .0
    );
    check_equal_as_material::<NeoHookean>(8); // without I2
    check_equal_as_material::<FungDemiray>(9); // without I2, exp
    check_equal_as_material::<MooneyRivlin>(10); // with I2
}

/// The runtime law through the checks every registered law gets: forces are minus
/// the energy gradient (inverted tet included), rest is energy- and force-free,
/// and the HEML field equals the P1 FEM field.
#[test]
fn runtime_law_passes_the_property_checks() {
    let mut rng = rng(11);
    let law = RuntimeLaw::from_energy(
        "c1*(I1bar - 3) + c2*(I1bar - 3).powi(2) + kappa/2*(J - 1 - ln(J))",
        &Params::from([("c1", 0.7), ("c2", 0.3), ("kappa", 5.0)]),
    )
    .unwrap();
    let mesh = jittered_box(&mut rng, [2, 2, 1]);
    let opts = ForceOptions::default();
    let field = law.force_field(&mesh, None, &opts).unwrap();
    let p1 = law.fem_field(&mesh, None, &opts).unwrap().unwrap();
    // rest, and rigidly moved: no energy, no force (round-off of O(1) terms: 1e-12)
    let r = random_rotation(&mut rng);
    let rigid: Vec<Vec3> = mesh.nodes().iter().map(|p| r * p + Vec3::new(1.0, 2.0, 3.0)).collect();
    for x in [mesh.nodes(), &rigid[..]] {
        let (e, f) = field.forces(x).unwrap();
        assert!(
            e.abs() < 1e-12 && max_norm(&f) < 1e-12,
            "rest: energy {e:e}, force {:e}",
            max_norm(&f)
        );
    }
    let mut x = random_deformation(&mut rng, &mesh, 0.7, 1.4, 0.05);
    for inverted in [false, true] {
        if inverted {
            invert_first_tet(&mesh, &mut x, 0.4);
        }
        let (e, f) = field.forces(&x).unwrap();
        assert!(e.is_finite());
        // finite differences: h = 1e-6 on a mesh of size ~1, truncation h²|E'''| and
        // round-off ε|E|/h ≈ 2e-10|E|: 1e-6 relative to the largest force (as the
        // registry laws' check)
        let g = fd_gradient(&x, 1e-6, |y| field.energy(y).unwrap());
        let minus_g: Vec<Vec3> = g.iter().map(|v| -v).collect();
        let scale = max_norm(&f).max(1.0);
        assert!(
            max_diff(&f, &minus_g) <= 1e-6 * scale,
            "inverted {inverted}: |f + ∇E| too large"
        );
        // HEML = P1 (same energy, two formulations): round-off of sums of O(10)
        // terms, 1e-10 relative to the largest force
        let (ep, fp) = p1.forces(&x).unwrap();
        assert!(
            max_diff(&f, &fp) <= 1e-10 * scale,
            "HEML vs P1: {:e}",
            max_diff(&f, &fp)
        );
        assert!((e - ep).abs() <= 1e-10 * e.abs().max(1.0));
    }
}

/// The error message of `energy` over the parameters mu, lambda.
fn error(energy: &str) -> String {
    let params = Params::from([("mu", 1.0), ("lambda", 2.0)]);
    RuntimeLaw::from_energy(energy, &params).unwrap_err().to_string()
}

#[test]
fn bad_energies_are_clear_errors_with_a_column() {
    let e = error("mu/2*(I1-3) - mu*ln(J) + lamda/2*ln(J).powi(2)");
    assert!(
        e.contains("column 26: unknown identifier `lamda`") && e.contains("did you mean `lambda`"),
        "{e}"
    );
    assert!(
        e.contains("\n    mu/2*(I1-3) - mu*ln(J) + lamda/2*ln(J).powi(2)\n"),
        "{e}"
    );
    assert!(e.contains(&format!("\n    {}^^^^^", " ".repeat(25))), "{e}");
    let e = error("mu*(I1-3) + lambda*ln(J)^2");
    assert!(e.contains("column 25: unsupported operator"), "{e}");
    let e = error("mu*(I1-3) + lambda*(ln(J)");
    assert!(e.contains("column 20"), "{e}");
    let e = error("mu*(I1-3) + lambda*ln(J, I1)");
    assert!(
        e.contains("column 20: `ln` takes 1 argument(s): `ln(x)` or `x.ln()`"),
        "{e}"
    );
    let e = error("mu*(I1-3) + lambda*J.powi(2.5)");
    assert!(
        e.contains("column 27: the exponent of `powi` must be an integer literal"),
        "{e}"
    );
    let e = error("mu*(I1-3) + lambda*");
    assert!(e.contains("column 20: unexpected end of input"), "{e}");
    let e = error("mu*(I1-3)");
    assert!(e.contains("parameter(s) 'lambda' given but not used"), "{e}");
    let e = error("");
    assert!(e.contains("column 1"), "{e}");
    // fibre invariants need per-tet directions, which a runtime law cannot take yet:
    // refused, pointing at the word (not silently read as another variable)
    let e = error("mu*(I1-3) + lambda*(I4_2-1)*(J-1)");
    assert!(
        e.contains("column 21: fibre invariants (I4, I5) are not available"),
        "{e}"
    );
    let e = RuntimeLaw::from_energy("mu*(I1-3)", &Params::from([("mu", f64::NAN)]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("parameter 'mu' is NaN, not a finite number"), "{e}");
    // a long text is quoted cut, and shown around the column: the message stays
    // short however long the text (a hostile one may have 64k characters)
    let long = format!("mu*(I1-3) + lambda*(J-1)^2{}", " + 0*I1".repeat(2000));
    let e = error(&long);
    assert!(e.contains("column 25: unsupported operator"), "{e}");
    assert!(e.contains("…\" (14026 characters)") && e.len() < 600, "{e}");
}

#[test]
fn laws_differing_only_in_values_share_their_compiled_form() {
    let a = RuntimeLaw::from_energy("mu*(I1-3)", &Params::from([("mu", 1.0)])).unwrap();
    let b = RuntimeLaw::from_energy("mu*(I1-3)", &Params::from([("mu", 2.0)])).unwrap();
    assert!(std::ptr::eq(a.energy(), b.energy()));
    assert_eq!((a.dw(4.0, 3.0, 1.0).d[0], b.dw(4.0, 3.0, 1.0).d[0]), (1.0, 2.0));
    assert_eq!(a.param_info()[0].name, "mu");
    assert_eq!(<RuntimeLaw as MaterialInfo>::to_params(&b), vec![2.0]);
}

const SCENE: &str = r#"
[mesh]
generate = { kind = "box", size = [0.02, 0.02, 0.02], cells = [2, 2, 2] }

[[material]]
MATERIAL
params = { mu = 1.0e3, lambda = 4.0e3 }

[[fix]]
box = { min = [0, 0, 0], max = [0, 0.02, 0.02] }

[loads]
gravity = [0, 0, -9.81]

[solver]
duration = 0.01

[output]
vtu = false
csv = false
"#;

/// A scene's `energy = "..."` material steps exactly as the registered law with
/// the same energy, also with the patch term and a `volumetric_energy`; bad
/// materials are errors naming the material and the column.
#[test]
fn scenes_accept_an_energy_in_place_of_a_law() {
    let _ = heml::materials_list();
    let run = |material: &str| {
        let text = SCENE.replace("MATERIAL", material);
        let mut sim = heml::scene::Scene::from_toml_str(&text, ".").unwrap().build().unwrap();
        sim.run(|_| {}).unwrap();
        sim.system.positions().to_vec()
    };
    let compiled = run("law = \"neo_hookean\"");
    let runtime = run(&format!("energy = \"{}\"", NeoHookean::ENERGY));
    let rest = heml::mesh::generate::box_mesh([0.02; 3], [2; 3], heml::mesh::generate::HexSplit::Six).unwrap();
    let moved = max_diff(&compiled, rest.nodes());
    assert!(moved > 1e-6, "gravity should move the body: {moved:e}");
    // the same forces to the bit give the same trajectory; 1e-12 of the motion
    // would still allow the reassociation margin of `TOL`
    assert!(max_diff(&compiled, &runtime) <= 1e-12 * moved);
    let err = |material: &str| {
        let text = SCENE.replace("MATERIAL", material);
        match heml::scene::Scene::from_toml_str(&text, ".").and_then(|s| s.build()) {
            Ok(_) => panic!("expected an error for {material}"),
            Err(e) => e.to_string(),
        }
    };
    let e = err("energy = \"mu*(I1 - 3) + lambda*ln(J)**2\"");
    assert!(
        e.contains("[[material]] #1") && e.contains("column 28") && e.contains("`**` is not one"),
        "{e}"
    );
    let e = err("law = \"neo_hookean\"\nenergy = \"mu*(I1 - 3) + lambda*ln(J)\"");
    assert!(e.contains("give one of them"), "{e}");
    let e = err("density = 1000.0");
    assert!(e.contains("needs `law`"), "{e}");
    // the anti-locking patch term, the runtime law with neo-Hookean's declared U
    let patch = "\nvolumetric = \"patch\"";
    let compiled = run(&format!("law = \"neo_hookean\"{patch}"));
    let u = NeoHookean::VOLUMETRIC.unwrap();
    let runtime = run(&format!(
        "energy = \"{}\"\nvolumetric_energy = \"{u}\"{patch}",
        NeoHookean::ENERGY
    ));
    assert!(max_diff(&compiled, &runtime) <= 1e-12 * moved);
    let e = err(&format!("law = \"neo_hookean\"\nvolumetric_energy = \"{u}\""));
    assert!(
        e.contains("[[material]] #1") && e.contains("law given as `energy`"),
        "{e}"
    );
    let e = err(&format!(
        "energy = \"{}\"\nvolumetric_energy = \"mu*(J - 1)\"",
        NeoHookean::ENERGY
    ));
    assert!(
        e.contains("[[material]] #1") && e.contains("must vanish with its slope"),
        "{e}"
    );
}

/// A runtime law declaring its volumetric energy with the compiled law's
/// `#[volumetric(...)]` text equals the compiled law in the anti-locking fields
/// (nodal and patch, batched and reference paths), forces and energy, on a
/// deformed jittered box with an inverted tet: the split uses the declared U. For
/// neo-Hookean, whose declared U (K0/2·ln²J) is not the law along dilations, the
/// runtime law *without* it differs from the compiled one by far more than
/// round-off, so the comparison does see which U the split took.
fn check_volumetric_equal<M: InvariantLaw>(seed: u64, differs_without: bool) {
    let mut rng = rng(seed);
    let mesh = jittered_box(&mut rng, [5, 4, 3]);
    let mut x = random_deformation(&mut rng, &mesh, 0.7, 1.3, 0.05);
    invert_first_tet(&mesh, &mut x, 0.3);
    let (compiled, plain) = pair::<M>(&mut rng);
    let text = M::VOLUMETRIC.unwrap_or_else(|| panic!("{} declares no volumetric energy", M::NAME));
    let declared = plain.with_volumetric_energy(text).unwrap();
    assert_eq!(declared.volumetric_energy(), Some(text));
    let opts = ForceOptions::default();
    for v in [Volumetric::nodal(), Volumetric::patch(6)] {
        let run = |m: &dyn Material, assembly: Assembly| {
            let mut field = m.with_volumetric(v).unwrap().force_field(&mesh, None, &opts).unwrap();
            field.set_assembly(assembly);
            field.forces(&x).unwrap()
        };
        for assembly in [Assembly::Batched, Assembly::Reference] {
            let (ec, fc) = run(compiled.as_ref(), assembly);
            let (er, fr) = run(&declared, assembly);
            // [`TOL`]: the tapes of w and U against the generated code, summed at
            // the nodes in the same order; relative to the largest nodal force
            let err = max_diff(&fc, &fr) / max_norm(&fc);
            assert!(err <= TOL, "{} ({v}, {assembly:?}): forces differ by {err:e}", M::NAME);
            assert!(
                (ec - er).abs() <= TOL * ec.abs(),
                "{} ({v}): energy {ec} vs {er}",
                M::NAME
            );
            if differs_without {
                let (_, fp) = run(&plain, assembly);
                let err = max_diff(&fc, &fp) / max_norm(&fc);
                assert!(
                    err > 1e-6,
                    "{} ({v}): the dilation's U gives the same forces ({err:e})",
                    M::NAME
                );
            }
        }
    }
}

#[test]
fn runtime_laws_with_a_declared_volumetric_energy_equal_the_compiled_laws() {
    check_volumetric_equal::<NeoHookean>(21, true);
    check_volumetric_equal::<MooneyRivlin>(22, false);
    check_volumetric_equal::<Gent>(23, false);
}

/// A declared volumetric energy must be a function of J and the law's parameters
/// with U(1) = U′(1) = 0 and U″(1) = K0 at the law's values; each mistake is an
/// error saying which, with the numbers (or the column).
#[test]
fn a_wrong_volumetric_energy_is_an_error_that_says_why() {
    let law = RuntimeLaw::from_energy(
        "c10*(I1bar - 3) + kappa/2*(J - 1).powi(2)",
        &Params::from([("c10", 1.0e3), ("kappa", 1.0e5)]),
    )
    .unwrap();
    // the value, the slope, the curvature; then J and the parameters only: an
    // invariant, or a name the law does not have, is an error at its column
    let cases: [(&str, &[&str]); 5] = [
        (
            "kappa/2*(J - 1).powi(2) + kappa",
            &["must vanish with its slope", "U(1) = 100000"],
        ),
        ("kappa*(J - 1)", &["must vanish with its slope", "U'(1) = 100000"]),
        (
            "kappa*(J - 1).powi(2)",
            &["bulk modulus", "U''(1) = 200000", "K0 = 100000"],
        ),
        (
            "kappa/2*(J - 1).powi(2) + I1bar",
            &["column 27", "not available in a volumetric energy"],
        ),
        ("k/2*(J - 1).powi(2)", &["column 1", "unknown identifier `k`"]),
    ];
    for (u, expected) in cases {
        let e = law.with_volumetric_energy(u).unwrap_err().to_string();
        assert!(expected.iter().all(|part| e.contains(part)), "{u}: {e}");
    }
    // U″(1) = K0 holds for these values only: the check runs with the law's values
    let other = RuntimeLaw::from_energy(
        "c10*(I1bar - 3) + kappa/2*(J - 1).powi(2)",
        &Params::from([("c10", 1.0e3), ("kappa", 2.0e5)]),
    )
    .unwrap();
    assert!(other.with_volumetric_energy("1e5/2*(J - 1).powi(2)").is_err());
    assert!(law.with_volumetric_energy("1e5/2*(J - 1).powi(2)").is_ok());
}
