//! Budgets of the issue that are not timings: memory per tet of the force field.
//! (Speed is measured by `heml bench` and the criterion benches, never asserted.)

use heml::force::ElasticForces;
use heml::law::*;
use heml::mesh::generate::box_of_about;
use heml::prelude::*;

/// The neo-Hookean HEML field of a ~100k-tet mesh holds at most 100 bytes per tet:
/// rest data, indices, block lists and the scratch buffers of the parallel path,
/// once they are allocated by a first evaluation.
#[test]
fn neo_hookean_field_fits_in_100_bytes_per_tet() {
    let mesh = box_of_about(100_000).unwrap();
    let law = NeoHookean::from_young(3e3, 0.45);
    let field = HemlField::new(law, &mesh, ForceOptions::default()).unwrap();
    let (_, f) = field.forces(mesh.nodes()).unwrap();
    assert!(f.iter().all(|v| v.norm() < 1e-9), "rest state should be force-free");
    let b = field.bytes_per_tet();
    assert!(b <= 100.0, "{b:.1} bytes per tet");
    // the accounting counts at least the rest data (7 f64) and the 4 local indices
    assert!(b >= 7.0 * 8.0 + 8.0, "{b:.1} bytes per tet is less than the rest data");
}
