//! The anti-locking (nodal-J) volumetric formulation: forces are minus the energy
//! gradient for every invariant law, its tangent is the forces' derivative, the same
//! bits for any thread count, no spurious modes, bounded energy, and no locking.

use heml::force::SimdLevel;
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
            assert!(
                err <= 1e-6 * scale,
                "{name} seed {seed}: |f + ∇E| = {err:e} vs {scale:e}"
            );
            // the P1 oracle of the same split agrees with the HEML kernels
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

/// K·u from the tangent equals the directional derivative of −f (central
/// differences), so the implicit solvers see the exact Hessian of the nodal energy.
#[test]
fn nodal_tangent_is_the_derivative_of_the_forces() {
    let mut rng = rng(7);
    let mesh = jittered_box(&mut rng, [2, 2, 2]);
    let x = random_deformation(&mut rng, &mesh, 0.8, 1.2, 0.03);
    let u: Vec<Vec3> = (0..mesh.n_nodes())
        .map(|_| Vec3::from_fn(|_, _| rand::Rng::gen_range(&mut rng, -1.0..1.0)))
        .collect();
    for (name, law) in nodal_laws(&mut rng) {
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
    }
}

/// The nodal term's passes (block driver, nodal pass) give the same bits on 1, 2
/// and 3 threads, for the forces, the energy and the tangent product.
#[test]
fn nodal_field_gives_the_same_bits_for_any_thread_count() {
    let mut rng = rng(11);
    let mesh =
        heml::mesh::generate::box_mesh([1.0, 1.0, 1.0], [12, 12, 12], heml::mesh::generate::HexSplit::Six).unwrap();
    let x = random_deformation(&mut rng, &mesh, 0.8, 1.2, 0.02);
    let law = heml::registry::find_material("neo_hookean")
        .unwrap()
        .instantiate(&Params::from([("E", 1e4), ("nu", 0.49)]))
        .unwrap()
        .with_volumetric(Volumetric::nodal())
        .unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let field = law.force_field(&mesh, None, &ForceOptions::default()).unwrap();
            let (e, f) = field.forces(&x).unwrap();
            let mut k = law
                .tangent(&mesh, None, &ForceOptions::default(), false)
                .unwrap()
                .unwrap();
            k.update(&x).unwrap();
            let mut ku = vec![Vec3::zeros(); x.len()];
            k.add_product(&x, &mut ku).unwrap();
            (e.to_bits(), f, ku)
        })
    };
    let one = run(1);
    for threads in [2, 3] {
        let other = run(threads);
        assert_eq!(one.0, other.0, "energy bits, {threads} threads");
        assert!(
            one.1
                .iter()
                .zip(&other.1)
                .all(|(a, b)| a.iter().zip(b.iter()).all(|(p, q)| p.to_bits() == q.to_bits())),
            "force bits, {threads} threads"
        );
        assert!(
            one.2
                .iter()
                .zip(&other.2)
                .all(|(a, b)| a.iter().zip(b.iter()).all(|(p, q)| p.to_bits() == q.to_bits())),
            "tangent product bits, {threads} threads"
        );
    }
}

/// The nodal term's passes give the same bits on every instruction set this CPU
/// runs (AVX-512, AVX2 + FMA, baseline): the lumped-volume sweep, the nodal pass
/// (four nodes per vector) and the element pass with the pressures gathered from
/// the node buffers' padding slot do the same operations in the same order on each.
#[test]
fn nodal_field_gives_the_same_bits_on_every_instruction_set() {
    let mut rng = rng(12);
    let mesh = heml::mesh::generate::box_mesh([1.0, 1.0, 1.0], [9, 8, 7], heml::mesh::generate::HexSplit::Six).unwrap();
    let x = random_deformation(&mut rng, &mesh, 0.8, 1.2, 0.02);
    for name in ["neo_hookean", "mooney_rivlin"] {
        let entry = heml::registry::find_material(name).unwrap();
        let law = entry
            .instantiate(&heml_validation::fixtures::tissue_params(entry, 1e4, 0.49).unwrap())
            .unwrap()
            .with_volumetric(Volumetric::nodal())
            .unwrap();
        let field = law.force_field(&mesh, None, &ForceOptions::default()).unwrap();
        let bits = |(e, f): (f64, Vec<Vec3>)| -> (u64, Vec<u64>) {
            (
                e.to_bits(),
                f.iter().flat_map(|v| v.iter().map(|c| c.to_bits())).collect(),
            )
        };
        let levels = SimdLevel::available();
        let first = bits(levels[0].run_with(|| field.forces(&x)).unwrap().unwrap());
        for level in &levels[1..] {
            let other = bits(level.run_with(|| field.forces(&x)).unwrap().unwrap());
            assert!(
                first == other,
                "{name}: {} differs bitwise from {}",
                level.name(),
                levels[0].name()
            );
        }
    }
}

/// The stiffness at rest (dense, from the tangent's product on unit vectors) of the
/// nodal formulation at ν = 0.499 has exactly the six rigid modes as (near-)zero
/// eigenvalues: the smallest non-rigid one is positive, on three meshes (five- and
/// six-tet splits and a jittered, unstructured-like mesh), with and without the
/// stabilisation.
#[test]
fn nodal_stiffness_at_rest_has_no_spurious_zero_modes() {
    use heml::mesh::generate::{box_mesh, HexSplit};
    use heml::nalgebra::{DMatrix, SymmetricEigen};
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
        for s in [0.0, heml::force::nodal_volume::DEFAULT_STABILIZATION] {
            let law = heml::registry::find_material("neo_hookean")
                .unwrap()
                .instantiate(&Params::from([("E", 1.0), ("nu", 0.499)]))
                .unwrap()
                .with_volumetric(Volumetric::Nodal { stabilization: s })
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
            assert!(asym <= 1e-12 * dense.amax(), "{name}: K not symmetric ({asym:e})");
            let mut ev: Vec<f64> = SymmetricEigen::new(dense).eigenvalues.iter().copied().collect();
            ev.sort_by(f64::total_cmp);
            let max = ev[n - 1];
            // six rigid modes at round-off (|λ| ≤ 1e-10 λmax: the dense eigen-solver's
            // error is ~1e-13 λmax), then the smallest non-rigid one, which must be
            // clearly positive (a spurious mechanism would sit at round-off too)
            assert!(
                ev[..6].iter().all(|l| l.abs() <= 1e-10 * max),
                "{name} s = {s}: rigid modes {:?}",
                &ev[..7]
            );
            eprintln!(
                "{name} s = {s}: smallest non-rigid eigenvalue {:.3e} (largest {max:.3e})",
                ev[6]
            );
            assert!(
                ev[6] > 1e-6 * max,
                "{name} s = {s}: smallest non-rigid eigenvalue {:e} vs {max:e}",
                ev[6]
            );
        }
    }
}

/// An undamped block of nearly incompressible tissue (ν = 0.49, nodal term), held at
/// its base and plucked (its top pulled sideways, then released), keeps its total
/// energy bounded: no spurious mode pumps energy.
#[test]
fn plucked_nodal_block_keeps_its_energy_bounded() {
    use heml::mesh::generate::{box_mesh, HexSplit};
    let mesh = box_mesh([0.1, 0.1, 0.1], [4, 4, 4], HexSplit::Six).unwrap();
    let mut sys = heml::system(mesh)
        .material("neo_hookean", Params::from([("E", 3e3), ("nu", 0.49)]))
        .unwrap()
        .volumetric(Volumetric::nodal())
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
    eprintln!("plucked block: total energy in [{lo:.4e}, {hi:.4e}], start {e0:.4e}");
    // symplectic Euler conserves a modified energy: the measured one oscillates by
    // O(dt) (~1 % here) without drift; growth of a spurious mode would exceed 5 %
    assert!(
        hi <= 1.05 * e0 && lo >= 0.95 * e0,
        "energy left [{lo:e}, {hi:e}] around {e0:e}"
    );
}

/// Volumetric locking on the six-tet split (40 cells along the 40 × 4 × 2 beam, 4 × 2
/// across, 1 920 tets): tip deflection / beam theory relative to its ν = 0 value.
/// Measured: element 0.175 (ν = 0.49) and 0.027 (ν = 0.499) of 0.544; nodal 0.623 →
/// 0.581 (0.933) and 0.545 (0.875). The 10 % bound holds at ν = 0.49 on this
/// mesh and at ν = 0.49 on the 15 360-tet one (0.956, `heml validate --case locking`);
/// at ν = 0.499 this coarse mesh keeps 12.5 % of residual locking, so the bound
/// asserted there is 15 % (the element formulation is at 97 %).
#[test]
fn cantilever_does_not_lock_with_the_nodal_term() {
    let ratio = |nu: f64, v: Volumetric| tip_ratio(six_tet_beam(40).unwrap(), Bar::BEAM, nu, v).unwrap().0;
    let base = ratio(0.0, Volumetric::nodal());
    let element_base = ratio(0.0, Volumetric::Element);
    for (nu, tol) in [(0.49, 0.10), (0.499, 0.15)] {
        let nodal = ratio(nu, Volumetric::nodal()) / base;
        let element = ratio(nu, Volumetric::Element) / element_base;
        eprintln!("nu = {nu}: nodal {nodal:.3}, element {element:.3} of their nu = 0 values");
        assert!(
            (nodal - 1.0).abs() <= tol,
            "nu = {nu}: nodal keeps {nodal:.3} of its nu = 0 deflection"
        );
        // the standard term locks (the contrast that makes the test meaningful)
        assert!(element < 0.2, "nu = {nu}: element keeps {element:.3}");
    }
}

/// The nu sweep of the README on the 1 920- and the 15 360-tet six-tet beams
/// (printed; `HEML_S` = comma-separated stabilisation factors, default the default).
#[test]
#[ignore = "a minute: the README's nu sweep on 15 360 tets"]
fn cantilever_nu_sweep_both_meshes() {
    let ss: Vec<f64> = std::env::var("HEML_S")
        .map(|v| v.split(',').map(|s| s.parse().unwrap()).collect())
        .unwrap_or_else(|_| vec![heml::force::nodal_volume::DEFAULT_STABILIZATION]);
    for cells in [40, 80] {
        for &s in &ss {
            let mut base = 0.0;
            for nu in [0.0, 0.3, 0.45, 0.49, 0.499] {
                let t = std::time::Instant::now();
                let (r, rep) = tip_ratio(
                    six_tet_beam(cells).unwrap(),
                    Bar::BEAM,
                    nu,
                    Volumetric::Nodal { stabilization: s },
                )
                .unwrap();
                if nu == 0.0 {
                    base = r;
                }
                eprintln!(
                    "cells {cells} s {s} nu {nu}: {r:.4} ({:.3} of nu = 0; {} it, {:.1}s)",
                    r / base,
                    rep.iterations,
                    t.elapsed().as_secs_f64()
                );
            }
        }
    }
}

/// Cost of a force evaluation with the nodal term relative to the element one, on
/// 1 and 2 threads in one run (printed, not asserted: the README's benchmark;
/// evaluations interleaved so that both see the same machine load; median and range
/// of 40 each).
#[test]
#[ignore = "timing, for the README"]
fn nodal_cost_ratio() {
    let mesh = heml::mesh::generate::box_of_about(100_000).unwrap();
    let x = heml_validation::fixtures::smooth_deformation(&mesh);
    let stats = |t: &mut Vec<f64>| {
        t.sort_by(f64::total_cmp);
        (t[t.len() / 2], t[0], t[t.len() - 1])
    };
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            for name in ["neo_hookean", "mooney_rivlin"] {
                let entry = heml::registry::find_material(name).unwrap();
                let law = entry
                    .instantiate(&heml_validation::fixtures::tissue_params(entry, 3e3, 0.49).unwrap())
                    .unwrap();
                let fields: Vec<_> = [Volumetric::Element, Volumetric::nodal()]
                    .iter()
                    .map(|v| {
                        law.with_volumetric(*v)
                            .unwrap()
                            .force_field(&mesh, None, &ForceOptions::default())
                            .unwrap()
                    })
                    .collect();
                let mut times = [Vec::new(), Vec::new()];
                let mut ratios = Vec::new();
                let mut f = vec![Vec3::zeros(); x.len()];
                for _ in 0..40 {
                    let mut pair = [0.0; 2];
                    for (k, field) in fields.iter().enumerate() {
                        f.fill(Vec3::zeros());
                        let t = std::time::Instant::now();
                        field.add_forces(&x, &mut f).unwrap();
                        pair[k] = t.elapsed().as_secs_f64();
                        times[k].push(pair[k]);
                    }
                    ratios.push(pair[1] / pair[0]);
                }
                let (e, n, r) = (stats(&mut times[0]), stats(&mut times[1]), stats(&mut ratios));
                eprintln!(
                    "{threads} thread(s), {name}, {} tets: element {:.2} ms [{:.2}, {:.2}], nodal {:.2} ms [{:.2}, {:.2}]; \
                     ratio of each pair: median {:.2}x [{:.2}, {:.2}]",
                    mesh.n_tets(),
                    e.0 * 1e3,
                    e.1 * 1e3,
                    e.2 * 1e3,
                    n.0 * 1e3,
                    n.1 * 1e3,
                    n.2 * 1e3,
                    r.0,
                    r.1,
                    r.2
                );
            }
        });
    }
}

/// Where the nodal formulation's time goes (printed, ns per tet, median of 15
/// rounds taken round-robin so that every part sees the same load): the element
/// field, its split law alone, the lumped-volume sweep, the sweep plus the nodal
/// pass, the nodal term's own passes, the whole nodal field, and the same work as
/// separate calls (pressures, then the split-law element pass).
#[test]
#[ignore = "timing, for the README"]
fn nodal_cost_breakdown() {
    use heml::force::nodal_volume::element_fraction;
    use heml::force::{Dilation, HemlField, Isochoric, NodalVolume, NodalVolumeField};
    let mesh = heml::mesh::generate::box_of_about(100_000).unwrap();
    let x = heml_validation::fixtures::smooth_deformation(&mesh);
    let (mu, lambda) = heml::params::lame(3e3, 0.49);
    let law = heml::materials::NeoHookean { mu, lambda };
    let c = 1.0 - element_fraction(&Dilation::new(law), heml::force::nodal_volume::DEFAULT_STABILIZATION);
    let opts = ForceOptions::default();
    let plain = HemlField::on_tets(law, &mesh, None, opts).unwrap();
    let iso = HemlField::on_tets(Isochoric::new(law, c), &mesh, None, opts).unwrap();
    let nodal = NodalVolume::new(law, c, &mesh, None, opts).unwrap();
    let field = NodalVolumeField::new(
        HemlField::on_tets(Isochoric::new(law, c), &mesh, None, opts).unwrap(),
        NodalVolume::new(law, c, &mesh, None, opts).unwrap(),
    )
    .unwrap();
    let mut f = vec![Vec3::zeros(); x.len()];
    let parts = [
        "element field",
        "split law (element part alone)",
        "lumped sweep (nodal_j)",
        "nodal term alone (sweep, nodal pass, pressure forces)",
        "nodal field",
        "sweep + split-law element pass, separately",
    ];
    let inner = 10;
    let mut t = vec![Vec::new(); parts.len()];
    for _ in 0..15 {
        for (k, times) in t.iter_mut().enumerate() {
            let s = std::time::Instant::now();
            for _ in 0..inner {
                match k {
                    0 => std::hint::black_box(plain.add_forces(&x, &mut f).unwrap()),
                    1 => std::hint::black_box(iso.add_forces(&x, &mut f).unwrap()),
                    2 => std::hint::black_box(nodal.nodal_j(&x).unwrap()[0]),
                    3 => std::hint::black_box(nodal.add_forces(&x, &mut f, true).unwrap()),
                    4 => std::hint::black_box(field.add_forces(&x, &mut f).unwrap()),
                    _ => {
                        std::hint::black_box(nodal.nodal_j(&x).unwrap()[0]);
                        std::hint::black_box(iso.add_forces(&x, &mut f).unwrap())
                    }
                };
            }
            times.push(s.elapsed().as_secs_f64() / (inner * mesh.n_tets()) as f64 * 1e9);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let m: Vec<f64> = t.iter_mut().map(median).collect();
    for (name, v) in parts.iter().zip(&m) {
        eprintln!("{name:<56} {v:7.2} ns/tet  {:.2}x element", v / m[0]);
    }
}

/// Backward Euler on the nodal formulation (its tangent through the assembled matrix
/// plus the matrix-free nodal product) settles on the static solution of the same
/// system: a soft block at ν = 0.49 sagging under gravity, dt = 10 ms.
#[test]
fn implicit_steps_with_the_nodal_term_reach_the_static_solution() {
    use heml::mesh::generate::{box_mesh, HexSplit};
    let build = || {
        heml::system(box_mesh([0.1, 0.04, 0.04], [6, 3, 3], HexSplit::Six).unwrap())
            .material("neo_hookean", Params::from([("E", 3e3), ("nu", 0.49)]))
            .unwrap()
            .volumetric(Volumetric::nodal())
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
        "backward Euler vs static (nodal): relative difference {err:.2e}, sag {:.3e} m",
        max_norm(&us)
    );
    // 3 s with mass damping 20/s: the transient has decayed by e^-30 (the slowest
    // mode included); the bound is the CG/Newton tolerance of the steps (1e-6)
    assert!(err < 1e-3, "relative difference {err:e}");
}
