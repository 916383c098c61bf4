//! The anti-locking (nodal-J) volumetric formulation: forces are minus the energy
//! gradient for every invariant law, its tangent is the forces' derivative, the same
//! bits for any thread count, no spurious modes, bounded energy, and no locking.

use heml::law::Volumetric;
use heml::prelude::*;
use heml_tests::*;
use heml_validation::locking::{six_tet_beam, tip_ratio, Bar};

/// Forces are minus the energy gradient for every invariant law, and agree with
/// the P1 oracle (the grouped suite, [`heml_tests::grouped`]).
#[test]
fn nodal_forces_are_minus_the_energy_gradient_for_every_invariant_law() {
    grouped::forces_are_minus_the_energy_gradient([2, 2, 1], |_| Volumetric::nodal());
}

/// Every law that declares its volumetric energy U (`#[volumetric(...)]`) splits off
/// exactly the bulk stiffness it has along pure dilations — U(1) = U′(1) = 0 and
/// U″(1) = K0, the curvature of the law along F = J^(1/3)·I — so the element keeps
/// none at small strain whichever U the grouped terms use; U′ and U″ are U's
/// derivatives and the fast U, U′ the exact ones to round-off. A decoupled law (an
/// isochoric energy plus f(J)) declares exactly the law along dilations, at any J.
#[test]
fn declared_volumetric_energies_split_off_the_bulk_modulus() {
    use heml::force::Dilation;
    use heml::law::InvariantLaw;
    use heml::materials::*;
    fn check<M: InvariantLaw + Copy>(law: M, decoupled: bool) {
        let name = M::NAME;
        let u = |j: f64| law.volumetric(j).unwrap_or_else(|| panic!("{name} declares no U"));
        let dilation = Dilation::new(law);
        let k0 = dilation.along_dilations(1.0).2;
        // U″(1) against the dilation's curvature, which goes through J^(1/3) and the
        // law's own second derivatives: round-off of a few operations on values of
        // size K0 (1e-10 leaves four orders of margin)
        let [u0, u1, u2] = u(1.0);
        assert!(
            u0.abs() <= 1e-14 * k0 && u1.abs() <= 1e-14 * k0,
            "{name}: U(1) = {u0}, U'(1) = {u1}"
        );
        assert!((u2 - k0).abs() <= 1e-10 * k0, "{name}: U''(1) = {u2}, K0 = {k0}");
        for j in [0.6, 0.93, 1.0, 1.07, 1.4] {
            let [v, v1, v2] = u(j);
            // central differences, h = 1e-5: truncation h²·|U‴| ~ 1e-10·K0, round-off
            // 1e-16·|U|/h ~ 1e-12·K0; 1e-7·K0 catches any wrong derivative
            let h = 1e-5;
            let fd1 = (u(j + h)[0] - u(j - h)[0]) / (2.0 * h);
            let fd2 = (u(j + h)[1] - u(j - h)[1]) / (2.0 * h);
            assert!(
                (v1 - fd1).abs() <= 1e-7 * k0,
                "{name}: U'({j}) = {v1}, differences {fd1}"
            );
            assert!(
                (v2 - fd2).abs() <= 1e-7 * k0,
                "{name}: U''({j}) = {v2}, differences {fd2}"
            );
            // the fast ln/exp/powf are within a few ulps of the exact ones
            let (f0, f1) = law.volumetric_fast(j).unwrap();
            assert!(
                (f0 - v).abs() <= 1e-13 * k0 && (f1 - v1).abs() <= 1e-13 * k0,
                "{name}: fast U at {j}"
            );
            if decoupled {
                // Ī1 = Ī2 = 3 along dilations up to rounding: the same U to round-off
                let (d0, d1, _) = dilation.along_dilations(j);
                assert!(
                    (d0 - v).abs() <= 1e-12 * k0 && (d1 - v1).abs() <= 1e-12 * k0,
                    "{name}: U({j}) = {v} against {d0} along dilations"
                );
            }
        }
    }
    let (mu, lambda) = heml::params::lame(3e3, 0.49);
    let kappa = lambda + 2.0 * mu / 3.0;
    check(NeoHookean { mu, lambda }, false);
    check(
        MooneyRivlin {
            c10: 0.3 * mu,
            c01: 0.2 * mu,
            kappa,
        },
        true,
    );
    check(Gent { mu, jm: 50.0, kappa }, true);
    check(FungDemiray { a: mu, b: 0.8, kappa }, true);
    check(ArrudaBoyce { mu, lm: 3.0, kappa }, true);
    check(
        Yeoh {
            c1: mu / 2.0,
            c2: 0.1 * mu,
            c3: 0.01 * mu,
            kappa,
        },
        true,
    );
    check(
        VerondaWestmann {
            c1: mu / 0.8,
            c2: 0.8,
            kappa,
        },
        true,
    );
    // a law without a declaration leaves U to the dilation
    assert!(SaintVenantKirchhoff { mu, lambda }.volumetric(1.0).is_none());
}

/// K·u from the tangent equals the directional derivative of −f, and the assembled
/// blocks sum to the same product.
#[test]
fn nodal_tangent_is_the_derivative_of_the_forces() {
    grouped::tangent_is_the_derivative_of_the_forces(Volumetric::nodal());
}

/// The nodal term's passes (block driver, nodal pass, tangent) give the same bits
/// on 1, 2 and 3 threads.
#[test]
fn nodal_field_gives_the_same_bits_for_any_thread_count() {
    grouped::same_bits_for_any_thread_count(Volumetric::nodal());
}

/// The nodal term's batched pass (the lumped-volume sweep, the nodal pass four
/// nodes per vector, the element pass with the pressures from the node buffers'
/// padding slot) agrees with the tet-by-tet reference path, cut too, and gives the
/// same bits on every instruction set this CPU runs.
#[test]
fn nodal_field_gives_the_same_bits_on_every_instruction_set() {
    grouped::batched_pass_matches_the_reference_path(Volumetric::nodal());
}

/// The stiffness at rest of the nodal formulation at ν = 0.499 has exactly the six
/// rigid modes as (near-)zero eigenvalues on three meshes, with and without the
/// stabilisation.
#[test]
fn nodal_stiffness_at_rest_has_no_spurious_zero_modes() {
    let s = heml::force::nodal_volume::DEFAULT_STABILIZATION;
    grouped::rest_stiffness_has_no_spurious_zero_modes(&[
        Volumetric::Nodal { stabilization: 0.0 },
        Volumetric::Nodal { stabilization: s },
    ]);
}

/// An undamped block at ν = 0.49 with the nodal term, held at its base and
/// plucked, keeps its total energy bounded: no spurious mode pumps energy.
#[test]
fn plucked_nodal_block_keeps_its_energy_bounded() {
    grouped::plucked_block_keeps_its_energy_bounded(Volumetric::nodal());
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
    for (nu, tol) in [(0.49, 0.10), (0.499, 0.15)] {
        let nodal = grouped::kept_deflection(Volumetric::nodal(), nu);
        let element = grouped::kept_deflection(Volumetric::Element, nu);
        eprintln!("nu = {nu}: nodal {nodal:.3}, element {element:.3} of their nu = 0 values");
        assert!(
            (nodal - 1.0).abs() <= tol,
            "nu = {nu}: nodal keeps {nodal:.3} of its nu = 0 deflection"
        );
        // the standard term locks (the contrast that makes the test meaningful)
        assert!(element < 0.2, "nu = {nu}: element keeps {element:.3}");
    }
}

/// The nu sweep of the anti-locking guide on the 1 920- and the 15 360-tet six-tet beams
/// (printed; `HEML_S` = comma-separated stabilisation factors, default the default).
#[test]
#[ignore = "a minute: the anti-locking guide's nu sweep on 15 360 tets"]
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
/// 1 and 2 threads in one run (printed, not asserted: the anti-locking guide's benchmark;
/// evaluations interleaved so that both see the same machine load; median and range
/// of 40 each).
#[test]
#[ignore = "timing, for the anti-locking guide"]
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
#[ignore = "timing, for the anti-locking guide"]
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

/// Backward Euler with the nodal term settles on the static solution of the same
/// system (a soft block at ν = 0.49 sagging under gravity, dt = 10 ms).
#[test]
fn implicit_steps_with_the_nodal_term_reach_the_static_solution() {
    grouped::implicit_steps_reach_the_static_solution(Volumetric::nodal());
}
