//! Criterion benches of force evaluation (issue 5): every built-in law on generated
//! boxes of ~10k, ~100k and ~1M tets, and the standard P1 FEM path next to HEML for
//! every invariant law at ~100k tets. Fibre laws get the fibres of `heml bench`
//! ([`heml_validation::fixtures::with_bench_fibres`]).
//!
//! Run with `cargo bench -p heml-validation --features criterion --bench forces` (add
//! `-- --quick`, or a filter such as `-- neo_hookean`). Throughput is reported in
//! tets/s. Fields run in their default (parallel) assembly on rayon's global pool, i.e.
//! on all cores.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use heml::force::ElasticForces;
use heml::mesh::generate::box_of_about;
use heml::prelude::*;
use heml::registry::MaterialEntry;
use heml_validation::fixtures::{smooth_deformation as deformed, tissue_params, with_bench_fibres};
use std::hint::black_box;
use std::time::Duration;

/// Tet counts of every law (the largest with fewer samples), and the size at which
/// P1 runs beside HEML.
const SIZES: [(usize, &str); 2] = [(10_000, "10k"), (100_000, "100k")];
const LARGE: (usize, &str) = (1_000_000, "1M");
const P1_SIZE: (usize, &str) = (100_000, "100k");

/// Soft-tissue parameters (E = 3 kPa, ν = 0.45) as in `heml bench`; `None` for a law
/// without built-in parameters.
fn params_of(entry: &MaterialEntry) -> Option<Params> {
    tissue_params(entry, 3e3, 0.45)
}

/// Adds one benchmark `id` of `field.add_forces` at `x` to `group`.
fn bench_field(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    id: BenchmarkId,
    field: &dyn ElasticForces,
    x: &[Vec3],
) {
    let mut f = vec![Vec3::zeros(); x.len()];
    group.bench_function(id, |b| {
        b.iter(|| {
            f.fill(Vec3::zeros());
            black_box(field.add_forces(black_box(x), &mut f).expect("force evaluation"))
        })
    });
}

fn forces(c: &mut Criterion) {
    let opts = ForceOptions::default();
    let meshes: Vec<(TetMesh, &str)> = SIZES
        .iter()
        .map(|&(n, label)| (box_of_about(n).expect("generated box"), label))
        .collect();
    let large = box_of_about(LARGE.0).expect("generated box");

    for entry in heml::materials_list() {
        let Some(params) = params_of(entry) else { continue };
        // a fibre law is bound to one mesh's fibres: one instance per mesh
        let law_on = |mesh: &TetMesh| {
            let law = entry.instantiate(&params).expect("law with soft-tissue parameters");
            with_bench_fibres(law, mesh).expect("the benchmarks' fibres")
        };
        let mut group = c.benchmark_group(entry.name);
        group
            .warm_up_time(Duration::from_secs(1))
            .measurement_time(Duration::from_secs(3));
        for (mesh, label) in &meshes {
            let x = deformed(mesh);
            group.throughput(Throughput::Elements(mesh.n_tets() as u64));
            let law = law_on(mesh);
            let heml = law.force_field(mesh, None, &opts).expect("HEML field");
            bench_field(&mut group, BenchmarkId::new("heml", label), heml.as_ref(), &x);
            if *label == P1_SIZE.1 {
                if let Some(p1) = law.fem_field(mesh, None, &opts).expect("P1 field") {
                    bench_field(&mut group, BenchmarkId::new("p1", label), p1.as_ref(), &x);
                }
            }
        }
        {
            let x = deformed(&large);
            group
                .throughput(Throughput::Elements(large.n_tets() as u64))
                .sample_size(10)
                .warm_up_time(Duration::from_millis(500))
                .measurement_time(Duration::from_secs(2));
            let heml = law_on(&large).force_field(&large, None, &opts).expect("HEML field");
            bench_field(&mut group, BenchmarkId::new("heml", LARGE.1), heml.as_ref(), &x);
        }
        group.finish();
    }
}

criterion_group!(benches, forces);
criterion_main!(benches);
