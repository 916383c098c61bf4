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

/// Operations of each built-in law's generated value-and-gradient kernel (the
/// `dw_fast` the batch kernels run per tet; leaves not counted, `max` and its
/// step as additions), against the counts before heml-symbolic gathered squares,
/// dropped the step of max(x, 0), moved parametric factors outwards, collected
/// common factors and chose reverse accumulation where it is smaller (session 14).
/// None may grow. HGO's bound: its energy alone takes 40 operations (two
/// isochoric I4, two `exp`, the volumetric term, 1/J for the chain), its
/// gradient the chain through each family's ψ_k = k1·E_k·exp(k2·E_k²) once
/// (reverse accumulation) and the sums for I1, I4_k, J: 67 when written, 70
/// leaves room for a rule that trades one product for reuse, far below the
/// 107 of forward differentiation before.
#[test]
fn generated_law_kernels_do_not_grow() {
    let before: &[(&str, u32)] = &[
        ("arruda_boyce", 79),
        ("fung_demiray", 26),
        ("gent", 27),
        ("holzapfel_gasser_ogden", 107),
        ("mooney_rivlin", 28),
        ("neo_hookean", 16),
        ("saint_venant_kirchhoff", 20),
        ("stable_neo_hookean", 27),
        ("ti_mooney_rivlin", 61),
        ("veronda_westmann", 38),
        ("yeoh", 44),
    ];
    for &(name, old) in before {
        let entry = heml::materials_list()
            .into_iter()
            .find(|e| e.name == name)
            .unwrap_or_else(|| panic!("{name} is not registered"));
        let law = (entry.build)(&vec![1.0; entry.params.len()]);
        let o = law.ops();
        let total = o.add + o.mul + o.div + o.func;
        println!("{name}: {total} operations (before {old}): {o:?}");
        assert!(total <= old, "{name}: {total} operations, {old} before");
    }
    let hgo = heml::materials_list()
        .into_iter()
        .find(|e| e.name == "holzapfel_gasser_ogden")
        .map(|e| (e.build)(&vec![1.0; e.params.len()]).ops())
        .unwrap();
    assert!(hgo.add + hgo.mul + hgo.div + hgo.func <= 70, "{hgo:?}");
}
