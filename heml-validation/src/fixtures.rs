//! Fixtures shared by the validation cases, `heml bench`, the criterion benches and
//! the test crates: soft-tissue parameters for any registered law, smooth test
//! deformations, and deterministic shuffles of a mesh's numbering. One copy each, so
//! that every measurement runs on the same inputs.

use heml::law::LawKind;
use heml::mesh::reorder::{morton_node_order, Permutation};
use heml::nalgebra::Matrix3;
use heml::registry::MaterialEntry;
use heml::{Params, Result, TetMesh, Vec3};

/// Parameters of `entry` for soft tissue of Young's modulus `e` and Poisson's ratio
/// `nu` ([`heml::materials::soft_tissue_params`], matched to linear elasticity for
/// every built-in invariant law). A link law with a single parameter gets a spring
/// stiffness of `e` × 1 m / 300 per tet edge (10 N/m for 3 kPa, the value `heml
/// bench` has always used); any other law without built-in values gets `None`.
///
/// ```
/// let entry = heml::find_material("mass_spring")?;
/// let p = heml_validation::fixtures::tissue_params(entry, 3e3, 0.45).unwrap();
/// assert_eq!(p.get("k"), Some(10.0));
/// # Ok::<(), heml::HemlError>(())
/// ```
pub fn tissue_params(entry: &MaterialEntry, e: f64, nu: f64) -> Option<Params> {
    heml::materials::soft_tissue_params(entry.name, e, nu).or_else(|| {
        (entry.kind == LawKind::Link && entry.params.len() == 1)
            .then(|| Params::new().with(entry.params[0].name, e / 300.0))
    })
}

/// A smooth deformation of `mesh` that inverts no element: 10 % stretch along x, a
/// 0.2 rad twist over the length, 2 % shear, scaled to the mesh's bounding box.
///
/// ```
/// let mesh = heml::mesh::generate::box_of_about(200)?;
/// let x = heml_validation::fixtures::smooth_deformation(&mesh);
/// assert_eq!(x.len(), mesh.n_nodes());
/// # Ok::<(), heml::HemlError>(())
/// ```
pub fn smooth_deformation(mesh: &TetMesh) -> Vec<Vec3> {
    let (lo, hi) = mesh.bounding_box();
    let size = hi - lo;
    let c = (lo + hi) / 2.0;
    mesh.nodes()
        .iter()
        .map(|p| {
            let q = p - c;
            let s = q.x / size.x.max(1e-300);
            let (sn, cs) = (0.2 * s).sin_cos();
            Vec3::new(
                c.x + 1.1 * q.x + 0.02 * q.y,
                c.y + cs * q.y - sn * q.z,
                c.z + sn * q.y + cs * q.z,
            )
        })
        .collect()
}

/// A smooth *large* deformation of `mesh`, scaled to its size: stretches 0.9–1.1,
/// shear, a 0.6 rad rotation and a sinusoidal bend of 2 % of the diagonal (the P1
/// equivalence case's deformation).
pub fn large_deformation(mesh: &TetMesh) -> Vec<Vec3> {
    let (lo, hi) = mesh.bounding_box();
    let c = (lo + hi) * 0.5;
    let d = (hi - lo).norm();
    let (s, co) = 0.6f64.sin_cos();
    let rot = Matrix3::new(co, -s, 0.0, s, co, 0.0, 0.0, 0.0, 1.0);
    let stretch = Matrix3::new(1.1, 0.08, 0.0, 0.0, 0.95, 0.05, 0.0, 0.0, 0.9);
    let f = rot * stretch;
    let k = 2.0 * std::f64::consts::PI / d;
    mesh.nodes()
        .iter()
        .map(|p| {
            let q = p - c;
            let bend = Vec3::new((k * q.y).sin(), (k * q.z).sin(), (k * q.x).sin()) * (0.02 * d);
            c + f * q + bend
        })
        .collect()
}

/// `mesh` with nodes and tets in a pseudo-random order (deterministic), as real
/// meshes often arrive.
///
/// ```
/// let mesh = heml::mesh::generate::box_of_about(200)?;
/// let s = heml_validation::fixtures::shuffled(&mesh)?;
/// assert_eq!(s.n_tets(), mesh.n_tets());
/// assert_ne!(s.nodes(), mesh.nodes());
/// # Ok::<(), heml::HemlError>(())
/// ```
pub fn shuffled(mesh: &TetMesh) -> Result<TetMesh> {
    let nodes = Permutation::pseudo_random(mesh.n_nodes(), 1);
    let tets = Permutation::pseudo_random(mesh.n_tets(), 2);
    mesh.renumbered(&nodes, &tets)
}

/// `mesh` with its nodes renumbered along a Morton curve, as the scene loader does.
pub fn renumbered_at_load(mesh: &TetMesh) -> Result<TetMesh> {
    mesh.renumbered(&morton_node_order(mesh), &Permutation::identity(mesh.n_tets()))
}
