//! Fixtures shared by the validation cases, `heml bench`, the criterion benches and
//! the test crates: soft-tissue parameters for any registered law, smooth test
//! deformations, and deterministic shuffles of a mesh's numbering. One copy each, so
//! that every measurement runs on the same inputs.

use heml::law::LawKind;
use heml::mesh::reorder::{morton_node_order, Permutation};
use heml::nalgebra::Matrix3;
use heml::registry::MaterialEntry;
use heml::{Params, Result, TetMesh, Vec3};

/// Parameters of the registered law `law` whose small-strain behaviour is linear
/// elasticity with Young's modulus `e` and Poisson's ratio `nu`: `E` and `nu`, which
/// the law's declared small-strain mapping (`#[small_strain]`) turns into its own
/// parameters, plus its shape parameters at moderate soft-tissue values — Mooney–
/// Rivlin gives 30 % of the shear modulus to c01, Fung–Demiray and Veronda–Westmann
/// stiffen with exponent 1, Yeoh softens then stiffens (c2 = −μ/20, c3 = μ/40), Gent
/// locks at Jm = 50, Arruda–Boyce at λm = 3, Ogden takes Treloar's exponents (1.3, 5,
/// −2) and moduli ratios (μ2 = 0.0028 μ, μ3 = −0.0237 μ; Ogden 1972). `None` for laws without a mapping (link
/// laws: a spring stiffness depends on the mesh) or that need shape parameters this
/// table does not know.
///
/// ```
/// use heml_validation::fixtures::soft_tissue_params;
/// let p = soft_tissue_params("gent", 3e3, 0.45).unwrap();
/// assert_eq!((p.get("E"), p.get("nu"), p.get("jm")), (Some(3e3), Some(0.45), Some(50.0)));
/// assert!(soft_tissue_params("mass_spring", 3e3, 0.45).is_none());
/// ```
pub fn soft_tissue_params(law: &str, e: f64, nu: f64) -> Option<Params> {
    let entry = heml::find_material(law).ok()?;
    entry.small_strain.as_ref()?;
    let mu = e / (2.0 * (1.0 + nu));
    let shape: &[(&str, f64)] = match law {
        "mooney_rivlin" => &[("c01", 0.15 * mu)],
        "fung_demiray" => &[("b", 1.0)],
        "veronda_westmann" => &[("c2", 1.0)],
        "yeoh" => &[("c2", -mu / 20.0), ("c3", mu / 40.0)],
        "gent" => &[("jm", 50.0)],
        "arruda_boyce" => &[("lm", 3.0)],
        "ogden" => &[
            ("alpha1", 1.3),
            ("mu2", 0.0028 * mu),
            ("alpha2", 5.0),
            ("mu3", -0.0237 * mu),
            ("alpha3", -2.0),
        ],
        _ => &[],
    };
    let params = shape
        .iter()
        .fold(Params::from([("E", e), ("nu", nu)]), |p, (k, v)| p.with(k, *v));
    entry.instantiate(&params).ok().map(|_| params)
}

/// Parameters of `entry` for soft tissue of Young's modulus `e` and Poisson's ratio
/// `nu` ([`soft_tissue_params`]). A link law with a single parameter gets a spring
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
    soft_tissue_params(entry.name, e, nu)
        .or_else(|| {
            (entry.kind == LawKind::Link && entry.params.len() == 1)
                .then(|| Params::new().with(entry.params[0].name, e / 300.0))
        })
        .or_else(|| fibre_tissue_params(entry.name, e, nu))
}

/// Parameters of the built-in fibre laws for a matrix of small-strain moduli (E, ν)
/// reinforced by fibres of comparable stiffness (k1 = μ, k2 = 1 for HGO with
/// dispersion 0.1; c3 = μ/2, c4 = 10 for TI Mooney–Rivlin): soft tissue such as a
/// vessel wall or a tendon sheath, for benchmarks.
pub fn fibre_tissue_params(law: &str, e: f64, nu: f64) -> Option<Params> {
    let (mu, lambda) = heml::params::lame(e, nu);
    let k = lambda + 2.0 * mu / 3.0;
    let set: &[(&str, f64)] = match law {
        "holzapfel_gasser_ogden" => &[("c", mu), ("k1", mu), ("k2", 1.0), ("dispersion", 0.1), ("kappa", k)],
        "ti_mooney_rivlin" => &[
            ("c1", 0.4 * mu),
            ("c2", 0.1 * mu),
            ("c3", 0.5 * mu),
            ("c4", 10.0),
            ("kappa", k),
        ],
        _ => return None,
    };
    Some(set.iter().fold(Params::new(), |p, (n, v)| p.with(n, *v)))
}

/// `law` with the benchmarks' fibres when it has fibre families (unchanged when
/// not): two families in the x–y plane at ±30° from x, the same in every tet
/// (x is stretched by [`smooth_deformation`], so the fibres work in tension,
/// exponential included). A fibre law has no force field without its directions:
/// `heml bench` and the criterion benches call this before building fields.
///
/// ```
/// let mesh = heml::mesh::generate::box_of_about(200)?;
/// let params = heml_validation::fixtures::fibre_tissue_params("holzapfel_gasser_ogden", 3e3, 0.45).unwrap();
/// let law = heml::material("holzapfel_gasser_ogden", &params)?;
/// let law = heml_validation::fixtures::with_bench_fibres(law, &mesh)?;
/// assert!(law.force_field(&mesh, None, &Default::default()).is_ok());
/// # Ok::<(), heml::HemlError>(())
/// ```
pub fn with_bench_fibres(
    law: Box<dyn heml::heml_core::Material>,
    mesh: &TetMesh,
) -> Result<Box<dyn heml::heml_core::Material>> {
    if law.fibre_families() == 0 {
        return Ok(law);
    }
    let (s, c) = 30f64.to_radians().sin_cos();
    let dirs = [Vec3::new(c, s, 0.0), Vec3::new(c, -s, 0.0)];
    let fibres = heml::heml_core::fibres::Fibres::uniform(mesh.n_tets(), &dirs)?;
    law.with_fibres(std::sync::Arc::new(fibres))
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
