//! One suite for both grouped volumetric formulations (nodal and patch, which share
//! one implementation in `heml::force::grouped`): each check takes the
//! [`Volumetric`] to test, and `tests/suite/nodal_volume.rs` and `tests/suite/patch_volume.rs`
//! run it on theirs.

use crate::{fd_gradient, invert_first_tet, jittered_box, max_diff, max_norm, random_deformation, rng};
use heml::force::{Assembly, SimdLevel};
use heml::law::{LawKind, Volumetric};
use heml::mesh::generate::{box_mesh, HexSplit};
use heml::nalgebra::{DMatrix, SymmetricEigen};
use heml::prelude::*;

/// Every invariant law (sampled parameters) with the volumetric term `v`.
pub fn grouped_laws(rng: &mut crate::TestRng, v: Volumetric) -> Vec<(&'static str, Box<dyn Material>)> {
    crate::all_laws(rng)
        .into_iter()
        .filter(|(_, l)| l.kind() == LawKind::Invariant)
        .map(|(n, l)| (n, l.with_volumetric(v).unwrap()))
        .collect()
}

/// The neo-Hookean law at E = 1e4, ν = 0.49 (or `entry`'s tissue parameters) with `v`.
fn tissue(name: &str, v: Volumetric) -> Box<dyn Material> {
    let entry = heml::registry::find_material(name).unwrap();
    entry
        .instantiate(&heml_validation::fixtures::tissue_params(entry, 1e4, 0.49).unwrap())
        .unwrap()
        .with_volumetric(v)
        .unwrap()
}

/// The bits of an energy and forces.
fn bits((e, f): (f64, Vec<Vec3>)) -> (u64, Vec<u64>) {
    (
        e.to_bits(),
        f.iter().flat_map(|v| v.iter().map(|c| c.to_bits())).collect(),
    )
}

/// Forces are minus the energy gradient (central differences) for every invariant
/// law with the term `v(seed)` on jittered boxes of `cells` (one tet inverted on odd
/// seeds), and the P1 oracle of the same split and groups agrees with the HEML
/// kernels.
pub fn forces_are_minus_the_energy_gradient(cells: [usize; 3], v: impl Fn(u64) -> Volumetric) {
    for seed in 0..4u64 {
        let mut rng = rng(seed);
        let mesh = jittered_box(&mut rng, cells);
        let mut x = random_deformation(&mut rng, &mesh, 0.6, 1.6, 0.05);
        if seed % 2 == 1 {
            invert_first_tet(&mesh, &mut x, 0.5);
        }
        for (name, law) in grouped_laws(&mut rng, v(seed)) {
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
            // as tests/suite/forces.rs: h = 1e-6 central differences, 1e-6 of the largest force
            assert!(
                err <= 1e-6 * scale,
                "{name} seed {seed}: |f + ∇E| = {err:e} vs {scale:e}"
            );
            // round-off of two kernels summing in different orders: 1e-9
            let fem = law.fem_field(&mesh, None, &ForceOptions::default()).unwrap().unwrap();
            let (ep, fp) = fem.forces(&x).unwrap();
            assert!(
                (ep - e).abs() <= 1e-9 * e.abs().max(1.0),
                "{name}: energy {e} vs P1 {ep}"
            );
            assert!(max_diff(&f, &fp) <= 1e-9 * scale, "{name}: forces vs P1");
        }
    }
}

/// K·u from the tangent of term `v` equals the directional derivative of −f
/// (central differences), so the implicit and static solvers see the exact
/// Hessian; and the blocks the banded static solve assembles sum to the same
/// product.
pub fn tangent_is_the_derivative_of_the_forces(v: Volumetric) {
    let mut rng = rng(7);
    let mesh = jittered_box(&mut rng, [2, 2, 2]);
    let x = random_deformation(&mut rng, &mesh, 0.8, 1.2, 0.03);
    let u: Vec<Vec3> = (0..mesh.n_nodes())
        .map(|_| Vec3::from_fn(|_, _| rand::Rng::gen_range(&mut rng, -1.0..1.0)))
        .collect();
    for (name, law) in grouped_laws(&mut rng, v) {
        let field = law.force_field(&mesh, None, &ForceOptions::default()).unwrap();
        let mut k = law
            .tangent(&mesh, None, &ForceOptions::default(), false)
            .unwrap()
            .unwrap();
        k.update(&x).unwrap();
        let mut ku = vec![Vec3::zeros(); mesh.n_nodes()];
        k.add_product(&u, &mut ku).unwrap();
        let h = 1e-6;
        let shift = |s: f64| -> Vec<Vec3> { x.iter().zip(&u).map(|(p, d)| p + d * s).collect() };
        let (_, fp) = field.forces(&shift(h)).unwrap();
        let (_, fm) = field.forces(&shift(-h)).unwrap();
        let fd: Vec<Vec3> = fp.iter().zip(&fm).map(|(a, b)| -(a - b) / (2.0 * h)).collect();
        let scale = max_norm(&fd).max(1e-3 * max_norm(&fp)).max(1e-12);
        // central differences of the forces: O(h²) truncation and ε|f|/h round-off,
        // ~1e-8 relative here; a wrong term would be O(1)
        let err = max_diff(&ku, &fd);
        assert!(err <= 1e-5 * scale, "{name}: |K u + df/dx u| = {err:e} vs {scale:e}");
        let mut kb = vec![Vec3::zeros(); mesh.n_nodes()];
        for (e, &t) in k.tet_ids().iter().enumerate() {
            let idx = mesh.tets()[t];
            let ke = k.tet_stiffness(e);
            for a in 0..4 {
                for b in 0..4 {
                    kb[idx[a] as usize] += ke.fixed_view::<3, 3>(3 * a, 3 * b).into_owned() * u[idx[b] as usize];
                }
            }
        }
        k.for_each_nonlocal_block(&mut |i, j, b| kb[i] += b * u[j]);
        let err = max_diff(&kb, &ku);
        // the same sums in another order: round-off
        assert!(
            err <= 1e-10 * max_norm(&ku),
            "{name}: assembled blocks vs product {err:e}"
        );
    }
}

/// The field of term `v` gives the same bits on 1, 2 and 3 threads (forces, energy,
/// tangent product): the groups come from the mesh only and every sum runs in a
/// fixed order.
pub fn same_bits_for_any_thread_count(v: Volumetric) {
    let mut rng = rng(11);
    let mesh = box_mesh([1.0, 1.0, 1.0], [12, 12, 12], HexSplit::Six).unwrap();
    let x = random_deformation(&mut rng, &mesh, 0.8, 1.2, 0.02);
    let law = tissue("neo_hookean", v);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let field = law.force_field(&mesh, None, &ForceOptions::default()).unwrap();
            let forces = bits(field.forces(&x).unwrap());
            let mut k = law
                .tangent(&mesh, None, &ForceOptions::default(), false)
                .unwrap()
                .unwrap();
            k.update(&x).unwrap();
            let mut ku = vec![Vec3::zeros(); x.len()];
            k.add_product(&x, &mut ku).unwrap();
            (forces, bits((0.0, ku)).1)
        })
    };
    let one = run(1);
    for threads in [2, 3] {
        assert!(one == run(threads), "{v}: bits differ on {threads} threads");
    }
}

/// The batched pass of term `v` agrees with the reference path (element pass, then
/// the term tet by tet), with tets removed too, and gives the same bits on every
/// instruction set this CPU runs (AVX-512, AVX2 + FMA, baseline: the same operations
/// in the same order on each).
pub fn batched_pass_matches_the_reference_path(v: Volumetric) {
    let mut rng = rng(13);
    let mesh = box_mesh([1.0, 1.0, 1.0], [9, 8, 7], HexSplit::Six).unwrap();
    let x = random_deformation(&mut rng, &mesh, 0.8, 1.2, 0.02);
    for name in ["neo_hookean", "mooney_rivlin"] {
        let law = tissue(name, v);
        let mut fast = law.force_field(&mesh, None, &ForceOptions::default()).unwrap();
        let mut reference = law.force_field(&mesh, None, &ForceOptions::default()).unwrap();
        reference.set_assembly(Assembly::Reference);
        for cut in [false, true] {
            if cut {
                let gone: Vec<usize> = (0..mesh.n_tets()).step_by(7).collect();
                fast.remove_tets(&gone).unwrap();
                reference.remove_tets(&gone).unwrap();
            }
            let (e, f) = fast.forces(&x).unwrap();
            let (er, fr) = reference.forces(&x).unwrap();
            // the same terms summed in other orders (per block or sweep vs tet by tet,
            // the lane volumes vs the plain formula, the fast U′): round-off, 1e-9
            let scale = max_norm(&fr);
            assert!(
                (e - er).abs() <= 1e-9 * er.abs(),
                "{v} {name} cut {cut}: energy {e} vs {er}"
            );
            let err = max_diff(&f, &fr);
            assert!(err <= 1e-9 * scale, "{v} {name} cut {cut}: forces {err:e} vs {scale:e}");
            let levels = SimdLevel::available();
            let first = bits(levels[0].run_with(|| fast.forces(&x)).unwrap().unwrap());
            for level in &levels[1..] {
                let other = bits(level.run_with(|| fast.forces(&x)).unwrap().unwrap());
                assert!(
                    first == other,
                    "{v} {name}: {} differs bitwise from {}",
                    level.name(),
                    levels[0].name()
                );
            }
        }
    }
}

/// The stiffness at rest (dense, from the tangent's product on unit vectors) at
/// ν = 0.499 with each term of `terms` has exactly the six rigid modes as
/// (near-)zero eigenvalues: the smallest non-rigid one is positive, on three meshes
/// (five- and six-tet splits and a jittered, unstructured-like mesh); printed.
pub fn rest_stiffness_has_no_spurious_zero_modes(terms: &[Volumetric]) {
    let mut rng = rng(3);
    let meshes = vec![
        (
            "five-tet box",
            box_mesh([1.0, 1.0, 1.0], [3, 3, 3], HexSplit::Five).unwrap(),
        ),
        (
            "six-tet box",
            box_mesh([1.0, 1.0, 1.0], [3, 3, 3], HexSplit::Six).unwrap(),
        ),
        ("jittered box", jittered_box(&mut rng, [3, 3, 2])),
    ];
    for (name, mesh) in &meshes {
        for &v in terms {
            let law = heml::registry::find_material("neo_hookean")
                .unwrap()
                .instantiate(&Params::from([("E", 1.0), ("nu", 0.499)]))
                .unwrap()
                .with_volumetric(v)
                .unwrap();
            let mut k = law
                .tangent(mesh, None, &ForceOptions::default(), false)
                .unwrap()
                .unwrap();
            k.update(mesh.nodes()).unwrap();
            let n = 3 * mesh.n_nodes();
            let mut dense = DMatrix::zeros(n, n);
            for c in 0..n {
                let mut u = vec![Vec3::zeros(); mesh.n_nodes()];
                u[c / 3][c % 3] = 1.0;
                let mut y = vec![Vec3::zeros(); mesh.n_nodes()];
                k.add_product(&u, &mut y).unwrap();
                for r in 0..n {
                    dense[(r, c)] = y[r / 3][r % 3];
                }
            }
            let asym = (&dense - dense.transpose()).amax();
            assert!(asym <= 1e-12 * dense.amax(), "{name} {v:?}: K not symmetric ({asym:e})");
            let mut ev: Vec<f64> = SymmetricEigen::new(dense).eigenvalues.iter().copied().collect();
            ev.sort_by(f64::total_cmp);
            let max = ev[n - 1];
            // six rigid modes at round-off (|λ| ≤ 1e-10 λmax: the dense eigen-solver's
            // error is ~1e-13 λmax), then the smallest non-rigid one, which must be
            // clearly positive (a spurious mechanism would sit at round-off too)
            assert!(
                ev[..6].iter().all(|l| l.abs() <= 1e-10 * max),
                "{name} {v:?}: rigid modes {:?}",
                &ev[..7]
            );
            eprintln!(
                "{name} {v:?}: smallest non-rigid eigenvalue {:.3e} (largest {max:.3e})",
                ev[6]
            );
            assert!(ev[6] > 1e-6 * max, "{name} {v:?}: {:e} vs {max:e}", ev[6]);
        }
    }
}

/// An undamped block of nearly incompressible tissue (ν = 0.49) with term `v`, held
/// at its base and plucked (its top pulled sideways, then released), keeps its
/// total energy bounded: no spurious mode pumps energy.
pub fn plucked_block_keeps_its_energy_bounded(v: Volumetric) {
    let mesh = box_mesh([0.1, 0.1, 0.1], [4, 4, 4], HexSplit::Six).unwrap();
    let mut sys = heml::system(mesh)
        .material("neo_hookean", Params::from([("E", 3e3), ("nu", 0.49)]))
        .unwrap()
        .volumetric(v)
        .density(1000.0)
        .fix_where(|p| p.z < 1e-9)
        .build()
        .unwrap();
    // pluck: a shear displacement growing with height (5 % of the size at the top)
    let rest = sys.rest_positions().to_vec();
    for (x, p) in sys.positions_mut().iter_mut().zip(rest) {
        x.x += 0.005 * (p.z / 0.1).powi(2);
    }
    let mut integ = heml::integrator("symplectic_euler").unwrap();
    let dt = 0.5 * sys.stable_dt();
    let e0 = sys.energies().unwrap().total;
    assert!(e0 > 0.0);
    let (mut lo, mut hi) = (e0, e0);
    for _ in 0..4000 {
        integ.step(&mut sys, dt).unwrap();
        let e = sys.energies().unwrap().total;
        lo = lo.min(e);
        hi = hi.max(e);
    }
    eprintln!("plucked block ({v}): total energy in [{lo:.4e}, {hi:.4e}], start {e0:.4e}");
    // symplectic Euler conserves a modified energy: the measured one oscillates by
    // O(dt) (~1 % here) without drift; growth of a spurious mode would exceed 5 %
    assert!(
        hi <= 1.05 * e0 && lo >= 0.95 * e0,
        "{v}: energy left [{lo:e}, {hi:e}] around {e0:e}"
    );
}

/// Backward Euler with term `v` (the element tangent plus the term's matrix-free
/// product) settles on the static solution of the same system (banded solve with
/// the term's couplings): a soft block at ν = 0.49 sagging under gravity, dt = 10 ms.
pub fn implicit_steps_reach_the_static_solution(v: Volumetric) {
    let build = || {
        heml::system(box_mesh([0.1, 0.04, 0.04], [6, 3, 3], HexSplit::Six).unwrap())
            .material("neo_hookean", Params::from([("E", 3e3), ("nu", 0.49)]))
            .unwrap()
            .volumetric(v)
            .density(1000.0)
            .gravity(Vec3::new(0.0, 0.0, -9.81))
            .rayleigh(20.0, 0.0)
            .fix_where(|p| p.x < 1e-9)
            .build()
            .unwrap()
    };
    let mut stat = build();
    stat.solve_static(&heml::system::StaticOptions {
        tol: 1e-9,
        ..Default::default()
    })
    .unwrap();
    let mut dyn_sys = build();
    let mut be = heml::integrator("backward_euler").unwrap();
    for _ in 0..300 {
        be.step(&mut dyn_sys, 0.01).unwrap();
    }
    let us = stat.displacements();
    let ud = dyn_sys.displacements();
    let err = max_diff(&us, &ud) / max_norm(&us);
    eprintln!(
        "backward Euler vs static ({v}): relative difference {err:.2e}, sag {:.3e} m",
        max_norm(&us)
    );
    // 3 s with mass damping 20/s: the transient has decayed by e^-30 (the slowest
    // mode included); the bound is the CG/Newton tolerance of the steps (1e-6)
    assert!(err < 1e-3, "{v}: relative difference {err:e}");
}

/// The tip deflection of the 1 920-tet six-tet cantilever (40 cells along the
/// 40 × 4 × 2 beam) with term `v` at ν = `nu`, relative to its ν = 0 value.
pub fn kept_deflection(v: Volumetric, nu: f64) -> f64 {
    use heml_validation::locking::{six_tet_beam, tip_ratio, Bar};
    let ratio = |nu: f64| tip_ratio(six_tet_beam(40).unwrap(), Bar::BEAM, nu, v).unwrap().0;
    ratio(nu) / ratio(0.0)
}
