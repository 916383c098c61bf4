//! The data of a scene file, as deserialized from TOML (see `scenes/example.toml`
//! for a fully commented file). Every table rejects unknown keys.

use serde::Deserialize;

use crate::error::{HemlError, Result};
use crate::mesh::generate::HexSplit;
use crate::params::Params;
use crate::system::{
    CgFailure, CholeskyOrdering, FactorPrecision, Integrator, LinearSolver, PronyTerm, Ramp, TimeStepPolicy,
};

/// Where the body comes from and how its coordinates map to metres.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// A mesh file (`.msh`, `.vtk`, `.vtu`, `.node`/`.ele`, `.mesh`), relative to the
    /// scene file's directory. Exactly one of `file` and `generate`.
    pub file: Option<String>,
    /// A generated box or beam.
    pub generate: Option<GenerateSpec>,
    /// Multiplies the mesh coordinates (and the generated `size`) to get metres.
    /// Exclusive with `units`.
    pub scale: Option<f64>,
    /// Length unit of the mesh coordinates (and of the generated `size`).
    pub units: Option<Units>,
    /// Translation in metres, applied after the scaling.
    #[serde(default, deserialize_with = "super::exact::opt_vec3")]
    pub translate: Option<[f64; 3]>,
    /// Hold nodes that belong to no tet in place (with a warning) instead of
    /// refusing the mesh.
    #[serde(default)]
    pub pin_unreferenced: bool,
    /// Store the nodes in Morton (Z-curve) order of their rest positions (default
    /// true): meshers write nodes in an order that makes the force loop jump around
    /// memory, and sorting them along the curve speeds force evaluation up (~20 % on
    /// a shuffled 1M-tet mesh). Node ids in the scene and in every output keep the
    /// file's numbering either way; `false` keeps the file order internally too
    /// (e.g. to compare).
    #[serde(default = "yes")]
    pub renumber: bool,
    /// How the hexahedra of a mesh file are cut into tets at load: `"six"`
    /// (default, conforming on any hex mesh), `"five"` (needs corners 2-colourable
    /// along the edges, as in a structured grid), `"ten"` (the same colouring, both
    /// five-tet cuttings overlapping, each tet weighted ½: no preferred diagonal) or
    /// `"twentyfour"` (adds face and cell centres, no preferred direction). Only for
    /// `file`: a generated mesh has `generate.split`.
    pub hex_split: Option<crate::mesh::generate::HexSplit>,
}

impl Default for MeshSpec {
    fn default() -> Self {
        MeshSpec {
            file: None,
            generate: None,
            scale: None,
            units: None,
            translate: None,
            pin_unreferenced: false,
            renumber: true,
            hex_split: None,
        }
    }
}

/// Length units of a mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Units {
    /// Metres.
    M,
    /// Centimetres.
    Cm,
    /// Millimetres.
    Mm,
    /// Micrometres.
    Um,
}

impl Units {
    /// Metres per unit.
    pub fn to_metres(self) -> f64 {
        match self {
            Units::M => 1.0,
            Units::Cm => 1e-2,
            Units::Mm => 1e-3,
            Units::Um => 1e-6,
        }
    }
}

/// Kind of generated mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GenerateKind {
    /// `[0, size.x] × [0, size.y] × [0, size.z]` with `cells = [nx, ny, nz]`.
    Box,
    /// A beam along x: `cells = [n]` cells along its length and as many across as
    /// keep the cells close to cubes (or `cells = [nx, ny, nz]` like a box).
    Beam,
}

/// A generated mesh.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GenerateSpec {
    /// `box` or `beam`.
    pub kind: GenerateKind,
    /// Extent along x, y, z (in the mesh units).
    #[serde(deserialize_with = "super::exact::vec3")]
    pub size: [f64; 3],
    /// Hexahedral cells: `[nx, ny, nz]`, or `[n]` along the length of a beam.
    pub cells: Vec<usize>,
    /// Tets per cell: `five`, `six` (default), `ten` (both five-tet cuttings, each
    /// tet weighted ½) or `twentyfour`.
    #[serde(default)]
    pub split: HexSplit,
    /// Largest number of tets to generate (default
    /// [`crate::mesh::generate::DEFAULT_MAX_GENERATED_TETS`], 50 million): a bigger
    /// mesh is refused, with its size, before anything is allocated.
    pub max_tets: Option<usize>,
}

/// One material: a registered law (or an energy given as text) with its
/// parameters, over one tag or all tets.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Registry name (`heml materials` lists them); empty when `energy` is given.
    #[serde(default)]
    pub law: String,
    /// An invariant energy w(I1, I2, J) in the language of `#[heml::material]`,
    /// compiled at load time ([`crate::RuntimeLaw`]), in place of `law`; its
    /// parameters are the names in `params`.
    pub energy: Option<String>,
    /// With `energy`: the law's volumetric energy U(J) as text (J and the names in
    /// `params`), which `volumetric = "nodal"` or `"patch"` evaluate at averaged
    /// volume ratios instead of the law along pure dilations
    /// ([`crate::RuntimeLaw::with_volumetric_energy`]).
    pub volumetric_energy: Option<String>,
    /// Parameters by name; laws with exactly `mu`, `lambda` also accept `E`, `nu`.
    #[serde(default)]
    pub params: Params,
    /// Density in kg/m³ (default 1000).
    pub density: Option<f64>,
    /// Mesh tag whose tets this material covers; absent: every tet that no tagged
    /// material claims.
    pub tag: Option<i32>,
    /// Prony series (visco-hyperelasticity): `[{ alpha = 0.3, tau = 0.1 }, …]`.
    #[serde(default)]
    pub prony: Vec<PronyTerm>,
    /// Volumetric formulation: `"element"` (standard), `"nodal"` or `"patch"`
    /// (anti-locking, for nearly incompressible tissue; `"patch"`: one volume per
    /// patch of 6 tets); default: `[solver] volumetric`, else `"element"`.
    pub volumetric: Option<String>,
    /// Stabilisation factor s of `volumetric = "nodal"` or `"patch"` (β = min(1, s·μ0/K0) of the
    /// element volumetric energy is kept; default 0.1, or `[solver]`'s).
    pub volumetric_stabilization: Option<f64>,
    /// Fibre laws: one or two constant fibre directions (rest frame) for the
    /// region, `[[1, 0, 0]]` or `[[1, 0, 0], [0, 1, 0]]`.
    #[serde(default, deserialize_with = "super::exact::opt_rows")]
    pub fibres: Option<Vec<[f64; 3]>>,
    /// Fibre laws: two helical families around an axis, at ±`angle` degrees from
    /// the circumferential direction at each tet's rest centroid (vessel walls).
    pub fibre_helix: Option<HelixSpec>,
    /// Fibre laws: the names of one or two 3-component cell fields of the mesh file
    /// (VTU `CellData`) holding each tet's fibre directions.
    pub fibre_fields: Option<Vec<String>>,
    /// Fibre laws: one or two directions as expressions of the rest centroid's
    /// coordinates x, y, z (metres), one `[ax, ay, az]` triple per family, e.g.
    /// `[["-y", "x", "0"]]` (circumferential about z); normalised per tet.
    pub fibre_expressions: Option<Vec<[String; 3]>>,
}

/// `fibre_helix = { axis = [0, 0, 1], origin = [0, 0, 0], angle = 40 }`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HelixSpec {
    /// Direction of the axis (any length > 0).
    #[serde(deserialize_with = "super::exact::vec3")]
    pub axis: [f64; 3],
    /// A point of the axis (metres, default the origin).
    #[serde(default)]
    #[serde(deserialize_with = "super::exact::vec3")]
    pub origin: [f64; 3],
    /// Angle of the fibres to the circumferential direction, in degrees.
    pub angle: f64,
}

/// An axis-aligned box `min ≤ X ≤ max` (metres, inclusive up to 1e-9 of the mesh size).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    /// Lower corner.
    #[serde(deserialize_with = "super::exact::vec3")]
    pub min: [f64; 3],
    /// Upper corner.
    #[serde(deserialize_with = "super::exact::vec3")]
    pub max: [f64; 3],
}

/// The nodes within `tolerance` of a plane.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneSpec {
    /// A point of the plane (metres).
    #[serde(deserialize_with = "super::exact::vec3")]
    pub point: [f64; 3],
    /// Its normal (any length > 0).
    #[serde(deserialize_with = "super::exact::vec3")]
    pub normal: [f64; 3],
    /// Largest distance (metres) of a selected node; default 1e-6 × the mesh's
    /// bounding-box diagonal.
    pub tolerance: Option<f64>,
}

/// `[[fix]]`: nodes held at their rest position. Exactly one selector.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FixSpec {
    /// Node ids (0-based).
    pub nodes: Option<Vec<usize>>,
    /// Nodes inside a box.
    #[serde(rename = "box")]
    pub bbox: Option<BoxSpec>,
    /// Nodes on a plane.
    pub plane: Option<PlaneSpec>,
    /// Nodes of the tets with this mesh tag.
    pub tag: Option<i32>,
    /// The mesh file's node set of this name (e.g. `"boundary_condition"` of an
    /// OpenSurgSim `.ply`).
    pub node_set: Option<String>,
}

/// `[[prescribe]]`: nodes moved by `displacement` following `ramp`, or along
/// `keyframes`. Exactly one selector.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PrescribeSpec {
    /// Node ids (0-based).
    pub nodes: Option<Vec<usize>>,
    /// Nodes inside a box.
    #[serde(rename = "box")]
    pub bbox: Option<BoxSpec>,
    /// Nodes on a plane.
    pub plane: Option<PlaneSpec>,
    /// Nodes of the tets with this mesh tag.
    pub tag: Option<i32>,
    /// The mesh file's node set of this name (e.g. `"boundary_condition"` of an
    /// OpenSurgSim `.ply`).
    pub node_set: Option<String>,
    /// Full displacement (metres), reached when the ramp reaches 1. With `ramp`;
    /// exclusive with `keyframes`.
    #[serde(default, deserialize_with = "super::exact::opt_vec3")]
    pub displacement: Option<[f64; 3]>,
    /// Time profile: `{ kind = "linear"|"smooth", duration = s }`, `{ kind = "step" }`
    /// or `{ kind = "keyframes", points = [[t, r], …] }`.
    pub ramp: Option<Ramp>,
    /// Piecewise-linear displacement `[[t, ux, uy, uz], …]` (seconds, metres; times
    /// strictly increasing, held after the last; an implicit `[0, 0, 0, 0]` precedes
    /// a first time > 0): motions that go back down (press, hold, release). The
    /// displacements must lie along one direction (they scale one vector).
    #[serde(default, deserialize_with = "super::exact::opt_rows")]
    pub keyframes: Option<Vec<[f64; 4]>>,
}

/// `[[loads.nodal]]`: a total force shared equally by the selected nodes.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodalLoadSpec {
    /// Node ids (0-based).
    pub nodes: Option<Vec<usize>>,
    /// Nodes inside a box.
    #[serde(rename = "box")]
    pub bbox: Option<BoxSpec>,
    /// Nodes on a plane.
    pub plane: Option<PlaneSpec>,
    /// Nodes of the tets with this mesh tag.
    pub tag: Option<i32>,
    /// The mesh file's node set of this name (e.g. `"boundary_condition"` of an
    /// OpenSurgSim `.ply`).
    pub node_set: Option<String>,
    /// Total force (newtons), split equally over the selected nodes.
    #[serde(deserialize_with = "super::exact::vec3")]
    pub force: [f64; 3],
}

/// `[loads]`.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadsSpec {
    /// Gravity acceleration (m/s²), e.g. `[0, 0, -9.81]`; default none.
    #[serde(default, deserialize_with = "super::exact::opt_vec3")]
    pub gravity: Option<[f64; 3]>,
    /// Constant nodal forces.
    #[serde(default)]
    pub nodal: Vec<NodalLoadSpec>,
}

/// `[damping]`: Rayleigh damping −α m v − β K v.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DampingSpec {
    /// Mass-proportional α (1/s).
    #[serde(default)]
    pub mass: f64,
    /// Stiffness-proportional β (s).
    #[serde(default)]
    pub stiffness: f64,
}

/// `[solver]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    /// Registry name of the integrator (default `symplectic_euler`).
    #[serde(default = "default_integrator")]
    pub integrator: String,
    /// Time step (s); default: the stable estimate. The run uses
    /// `duration / ceil(duration / dt)` so that it ends exactly at `duration`.
    pub dt: Option<f64>,
    /// Simulated time (s).
    pub duration: f64,
    /// What a dt above the stable estimate does: `warn`, `refuse`, `ignore`, or
    /// `adapt` (follow the stiffness of the deformed tissue: the step is re-estimated
    /// every `adapt_every` steps, never above `dt` or the rest estimate). Default:
    /// `adapt` when the scene has `[[prescribe]]` motion (tools press tissue hard),
    /// `warn` otherwise.
    pub dt_policy: Option<TimeStepPolicy>,
    /// Steps between two re-estimates of the adaptive step (default 20).
    pub adapt_every: Option<u64>,
    /// Steps above which the run starts with a warning (default 1e6).
    pub warn_steps: Option<u64>,
    /// Steps above which the run is refused (default 1e8; an adaptive run stops
    /// with an error when it gets there).
    pub max_steps: Option<u64>,
    /// Safety factor of the stable estimate, in (0, 1] (default 0.9).
    pub safety: Option<f64>,
    /// Inversion threshold J0 of the laws, in (0, 1) (default 0.4).
    pub j0: Option<f64>,
    /// Implicit integrators: relative tolerance of the conjugate-gradient solves, in
    /// (0, 1) (default 1e-6).
    pub cg_tolerance: Option<f64>,
    /// Implicit integrators: CG iterations per linear solve at most (default 1000).
    pub cg_max_iterations: Option<usize>,
    /// Implicit integrators: what a CG solve that misses its tolerance does: `warn`
    /// (default) or `refuse`.
    pub cg_failure: Option<CgFailure>,
    /// Implicit integrators: Newton iterations per step at most, 1..=100 (default 1).
    pub newton_iterations: Option<usize>,
    /// Implicit integrators: relative residual at which Newton stops early (default 1e-6).
    pub newton_tolerance: Option<f64>,
    /// Implicit integrators: project each tet's stiffness to positive semi-definite
    /// (default true).
    pub project_psd: Option<bool>,
    /// Implicit integrators: the linear solver of the Newton steps, `"cg"` (default:
    /// preconditioned conjugate gradients) or `"cholesky"` (a sparse Cholesky factor
    /// reused across Newton iterations and steps while it keeps converging).
    pub linear_solver: Option<LinearSolver>,
    /// Implicit integrators with `linear_solver = "cholesky"`: the most nonzeros the
    /// factor may hold (default 5e7, 400 MB); a larger factor is refused.
    pub max_factor_nonzeros: Option<usize>,
    /// Implicit integrators with `linear_solver = "cholesky"`: the factor's
    /// fill-reducing ordering, `"auto"` (default: nested dissection from 3000
    /// unknowns on, node-graph AMD below), `"amd"`, `"node_amd"` or
    /// `"nested_dissection"`.
    pub cholesky_ordering: Option<CholeskyOrdering>,
    /// Implicit integrators with `linear_solver = "cholesky"`: the factor's
    /// precision, `"auto"` (default: f32 for time steps from 256 unknowns on, f64
    /// otherwise), `"f64"` or `"f32"`.
    pub factor_precision: Option<FactorPrecision>,
    /// Volumetric formulation of every material that does not set its own:
    /// `"element"` (default), `"nodal"` or `"patch"` (anti-locking).
    pub volumetric: Option<String>,
    /// Stabilisation factor of `volumetric = "nodal"` or `"patch"` for every material that does
    /// not set its own (default 0.1).
    pub volumetric_stabilization: Option<f64>,
}

impl SolverSpec {
    /// Applies the implicit-integrator keys to `integrator`; returns whether it is
    /// implicit. The keys are an error on an explicit integrator.
    pub(crate) fn configure_implicit(&self, integrator: &mut dyn Integrator, what: &str) -> Result<bool> {
        let given = [
            ("cg_tolerance", self.cg_tolerance.is_some()),
            ("cg_max_iterations", self.cg_max_iterations.is_some()),
            ("cg_failure", self.cg_failure.is_some()),
            ("newton_iterations", self.newton_iterations.is_some()),
            ("newton_tolerance", self.newton_tolerance.is_some()),
            ("project_psd", self.project_psd.is_some()),
            ("linear_solver", self.linear_solver.is_some()),
            ("max_factor_nonzeros", self.max_factor_nonzeros.is_some()),
            ("cholesky_ordering", self.cholesky_ordering.is_some()),
            ("factor_precision", self.factor_precision.is_some()),
        ];
        let name = integrator.name();
        let Some(settings) = integrator.implicit_settings_mut() else {
            if let Some((key, _)) = given.iter().find(|(_, g)| *g) {
                return Err(HemlError::Invalid(format!(
                    "{what}: `{key}` applies to implicit integrators (backward_euler, newmark), not `{name}`"
                )));
            }
            return Ok(false);
        };
        let mut s = *settings;
        s.cg_tolerance = self.cg_tolerance.unwrap_or(s.cg_tolerance);
        s.cg_max_iterations = self.cg_max_iterations.unwrap_or(s.cg_max_iterations);
        s.cg_failure = self.cg_failure.unwrap_or(s.cg_failure);
        s.newton_iterations = self.newton_iterations.unwrap_or(s.newton_iterations);
        s.newton_tolerance = self.newton_tolerance.unwrap_or(s.newton_tolerance);
        s.project_psd = self.project_psd.unwrap_or(s.project_psd);
        s.linear_solver = self.linear_solver.unwrap_or(s.linear_solver);
        s.max_factor_nonzeros = self.max_factor_nonzeros.unwrap_or(s.max_factor_nonzeros);
        s.cholesky_ordering = self.cholesky_ordering.unwrap_or(s.cholesky_ordering);
        s.factor_precision = self.factor_precision.unwrap_or(s.factor_precision);
        s.validate().map_err(|e| HemlError::Invalid(format!("{what}: {e}")))?;
        *settings = s;
        Ok(true)
    }
}

fn default_integrator() -> String {
    "symplectic_euler".into()
}

/// `[output]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Output directory, relative to the working directory (created if needed;
    /// default `heml-output`).
    pub dir: Option<String>,
    /// A frame every this many steps. Exclusive with `frame_interval`.
    pub every: Option<u64>,
    /// A frame every this many simulated seconds (rounded to whole steps).
    /// Default: 50 frames over the duration.
    pub frame_interval: Option<f64>,
    /// Write VTU frames and the `.pvd` series (default true).
    #[serde(default = "yes")]
    pub vtu: bool,
    /// Write `energy.csv` (default true).
    #[serde(default = "yes")]
    pub csv: bool,
    /// A CSV row every this many steps (default: 10 rows per frame).
    pub csv_every: Option<u64>,
    /// Estimated output size (bytes) above which the run starts with a warning
    /// (default 1e9).
    pub warn_output_bytes: Option<u64>,
    /// Estimated output size (bytes) above which the run is refused (default 2e10).
    pub max_output_bytes: Option<u64>,
    /// How the VTU frames store their arrays: `zlib` (default) or `none`.
    #[serde(default)]
    pub compression: Compression,
    /// Floating-point type of the frames' point and cell fields: `double` (default)
    /// or `single` (positions stay double either way).
    #[serde(default)]
    pub precision: crate::io::FieldPrecision,
}

/// `[output] compression`: zlib makes frames several times smaller (a demo run
/// wrote 79 MB uncompressed); ParaView, VTK and meshio read both.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Compression {
    /// zlib-compressed base64 (`vtkZLibDataCompressor`), the default.
    #[default]
    Zlib,
    /// Plain base64: faster to write, larger.
    None,
}

impl Compression {
    /// The VTU encoding that implements it.
    pub fn vtu_encoding(self) -> crate::io::VtuEncoding {
        match self {
            Compression::Zlib => crate::io::VtuEncoding::Base64Zlib,
            Compression::None => crate::io::VtuEncoding::Base64,
        }
    }
}

fn yes() -> bool {
    true
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            dir: None,
            every: None,
            frame_interval: None,
            vtu: true,
            csv: true,
            csv_every: None,
            compression: Compression::default(),
            precision: crate::io::FieldPrecision::default(),
            warn_output_bytes: None,
            max_output_bytes: None,
        }
    }
}
