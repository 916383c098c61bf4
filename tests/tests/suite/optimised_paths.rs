//! Every optimised force path equals the plain serial kernel to round-off, for every
//! registered law (HEML and link fields; P1 for the invariant laws), thread count, with inverted tets and tet
//! counts that are not multiples of the batch width; and the parallel path gives the
//! same bits for any number of threads.
//!
//! Tolerance: the optimised paths evaluate each tet with the same formula as the
//! plain kernel, except that (a) `ln`/`exp`/`powf` are the vectorisable versions
//! (≤ 2 ulp from libm), and (b) the contributions of the ~20 tets around a node are
//! summed in another order. (b) changes a node's sum by at most n·ε·S_i, where S_i is
//! the sum of the magnitudes of the contributions to node i (n ≈ 24, ε = 1.1e-16:
//! ≈ 3e-15·S_i); (a) changes each contribution by a few ε relative. So each node is
//! compared relative to its own S_i, with the bound 1e-14.
//!
//! Parameters are soft-tissue-like (exponential stiffening b = 1): for exponential
//! laws the 1-ulp difference of the fast `powf` in Ī1 is amplified by the condition
//! number b·Ī1 of exp(b(Ī1 − 3)); with b·Ī1 ~ 100 (forces ~1e37 in random-parameter
//! tests) the difference reaches ~1.5e-14·S_i, as libm's own error does. The bound is
//! therefore 1e-14·S_i·max(1, ln(S_i / median S)): e^x ≤ S_i/typical S bounds |x|.

use heml::force::{Assembly, ElasticForces, SimdLevel};
use heml::law::*;
use heml::mesh::reorder::{morton_node_order, morton_order, Permutation};
use heml::prelude::*;
use heml_tests::*;

const REL: f64 = 1e-14;

fn pool(n: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap()
}

/// A jittered box of 1 134 tets (three blocks, enough for the block driver to go
/// parallel, `PARALLEL_MIN_TETS`; not a multiple of the batch width: the
/// padded last batch is exercised), deformed with a few
/// compressed and inverted tets.
fn setup(seed: u64) -> (TetMesh, Vec<Vec3>) {
    let mut rng = rng(seed);
    let mesh = jittered_box(&mut rng, [9, 7, 3]);
    assert!(mesh.n_tets() >= heml::force::assembly::PARALLEL_MIN_TETS);
    assert_ne!(mesh.n_tets() % heml::force::assembly::LANES, 0);
    let mut x = random_deformation(&mut rng, &mesh, 0.8, 1.25, 0.02);
    invert_first_tet(&mesh, &mut x, 0.3);
    // squash a corner region so that some tets fall below J0 without inverting
    let (lo, hi) = mesh.bounding_box();
    for (xi, p) in x.iter_mut().zip(mesh.nodes()) {
        if (p.x - lo.x) < 0.3 * (hi.x - lo.x) {
            xi.z = lo.z + 0.35 * (xi.z - lo.z);
        }
    }
    (mesh, x)
}

/// S_i: the sum over tets of |contribution to node i| (plain kernel, one tet at a time).
fn magnitudes(law: &dyn Material, mesh: &TetMesh, x: &[Vec3], fem: bool) -> Vec<f64> {
    let opts = ForceOptions::default();
    let mut s = vec![0.0; mesh.n_nodes()];
    for t in 0..mesh.n_tets() {
        let mut field = if fem {
            law.fem_field(mesh, Some(&[t]), &opts).unwrap().unwrap()
        } else {
            law.force_field(mesh, Some(&[t]), &opts).unwrap()
        };
        field.set_assembly(Assembly::Reference);
        let (_, f) = field.forces(x).unwrap();
        for &i in &mesh.tets()[t] {
            s[i as usize] += f[i as usize].norm();
        }
    }
    s
}

/// Soft-tissue parameters (E = 3 kPa, ν = 0.45) for the built-in invariant laws; the
/// test's own laws get random parameters from their valid ranges.
fn tissue_params(entry: &MaterialEntry) -> Params {
    let p = heml_validation::fixtures::soft_tissue_params(entry.name, 3e3, 0.45)
        .unwrap_or_else(|| heml_tests::sample_params(entry, &mut heml_tests::rng(1)));
    // fibre laws' exp(k2·E²) overflows at this setup's inverted, 3× squashed tets for
    // k2 ~ 1 (E ~ 10): a small exponent keeps the forces finite, the code paths the same
    match entry.name {
        "holzapfel_gasser_ogden" => p.with("k2", 0.05),
        "ti_mooney_rivlin" => p.with("c4", 0.5),
        _ => p,
    }
}

fn assert_close(name: &str, what: &str, got: &[Vec3], want: &[Vec3], scale: &[f64]) {
    let mut sorted: Vec<f64> = scale.iter().copied().filter(|s| *s > 0.0).collect();
    sorted.sort_by(f64::total_cmp);
    let typical = sorted.get(sorted.len() / 2).copied().unwrap_or(1.0);
    for (i, ((a, b), s)) in got.iter().zip(want).zip(scale).enumerate() {
        let d = (a - b).norm();
        // exponential laws: exp(x) has condition number |x| ≲ ln(S_i / typical S)
        let cond = (s / typical).ln().max(1.0);
        assert!(
            d <= REL * cond * s.max(f64::MIN_POSITIVE),
            "{name} {what}: node {i} differs by {d:e} (scale {s:e}): {a:?} vs {b:?}"
        );
    }
}

/// Energies agree to round-off (Gent's energy is NaN past its locking stretch, on
/// every path alike). Exponential laws (HGO's exp(k2·E²) on the fibre lanes): the
/// fast `exp`'s ulp is amplified by its argument x, and x ≤ ln|E| for energies far
/// above the parameters' scale, hence the factor max(1, ln|E|).
fn same_energy(e: f64, e_ref: f64) -> bool {
    let cond = e_ref.abs().ln().max(1.0);
    (e - e_ref).abs() <= 1e-13 * cond * e_ref.abs().max(1e-300) || (e.is_nan() && e_ref.is_nan())
}

fn bits(f: &[Vec3]) -> Vec<u64> {
    f.iter().flat_map(|v| v.iter().map(|c| c.to_bits())).collect()
}

fn check_all_paths(fem: bool) {
    let (mesh, x) = setup(11);
    let opts = ForceOptions::default();
    let (mut checked, mut links) = (0, 0);
    for entry in heml::materials_list() {
        // link laws (mass–spring) have a HEML-style field but no P1 one
        if fem && entry.kind == LawKind::Link {
            continue;
        }
        links += usize::from(entry.kind == LawKind::Link);
        let law = heml_tests::fibred(
            entry.instantiate(&tissue_params(entry)).unwrap(),
            &mesh,
            &mut heml_tests::rng(3),
        );
        let build = || -> Box<dyn ElasticForces> {
            if fem {
                law.fem_field(&mesh, None, &opts).unwrap().unwrap()
            } else {
                law.force_field(&mesh, None, &opts).unwrap()
            }
        };
        let mut reference = build();
        reference.set_assembly(Assembly::Reference);
        let (e_ref, f_ref) = reference.forces(&x).unwrap();
        assert!(f_ref.iter().all(|v| v.iter().all(|c| c.is_finite())), "{}", entry.name);
        let scale = magnitudes(law.as_ref(), &mesh, &x, fem);

        let mut batched = build();
        batched.set_assembly(Assembly::Batched);
        let parallel = build();
        // every instruction set this CPU runs (AVX-512, AVX2 + FMA, baseline); they
        // do the same operations in the same order, so they agree bitwise too
        let mut first_level: Option<(u64, Vec<u64>)> = None;
        for level in SimdLevel::available() {
            let name = level.name();
            let (e, f) = level.run_with(|| batched.forces(&x)).unwrap().unwrap();
            assert_close(entry.name, &format!("batched, {name}"), &f, &f_ref, &scale);
            assert!(same_energy(e, e_ref), "{}: energy {e} vs {e_ref}", entry.name);

            let mut first: Option<(u64, Vec<u64>)> = None;
            for n in 1..=4 {
                let (e, f) = level
                    .run_with(|| pool(n).install(|| parallel.forces(&x)))
                    .unwrap()
                    .unwrap();
                assert_close(
                    entry.name,
                    &format!("parallel, {n} threads, {name}"),
                    &f,
                    &f_ref,
                    &scale,
                );
                assert!(same_energy(e, e_ref), "{}: energy {e} vs {e_ref}", entry.name);
                let b = (e.to_bits(), bits(&f));
                match &first {
                    None => first = Some(b),
                    Some(b1) => assert!(
                        *b1 == b,
                        "{}: {n} threads differ bitwise from 1 thread ({name})",
                        entry.name
                    ),
                }
            }
            match &first_level {
                None => first_level = first,
                Some(b0) => assert!(
                    Some(b0) == first.as_ref(),
                    "{}: {name} differs bitwise from {}",
                    entry.name,
                    SimdLevel::available()[0].name()
                ),
            }
        }
        // adding to a non-zero buffer adds: g − f_ref is the parallel path's forces,
        // held to the same bound as above (relative to S_i, the node's sum of
        // |contributions|, not to |f_i|, which cancellation can make arbitrarily
        // small); the subtraction adds ~2ε|f_ref| ≤ 2ε·S_i, within REL·S_i
        let mut g = f_ref.clone();
        parallel.add_forces(&x, &mut g).unwrap();
        let added: Vec<Vec3> = g.iter().zip(&f_ref).map(|(gi, fi)| gi - fi).collect();
        assert_close(entry.name, "added to a non-zero buffer", &added, &f_ref, &scale);
        checked += 1;
    }
    assert!(checked - links >= 8, "only {} invariant laws", checked - links);
    assert!(fem || links >= 1, "no link law checked");
}

#[test]
fn heml_paths_equal_the_plain_kernel() {
    check_all_paths(false);
}

#[test]
fn p1_paths_equal_the_plain_kernel() {
    check_all_paths(true);
}

/// The reordered field (Morton order, the default) against the field in mesh order,
/// and a randomly renumbered mesh against the original, mapped back by permutation.
#[test]
fn reordering_changes_nothing_but_round_off() {
    let (mesh, x) = setup(3);
    let opts = ForceOptions::default();
    let law = NeoHookean::from_young(3e3, 0.45);
    let mut plain = HemlField::on_tets_unordered(law, &mesh, None, opts).unwrap();
    plain.set_assembly(Assembly::Reference);
    assert_eq!(plain.tet_ids(), (0..mesh.n_tets()).collect::<Vec<_>>().as_slice());
    let (e_ref, f_ref) = plain.forces(&x).unwrap();
    let boxed = heml::material("neo_hookean", &Params::from([("E", 3e3), ("nu", 0.45)])).unwrap();
    let scale = magnitudes(boxed.as_ref(), &mesh, &x, false);

    let ordered = HemlField::new(law, &mesh, opts).unwrap();
    let mut ids = ordered.tet_ids().to_vec();
    assert_ne!(ids, plain.tet_ids(), "Morton order should differ from a box's order");
    ids.sort_unstable();
    assert_eq!(ids, plain.tet_ids());
    let (e, f) = ordered.forces(&x).unwrap();
    assert_close("neo_hookean", "reordered", &f, &f_ref, &scale);
    assert!((e - e_ref).abs() <= 1e-13 * e_ref.abs());
    // per-tet states follow tet_ids()
    let s_plain = plain.tet_states(&x).unwrap();
    for (k, (&t, s)) in ordered
        .tet_ids()
        .iter()
        .zip(ordered.tet_states(&x).unwrap())
        .enumerate()
    {
        assert!(
            (s.0 - s_plain[t].0).abs() <= 1e-13 * s.0.abs().max(1.0),
            "tet {t} (field {k})"
        );
    }

    // a shuffled numbering, then its Morton renumbering, give the same physical forces
    let mut r = rng(9);
    let mut perm = |n: usize| {
        use rand::seq::SliceRandom;
        let mut v: Vec<usize> = (0..n).collect();
        v.shuffle(&mut r);
        Permutation::from_new_to_old(v)
    };
    let (pn, pt) = (perm(mesh.n_nodes()), perm(mesh.n_tets()));
    let shuffled = mesh.renumbered(&pn, &pt).unwrap();
    let xs = pn.apply(&x);
    for m in [shuffled.clone(), {
        let (qn, qt) = (morton_node_order(&shuffled), morton_order(&shuffled));
        shuffled.renumbered(&qn, &qt).unwrap()
    }] {
        // positions of m's nodes: find them through the rest positions' permutation
        let field = HemlField::new(law, &m, opts).unwrap();
        let to_old: Vec<usize> = {
            let index: std::collections::HashMap<[u64; 3], usize> = mesh
                .nodes()
                .iter()
                .enumerate()
                .map(|(i, p)| ([p.x.to_bits(), p.y.to_bits(), p.z.to_bits()], i))
                .collect();
            m.nodes()
                .iter()
                .map(|p| index[&[p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]])
                .collect()
        };
        let xm: Vec<Vec3> = to_old.iter().map(|&o| x[o]).collect();
        let (e, f) = field.forces(&xm).unwrap();
        let mut back = vec![Vec3::zeros(); mesh.n_nodes()];
        for (new, &old) in to_old.iter().enumerate() {
            back[old] = f[new];
        }
        assert_close("neo_hookean", "renumbered mesh", &back, &f_ref, &scale);
        assert!((e - e_ref).abs() <= 1e-13 * e_ref.abs());
    }
    assert_eq!(xs.len(), x.len());
}

/// Tiny fields (fewer tets than one batch) and a single tet work on every path.
#[test]
fn tiny_fields() {
    let mut r = rng(2);
    let mesh = random_tet(&mut r);
    let x = random_deformation(&mut r, &mesh, 0.7, 1.3, 0.05);
    let law = heml::material(
        "mooney_rivlin",
        &Params::from([("c10", 300.0), ("c01", 200.0), ("kappa", 1e4)]),
    )
    .unwrap();
    let mut a = law.force_field(&mesh, None, &ForceOptions::default()).unwrap();
    a.set_assembly(Assembly::Reference);
    let (ea, fa) = a.forces(&x).unwrap();
    let b = law.force_field(&mesh, None, &ForceOptions::default()).unwrap();
    let (eb, fb) = b.forces(&x).unwrap();
    assert!(max_diff(&fa, &fb) <= 1e-14 * max_norm(&fa) * 4.0);
    assert!((ea - eb).abs() <= 1e-14 * ea.abs());
}
