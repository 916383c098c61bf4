//! The patch volumetric formulation (one volume per compact patch of about k tets):
//! forces are minus the energy gradient for every invariant law and agree with the
//! P1 oracle, its tangent is the forces' derivative, the same bits for any thread
//! count, no spurious zero modes at rest, and (measured) how far it unlocks.

use heml::law::Volumetric;
use heml::prelude::*;
use heml_tests::*;
use heml_validation::locking::{six_tet_beam, tip_ratio, Bar};

/// Forces are minus the energy gradient for every invariant law and patch sizes
/// 4, 6, 8, 5, and agree with the P1 oracle of the same partition (the grouped
/// suite, [`heml_tests::grouped`]).
#[test]
fn patch_forces_are_minus_the_energy_gradient_for_every_invariant_law() {
    grouped::forces_are_minus_the_energy_gradient([2, 2, 2], |seed| Volumetric::patch([4, 6, 8, 5][seed as usize]));
}

/// K·u from the tangent equals the directional derivative of −f, and the assembled
/// blocks sum to the same product.
#[test]
fn patch_tangent_is_the_derivative_of_the_forces() {
    grouped::tangent_is_the_derivative_of_the_forces(Volumetric::patch(6));
}

/// The patch term gives the same bits on 1, 2 and 3 threads (forces, energy, tangent
/// product): the patches come from the mesh only and their sums run in field order.
#[test]
fn patch_field_gives_the_same_bits_for_any_thread_count() {
    grouped::same_bits_for_any_thread_count(Volumetric::patch(6));
}

/// Patches are disjoint, cover the field, are face-connected groups of about k tets
/// and each lies in one block of the element field's layout.
#[test]
fn patches_partition_the_tets() {
    use heml::force::PatchVolume;
    let mut rng = rng(5);
    let meshes = [
        heml::mesh::generate::box_mesh([1.0, 1.0, 1.0], [10, 10, 10], heml::mesh::generate::HexSplit::Six).unwrap(),
        jittered_box(&mut rng, [6, 5, 4]),
    ];
    let (mu, lambda) = heml::params::lame(1e4, 0.49);
    let law = heml::materials::NeoHookean { mu, lambda };
    for mesh in &meshes {
        for k in [4, 6, 8] {
            let pv = PatchVolume::new(law, 0.9, k, mesh, None, ForceOptions::default()).unwrap();
            let patches = pv.patches();
            let mut seen = vec![false; mesh.n_tets()];
            let mut sizes = Vec::new();
            for p in &patches {
                sizes.push(p.len());
                for &t in p {
                    assert!(!std::mem::replace(&mut seen[t], true), "tet {t} in two patches");
                }
                // a patch left below k/2 joins a neighbour: several may join one
                assert!(p.len() < 3 * k, "patch of {} tets for k = {k}", p.len());
            }
            assert!(seen.iter().all(|&s| s), "a tet in no patch");
            let mean = mesh.n_tets() as f64 / patches.len() as f64;
            eprintln!(
                "{} tets, k = {k}: {} patches, mean {mean:.2}, min {}, max {}",
                mesh.n_tets(),
                patches.len(),
                sizes.iter().min().unwrap(),
                sizes.iter().max().unwrap()
            );
            // most patches are full: the mean is near k
            assert!(mean >= 0.8 * k as f64, "mean patch size {mean} for k = {k}");
        }
    }
}

/// The tip-deflection sweep of the anti-locking guide: element, nodal and patch (k = 4, 6, 8)
/// on the 1 920-tet six-tet beam and (when `HEML_BIG`) the 15 360-tet one, and on
/// the unstructured `ipc_bar` when ../shared/meshes has it (printed).
#[test]
#[ignore = "minutes: the anti-locking guide's patch nu sweep"]
fn patch_cantilever_nu_sweep() {
    let mut meshes = vec![("six-tet 40", six_tet_beam(40).unwrap(), Bar::BEAM)];
    if std::env::var("HEML_BIG").is_ok() {
        meshes.push(("six-tet 80", six_tet_beam(80).unwrap(), Bar::BEAM));
    }
    let bar = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/meshes/msh/ipc_bar.msh");
    let bar = if bar.is_file() {
        bar
    } else {
        std::path::PathBuf::from("/work/shared/meshes/msh/ipc_bar.msh")
    };
    if bar.is_file() {
        meshes.push(("ipc_bar", heml::io::read_mesh(&bar).unwrap().0, Bar::IPC));
    }
    let ks: Vec<usize> = std::env::var("HEML_K")
        .map(|v| v.split(',').map(|s| s.parse().unwrap()).collect())
        .unwrap_or_else(|_| vec![4, 6, 8]);
    for (name, mesh, bar) in &meshes {
        let mut vs = vec![
            ("element".to_string(), Volumetric::Element),
            ("nodal".into(), Volumetric::nodal()),
        ];
        for &k in &ks {
            vs.push((format!("patch {k}"), Volumetric::patch(k)));
        }
        for (label, v) in &vs {
            let mut line = format!("{name} ({} tets) {label:<9}:", mesh.n_tets());
            let mut base = 0.0;
            for nu in [0.0, 0.45, 0.49, 0.499] {
                let t = std::time::Instant::now();
                let (r, _) = tip_ratio(mesh.clone(), *bar, nu, *v).unwrap();
                if nu == 0.0 {
                    base = r;
                    line += &format!(" nu0 {r:.4}");
                } else {
                    line += &format!(" | {nu}: {r:.4} ({:.3})", r / base);
                }
                line += &format!(" [{:.0}s]", t.elapsed().as_secs_f64());
            }
            eprintln!("{line}");
        }
    }
}

/// The block driver's two-phase pass (volumes, patch pressures and the element
/// kernel per block) agrees with the reference path, with tets removed too, and
/// gives the same bits on every instruction set this CPU runs.
#[test]
fn patch_fast_path_matches_the_reference_path() {
    grouped::batched_pass_matches_the_reference_path(Volumetric::patch(6));
}

/// The stiffness at rest at ν = 0.499 with the patch term has exactly the six rigid
/// modes as (near-)zero eigenvalues on five-tet, six-tet and jittered meshes, for
/// k = 4, 6, 8, with and without the stabilisation.
#[test]
fn patch_stiffness_at_rest_has_no_spurious_zero_modes() {
    let s = heml::force::nodal_volume::DEFAULT_STABILIZATION;
    let terms: Vec<Volumetric> = [4, 6, 8]
        .into_iter()
        .flat_map(|size| [0.0, s].map(|stabilization| Volumetric::Patch { size, stabilization }))
        .collect();
    grouped::rest_stiffness_has_no_spurious_zero_modes(&terms);
}

/// Backward Euler with the patch term settles on the static solution of the same
/// system (a soft block at ν = 0.49 sagging under gravity, dt = 10 ms).
#[test]
fn implicit_steps_with_the_patch_term_reach_the_static_solution() {
    grouped::implicit_steps_reach_the_static_solution(Volumetric::patch(6));
}

/// The 1 920-tet six-tet cantilever does not lock with the patch term (k = 6, the
/// default): measured 0.884 (ν = 0.49) and 0.845 (ν = 0.499) of its ν = 0 tip
/// deflection (nodal 0.933 / 0.875, element 0.175 / 0.027). On this coarse mesh
/// the bound at ν = 0.499 is 20 % (the 15 360-tet beam keeps 0.961 / 0.942, within
/// the 10 %: `patch_cantilever_nu_sweep` with `HEML_BIG`).
#[test]
fn cantilever_does_not_lock_with_the_patch_term() {
    for (nu, tol) in [(0.49, 0.15), (0.499, 0.2)] {
        let rel = grouped::kept_deflection(Volumetric::patch(6), nu);
        eprintln!("nu = {nu}: patch keeps {rel:.3} of its nu = 0 deflection");
        assert!((rel - 1.0).abs() <= tol, "nu = {nu}: patch keeps {rel:.3}");
    }
}

/// An undamped block at ν = 0.49 with the patch term, held at its base and
/// plucked, keeps its total energy bounded: no spurious mode pumps energy.
#[test]
fn plucked_patch_block_keeps_its_energy_bounded() {
    grouped::plucked_block_keeps_its_energy_bounded(Volumetric::patch(6));
}
