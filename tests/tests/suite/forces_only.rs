//! Forces without the energy (`ElasticForces::add_forces_only`, what explicit steps
//! evaluate with `SystemBuilder::lazy_energy`): the same bits as the forces of
//! `add_forces` for every law, field, instruction set, assembly and thread count,
//! with tets removed; and a lazy system steps exactly as an eager one.

use heml::force::{Assembly, SimdLevel};
use heml::heml_core::fibres::Fibres;
use heml::prelude::*;
use heml_tests::laws::all_laws_on;
use heml_tests::*;
use std::sync::Arc;

fn pool(n: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap()
}

/// The forces of `add_forces` and of `add_forces_only` at `x` on `threads` threads.
fn both(field: &dyn ElasticForces, x: &[Vec3], threads: usize) -> (Vec<Vec3>, Vec<Vec3>) {
    pool(threads).install(|| {
        let (mut a, mut b) = (vec![Vec3::zeros(); x.len()], vec![Vec3::zeros(); x.len()]);
        field.add_forces(x, &mut a).unwrap();
        field.add_forces_only(x, &mut b).unwrap();
        (a, b)
    })
}

/// Exact equality (the forces-only driver runs the same operations; the compiler
/// only drops what the energy alone needs, and Rust never contracts a multiply-add),
/// on a 1 134-tet jittered box (parallel blocks, a padded last batch), deformed so
/// that fibres are stretched and compressed, before and after a cut.
#[test]
fn forces_only_are_the_forces_bit_for_bit() {
    let _ = heml::materials_list();
    let mut rng = rng(7);
    let mesh = jittered_box(&mut rng, [9, 7, 3]);
    let x = random_deformation(&mut rng, &mesh, 0.7, 1.4, 0.02);
    let cut: Vec<usize> = (0..mesh.n_tets()).step_by(5).collect();
    let mut skipping = 0;
    for (name, law) in all_laws_on(&mesh, &mut rng) {
        let opts = ForceOptions::default();
        let mut fields = vec![law.force_field(&mesh, None, &opts).unwrap()];
        fields.extend(law.fem_field(&mesh, None, &opts).unwrap());
        for mut field in fields {
            for removed in [false, true] {
                if removed && field.remove_tets(&cut).is_err() {
                    continue;
                }
                for assembly in [Assembly::Reference, Assembly::Batched, Assembly::Parallel] {
                    field.set_assembly(assembly);
                    let skips = field.skips_energy();
                    assert!(
                        !skips || (assembly != Assembly::Reference && law.fibre_families() > 0),
                        "{name}: only the fibre laws' batched fields skip the energy"
                    );
                    skipping += usize::from(skips);
                    for level in SimdLevel::available() {
                        for threads in [1, 2] {
                            let (a, b) = level.run_with(|| both(field.as_ref(), &x, threads)).unwrap();
                            assert!(
                                a == b,
                                "{name} {assembly:?} {} {threads} thread(s), removed {removed}: \
                                 forces differ by {:e}",
                                level.name(),
                                max_diff(&a, &b)
                            );
                        }
                    }
                }
            }
        }
    }
    // the forces-only driver itself ran (HGO and TI Mooney–Rivlin, batched and parallel,
    // before and after the cut)
    assert!(skipping >= 8, "{skipping} field evaluations skipped the energy");
}

/// A Holzapfel–Gasser–Ogden strip under gravity, 60 symplectic Euler steps with and
/// without `lazy_energy`: the same positions, bit for bit, and the energy the lazy
/// system evaluates when asked is the eager system's.
#[test]
fn a_lazy_system_steps_as_an_eager_one() {
    let _ = (heml::materials_list(), heml::integrators_list());
    let mesh =
        heml::mesh::generate::box_mesh([0.04, 0.01, 0.01], [8, 2, 2], heml::mesh::generate::HexSplit::Six).unwrap();
    let fibres = Arc::new(Fibres::uniform(mesh.n_tets(), &[Vec3::new(1.0, 1.0, 0.0).normalize(), Vec3::x()]).unwrap());
    let law = || {
        heml::material(
            "holzapfel_gasser_ogden",
            &Params::from([
                ("c", 2e3),
                ("k1", 5e3),
                ("k2", 10.0),
                ("dispersion", 0.1),
                ("kappa", 5e4),
            ]),
        )
        .unwrap()
        .with_fibres(fibres.clone())
        .unwrap()
    };
    let run = |lazy: bool| {
        let mut sys = heml::system(mesh.clone())
            .material_law(law())
            .density(1000.0)
            .gravity(Vec3::new(0.0, 0.0, -9.81))
            .fix_where(|p| p.x < 1e-9)
            .energy_every(0)
            .lazy_energy(lazy)
            .build()
            .unwrap();
        let mut integ = heml::integrator("symplectic_euler").unwrap();
        let dt = 0.9 * sys.stable_dt();
        for _ in 0..60 {
            integ.step(&mut sys, dt).unwrap();
        }
        (sys.positions().to_vec(), sys.elastic_energy().unwrap())
    };
    let (x_eager, e_eager) = run(false);
    let (x_lazy, e_lazy) = run(true);
    assert!(
        x_eager == x_lazy,
        "positions differ by {:e}",
        max_diff(&x_eager, &x_lazy)
    );
    // the strip sagged: a non-trivial energy to compare
    assert!(e_eager > 0.0 && e_lazy == e_eager, "{e_lazy} vs {e_eager}");
}
