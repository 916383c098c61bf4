//! Scene files: a whole simulation described in TOML — mesh (file or generator,
//! units), materials by registry name (per mesh tag, with Prony series), boundary
//! selections, loads, damping, integrator and time step, output — and the runner
//! that steps it and writes VTU frames, a `.pvd` series and an energy CSV.
//!
//! `scenes/example.toml` in the repository documents every key. In short:
//!
//! ```toml
//! [mesh]
//! generate = { kind = "beam", size = [0.1, 0.02, 0.02], cells = [10] }
//!
//! [[material]]
//! law = "neo_hookean"
//! params = { E = 5e3, nu = 0.45 }
//! density = 1000.0
//!
//! [[fix]]
//! plane = { point = [0, 0, 0], normal = [1, 0, 0] }
//!
//! [loads]
//! gravity = [0, 0, -9.81]
//!
//! [solver]
//! duration = 0.5
//! ```
//!
//! Parsing is strict: unknown keys and unknown enum values are errors with the file,
//! the line and the closest valid name. Everything else (law and integrator names,
//! parameters, selections that select nothing…) is checked by [`Scene::build`], whose
//! errors name the entry (`[[fix]] #2 (box)`) and its line.
//!
//! **Registries.** `heml-core` knows no laws or integrators: [`Scene::build`] looks
//! them up in the registry, which holds the built-in ones only when `heml-materials`
//! and `heml-integrators` are linked into the program. Programs use the `heml`
//! facade's `heml::scene::Scene`, whose `build` links them; code that uses this
//! crate alone must reference those crates itself.
//!
//! **Units.** Everything is SI (metres, kilograms, seconds, pascals, newtons)
//! except the coordinates of the mesh (and a generated mesh's `size`), which are
//! converted with `[mesh] units` or `scale`. Selections, displacements and
//! translations are in metres, on the converted mesh.

mod build;
mod exact;
mod fibre_expr;
mod fibres;
mod output;
mod parse;
mod plan;
mod runner;
mod schema;
mod select;
mod surgery;
mod tools;

pub use build::Simulation;
pub use output::CSV_HEADER;
pub use plan::{
    frame_bytes, human_bytes, RunPlan, CSV_ROW_BYTES, DEFAULT_MAX_OUTPUT_BYTES, DEFAULT_MAX_STEPS,
    DEFAULT_WARN_OUTPUT_BYTES, DEFAULT_WARN_STEPS,
};
pub use runner::{Progress, RunSummary};
pub use schema::{
    BoxSpec, Compression, DampingSpec, FixSpec, GenerateKind, GenerateSpec, HelixSpec, LoadsSpec, MaterialSpec,
    MeshSpec, NodalLoadSpec, OutputSpec, PlaneSpec, PrescribeSpec, SolverSpec, Units,
};
pub use select::Selection;
pub use surgery::{CutSpec, FacePlaneSpec, SurfaceLoadSpec, Surgery};
pub use tools::{KeyframeSpec, ScriptedTool, ToolPath, ToolShapeKind, ToolSpec};

use std::path::{Path, PathBuf};

use crate::error::{HemlError, Result};

/// A parsed scene file. Fields are public so that a program (or the CLI's
/// `--out`/`--duration` flags) can adjust a scene before [`Scene::build`].
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// `[mesh]`.
    pub mesh: MeshSpec,
    /// `[[material]]` entries (at least one).
    #[serde(rename = "material")]
    pub materials: Vec<MaterialSpec>,
    /// `[[fix]]` entries.
    #[serde(default)]
    pub fix: Vec<FixSpec>,
    /// `[[prescribe]]` entries.
    #[serde(default)]
    pub prescribe: Vec<PrescribeSpec>,
    /// `[loads]`.
    #[serde(default)]
    pub loads: LoadsSpec,
    /// `[damping]`.
    #[serde(default)]
    pub damping: DampingSpec,
    /// `[solver]`.
    pub solver: SolverSpec,
    /// `[output]`.
    #[serde(default)]
    pub output: OutputSpec,
    /// `[[cut]]` entries: blades applied when the run reaches their time.
    #[serde(default)]
    pub cut: Vec<CutSpec>,
    /// `[[surface_load]]` entries: pressure or traction on boundary faces.
    #[serde(default)]
    pub surface_load: Vec<SurfaceLoadSpec>,
    /// `[[tool]]` entries: rigid tools on keyframed paths.
    #[serde(default, rename = "tool")]
    pub tools: Vec<ToolSpec>,
    /// Directory that relative input paths (`[mesh] file`) are resolved against.
    #[serde(skip)]
    pub base_dir: PathBuf,
    /// Where the scene came from (a path, or a name like `demo.toml (embedded)`),
    /// for error messages.
    #[serde(skip)]
    pub origin: PathBuf,
    /// The TOML text, to give semantic errors a line number.
    #[serde(skip)]
    text: String,
    /// The lines of the text's `[[table]]` headers, by table, found in one pass when
    /// a message first needs one: rescanning the text per entry made loading a
    /// scene of n entries O(n²) (20 000 `[[loads.nodal]]` entries took 21 s).
    #[serde(skip)]
    headers: HeaderLines,
}

/// A cache of what the scene's text says (see `Scene::headers`): scenes compare
/// equal whether or not it is filled.
#[derive(Debug, Clone, Default)]
struct HeaderLines(std::sync::OnceLock<std::collections::HashMap<String, Vec<usize>>>);

impl PartialEq for HeaderLines {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Scene {
    /// Reads and parses a scene file; relative paths inside are resolved against
    /// the file's directory.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Scene> {
        let path = path.as_ref();
        // a scene is a few kB; 64 MB bounds a hostile one (a pipe or a device is
        // refused, not read forever)
        let bytes = crate::io::read_file(path, 64 << 20)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            HemlError::Invalid(format!(
                "{}: not UTF-8 text (byte {} is invalid); a scene is a TOML file",
                path.display(),
                e.utf8_error().valid_up_to()
            ))
        })?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Self::parse(&text, base, path.to_path_buf())
    }

    /// Parses scene text; relative paths inside are resolved against `base_dir`.
    /// Errors name the scene as `<scene>`.
    pub fn from_toml_str(text: &str, base_dir: impl Into<PathBuf>) -> Result<Scene> {
        Self::parse(text, base_dir.into(), PathBuf::from("<scene>"))
    }

    /// Parses scene text whose errors name `origin` (e.g. an embedded file).
    pub fn from_toml_str_named(text: &str, base_dir: impl Into<PathBuf>, origin: impl Into<PathBuf>) -> Result<Scene> {
        Self::parse(text, base_dir.into(), origin.into())
    }

    fn parse(text: &str, base_dir: PathBuf, origin: PathBuf) -> Result<Scene> {
        let mut scene: Scene = toml::from_str(text).map_err(|e| parse::toml_error(&origin, text, &e))?;
        scene.base_dir = base_dir;
        scene.origin = origin;
        scene.text = text.to_string();
        Ok(scene)
    }

    /// Names entry `index` (0-based) of the array of tables `table` for messages:
    /// `scene.toml:12: [[fix]] #2`.
    pub(crate) fn entry_name(&self, table: &str, index: usize) -> String {
        let headers = self.headers.0.get_or_init(|| parse::entry_lines(&self.text));
        match headers.get(table).and_then(|lines| lines.get(index).copied()) {
            Some(line) => format!("{}:{line}: [[{table}]] #{}", self.origin.display(), index + 1),
            None => format!("{}: [[{table}]] #{}", self.origin.display(), index + 1),
        }
    }

    /// Names the table `table` (e.g. `solver`) for messages, with its line.
    pub(crate) fn table_name(&self, table: &str) -> String {
        match parse::table_line(&self.text, table) {
            Some(line) => format!("{}:{line}: [{table}]", self.origin.display()),
            None => format!("{}: [{table}]", self.origin.display()),
        }
    }
}
