//! Criterion bench of the anti-locking volumetric term (issue 18): a force
//! evaluation with `volumetric = "nodal"` next to the standard (element) one, for
//! neo-Hookean (I1 and J) and Mooney–Rivlin (Ī1, Ī2 and κ/2 (J−1)²) on a ~100k-tet
//! box, in one run so that the ratio is measured under the same load.
//!
//! Run with `cargo bench -p heml-validation --features criterion --bench nodal_volume`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use heml::law::Volumetric;
use heml::mesh::generate::box_of_about;
use heml::prelude::*;
use heml_validation::fixtures::{smooth_deformation, tissue_params};
use std::hint::black_box;
use std::time::Duration;

fn nodal_volume(c: &mut Criterion) {
    let mesh = box_of_about(100_000).expect("generated box");
    let x = smooth_deformation(&mesh);
    let opts = ForceOptions::default();
    for name in ["neo_hookean", "mooney_rivlin"] {
        let entry = heml::registry::find_material(name).expect("built-in law");
        let params = tissue_params(entry, 3e3, 0.49).expect("tissue parameters");
        let law = entry.instantiate(&params).expect("law");
        let mut group = c.benchmark_group(format!("volumetric/{name}"));
        group
            .warm_up_time(Duration::from_secs(1))
            .measurement_time(Duration::from_secs(4))
            .throughput(Throughput::Elements(mesh.n_tets() as u64));
        for v in [Volumetric::Element, Volumetric::nodal()] {
            let field = law
                .with_volumetric(v)
                .expect("invariant law")
                .force_field(&mesh, None, &opts)
                .expect("field");
            let mut f = vec![Vec3::zeros(); x.len()];
            let id = if v == Volumetric::Element { "element" } else { "nodal" };
            group.bench_function(BenchmarkId::new(id, "100k"), |b| {
                b.iter(|| {
                    f.fill(Vec3::zeros());
                    black_box(field.add_forces(black_box(&x), &mut f).expect("forces"))
                })
            });
        }
        group.finish();
    }
}

criterion_group!(benches, nodal_volume);
criterion_main!(benches);
