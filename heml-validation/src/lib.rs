//! The validation cases of the HEML seed papers, reproduced (`heml validate`).
//!
//! Each case compares HEML against an analytic solution, an independent
//! implementation or a documented expectation and returns a [`CaseReport`]: rows of
//! (quantity, HEML value, reference, error, tolerance, [`Status`]) and, when an
//! output folder is given, one PNG plot. Quasi-static cases state the convergence
//! criterion of [`heml::system::System::solve_static`] they reached.
//!
//! | name | what |
//! |---|---|
//! | `uniaxial` | unconstrained uniaxial tension/compression of a cube, SVK and neo-Hookean vs closed forms (seed Fig. 6) |
//! | `cantilever` | cantilever under gravity vs Euler–Bernoulli, mesh refinement and observed order |
//! | `p1_equivalence` | HEML vs the standard P1 path on the organ meshes, every law: force difference and time per evaluation (seed Table 4) |
//! | `op_count` | arithmetic operations per tet, HEML vs standard P1, every law (seed Table 3) |
//! | `mass_spring` | the mass–spring law vs classical springs |
//! | `prony` | Prony relaxation of a held step strain vs α(t) |
//! | `inversion` | an organ crushed through itself, held, released: min J, NaN count, return to rest |
//! | `energy` | undamped long runs per integrator: relative energy drift |
//! | `ogden` | unconstrained uniaxial loading of a cube, Ogden with Treloar's parameters vs the closed form |
//! | `locking` | cantilever over a ν sweep to 0.499, standard vs anti-locking (nodal-J) volumetric term, six-tet split and unstructured bar |
//!
//! ```no_run
//! use heml_validation::{run_case, Options, Status};
//! let report = run_case("prony", &Options::quick())?;
//! assert!(report.rows.iter().all(|r| r.status != Status::Fail));
//! println!("{}", heml_validation::format_table(&[report]));
//! # Ok::<(), heml::HemlError>(())
//! ```
//!
//! Organ meshes are read from `../shared/meshes` (see [`Options::meshes`]); when it is
//! absent the cases that need it say so in the table (status `SKIP`) instead of
//! passing silently.

mod cantilever;
mod energy;
mod equivalence;
mod fibre_tube;
mod fibres;
pub mod fixtures;
mod inversion;
pub mod locking;
mod mass_spring;
pub mod ogden;
pub mod plot;
mod prony;
mod uniaxial;

pub use equivalence::{heml_fixed_ops, p1_fixed_ops, ORGAN_MESHES};

use heml::HemlError;
use heml::{Params, Result, TetMesh};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Outcome of one row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// Within tolerance.
    Pass,
    /// Outside tolerance: `heml validate` exits non-zero.
    Fail,
    /// Reported for information (timings, documented behaviour), no criterion.
    Info,
    /// Could not run (e.g. the shared meshes are absent); said so rather than passed.
    Skip,
}

impl std::fmt::Display for Status {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Status::Pass => "pass",
            Status::Fail => "FAIL",
            Status::Info => "info",
            Status::Skip => "SKIP",
        })
    }
}

/// One line of the validation table.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// What is measured.
    pub quantity: String,
    /// HEML's value (formatted).
    pub heml: String,
    /// The reference value (formatted).
    pub reference: String,
    /// The error measure compared with the tolerance (relative unless stated).
    pub error: Option<f64>,
    /// The tolerance (formatted, e.g. `<= 1e-6` or `grows`).
    pub tolerance: String,
    /// Outcome.
    pub status: Status,
}

impl Row {
    /// A row checked as `error <= tol`.
    pub fn check(quantity: impl Into<String>, heml: String, reference: String, error: f64, tol: f64) -> Row {
        Row {
            quantity: quantity.into(),
            heml,
            reference,
            error: Some(error),
            tolerance: format!("<= {}", fmt_num(tol)),
            status: if error <= tol { Status::Pass } else { Status::Fail },
        }
    }
    /// An information row (no criterion).
    pub fn info(quantity: impl Into<String>, heml: String, reference: String) -> Row {
        Row {
            quantity: quantity.into(),
            heml,
            reference,
            error: None,
            tolerance: "-".into(),
            status: Status::Info,
        }
    }
    /// A row for something that could not run, with the reason in the HEML column.
    pub fn skip(quantity: impl Into<String>, reason: impl Into<String>) -> Row {
        Row {
            quantity: quantity.into(),
            heml: reason.into(),
            reference: "-".into(),
            error: None,
            tolerance: "-".into(),
            status: Status::Skip,
        }
    }
}

/// The result of one case.
#[derive(Debug, Clone)]
pub struct CaseReport {
    /// Case name (see [`CASES`]).
    pub name: &'static str,
    /// The rows.
    pub rows: Vec<Row>,
    /// Convergence criterion reached by the quasi-static solves (worst one), if any.
    pub criterion: Option<String>,
    /// Free-text remarks (mesh sizes, parameters…).
    pub notes: Vec<String>,
    /// The plot written, if any.
    pub plot: Option<PathBuf>,
    /// Wall time (s).
    pub seconds: f64,
}

impl CaseReport {
    fn new(name: &'static str) -> Self {
        CaseReport {
            name,
            rows: Vec::new(),
            criterion: None,
            notes: Vec::new(),
            plot: None,
            seconds: 0.0,
        }
    }
    /// Whether any row failed.
    pub fn failed(&self) -> bool {
        self.rows.iter().any(|r| r.status == Status::Fail)
    }
}

/// How the cases run.
#[derive(Debug, Clone)]
pub struct Options {
    /// Reduced resolution and shorter runs (the test suite's setting).
    pub quick: bool,
    /// Folder for the PNG plots (`None`: no plots).
    pub out_dir: Option<PathBuf>,
    /// Folder of the shared meshes (`msh/NAME.msh`); `None` searches
    /// `$HEML_MESHES`, `../shared/meshes` and `<repo>/../shared/meshes`.
    pub meshes: Option<PathBuf>,
}

impl Options {
    /// Full resolution, plots into `heml-validation-output/`.
    pub fn full() -> Self {
        Options {
            quick: false,
            out_dir: Some(PathBuf::from("heml-validation-output")),
            meshes: None,
        }
    }
    /// Reduced resolution, no plots.
    pub fn quick() -> Self {
        Options {
            quick: true,
            out_dir: None,
            meshes: None,
        }
    }

    /// The shared mesh folder, if it exists.
    pub fn mesh_dir(&self) -> Option<PathBuf> {
        let mut candidates = Vec::new();
        if let Some(p) = &self.meshes {
            return p.is_dir().then(|| p.clone());
        }
        if let Some(p) = std::env::var_os("HEML_MESHES") {
            candidates.push(PathBuf::from(p));
        }
        candidates.push(PathBuf::from("../shared/meshes"));
        candidates.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/meshes"));
        candidates.into_iter().find(|p| p.join("msh").is_dir())
    }

    fn plot_path(&self, name: &str) -> Result<Option<PathBuf>> {
        let Some(dir) = &self.out_dir else { return Ok(None) };
        std::fs::create_dir_all(dir).map_err(|e| HemlError::io(dir, e))?;
        Ok(Some(dir.join(format!("{name}.png"))))
    }
}

/// A validation case: name and one-line description.
#[derive(Debug, Clone, Copy)]
pub struct CaseInfo {
    /// Name for `--case`.
    pub name: &'static str,
    /// What it checks.
    pub title: &'static str,
    run: fn(&Options, &mut CaseReport) -> Result<()>,
}

/// Every case, in the order `heml validate` runs them.
pub const CASES: &[CaseInfo] = &[
    CaseInfo {
        name: "uniaxial",
        title: "unconstrained uniaxial tension/compression of a cube vs closed forms (SVK, neo-Hookean)",
        run: uniaxial::run,
    },
    CaseInfo {
        name: "fibres",
        title: "uniaxial cube along/across the fibres vs closed forms (Holzapfel-Gasser-Ogden, TI Mooney-Rivlin); HGO tube with helical fibres inflated by pressure vs a 1D reference",
        run: fibres::run,
    },
    CaseInfo {
        name: "cantilever",
        title: "cantilever under gravity vs Euler-Bernoulli, mesh refinement",
        run: cantilever::run,
    },
    CaseInfo {
        name: "p1_equivalence",
        title: "HEML vs standard P1 FEM on organ meshes, every law: forces and time per evaluation",
        run: equivalence::run_equivalence,
    },
    CaseInfo {
        name: "op_count",
        title: "arithmetic operations per tet, HEML vs standard P1, every law",
        run: equivalence::run_op_count,
    },
    CaseInfo {
        name: "mass_spring",
        title: "mass-spring law vs classical spring forces",
        run: mass_spring::run,
    },
    CaseInfo {
        name: "prony",
        title: "Prony relaxation of a held step strain vs alpha(t)",
        run: prony::run,
    },
    CaseInfo {
        name: "inversion",
        title: "organ crushed until elements invert, held, released",
        run: inversion::run,
    },
    CaseInfo {
        name: "energy",
        title: "undamped long runs per integrator: energy drift",
        run: energy::run,
    },
    CaseInfo {
        name: "ogden",
        title: "uniaxial tension/compression of a cube, Ogden (Treloar's rubber) vs closed form",
        run: ogden::run,
    },
    CaseInfo {
        name: "locking",
        title: "volumetric locking: cantilever over a Poisson-ratio sweep, element vs nodal volumetric term",
        run: locking::run,
    },
];

/// The case called `name`; the error lists the known cases.
pub fn find_case(name: &str) -> Result<&'static CaseInfo> {
    CASES.iter().find(|c| c.name == name).ok_or_else(|| {
        let known: Vec<&str> = CASES.iter().map(|c| c.name).collect();
        HemlError::Invalid(format!(
            "unknown validation case '{name}'; known cases: {}",
            known.join(", ")
        ))
    })
}

/// Runs the case `name`. An error inside a case (e.g. a solve that does not
/// converge) becomes a failing row rather than aborting, so that the table is
/// always complete; an unknown name is an error.
pub fn run_case(name: &str, opts: &Options) -> Result<CaseReport> {
    let info = find_case(name)?;
    let mut report = CaseReport::new(info.name);
    let start = Instant::now();
    if let Err(e) = (info.run)(opts, &mut report) {
        report.rows.push(Row {
            quantity: "case ran to completion".into(),
            heml: format!("error: {e}"),
            reference: "-".into(),
            error: None,
            tolerance: "-".into(),
            status: Status::Fail,
        });
    }
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}

/// Runs every case in [`CASES`] order.
pub fn run_all(opts: &Options) -> Vec<CaseReport> {
    CASES
        .iter()
        .map(|c| run_case(c.name, opts).expect("known case"))
        .collect()
}

/// A number formatted for the table: 4 significant digits, scientific when very
/// large or small.
pub fn fmt_num(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if !v.is_finite() {
        format!("{v}")
    } else if v.abs() >= 1e5 || v.abs() < 1e-3 {
        format!("{v:.3e}")
    } else {
        let digits = (3 - v.abs().log10().floor() as i32).clamp(0, 6) as usize;
        format!("{v:.digits$}")
    }
}

/// The table printed by `heml validate`: one line per row, then the criterion and
/// notes of each case.
pub fn format_table(reports: &[CaseReport]) -> String {
    let header = ["case", "quantity", "HEML", "reference", "error", "tolerance", "status"];
    let mut lines: Vec<[String; 7]> = Vec::new();
    for r in reports {
        for row in &r.rows {
            lines.push([
                r.name.to_string(),
                row.quantity.clone(),
                row.heml.clone(),
                row.reference.clone(),
                row.error.map_or("-".into(), fmt_num),
                row.tolerance.clone(),
                row.status.to_string(),
            ]);
        }
    }
    let mut width = header.map(|h| h.chars().count());
    for l in &lines {
        for (w, c) in width.iter_mut().zip(l) {
            *w = (*w).max(c.chars().count());
        }
    }
    let fmt_line = |cells: &[String]| {
        let mut s = String::new();
        for (k, (c, w)) in cells.iter().zip(&width).enumerate() {
            let pad = w - c.chars().count();
            if k == 0 || k == 1 || k == 6 {
                s.push_str(c);
                s.push_str(&" ".repeat(pad));
            } else {
                s.push_str(&" ".repeat(pad));
                s.push_str(c);
            }
            s.push_str("  ");
        }
        s.trim_end().to_string()
    };
    let mut out = String::new();
    out.push_str(&fmt_line(&header.map(String::from)));
    out.push('\n');
    out.push_str(&"-".repeat(width.iter().sum::<usize>() + 2 * (width.len() - 1)));
    out.push('\n');
    let mut prev = "";
    for l in &lines {
        if !prev.is_empty() && prev != l[0] {
            out.push('\n');
        }
        prev = reports.iter().find(|r| r.name == l[0]).map_or("", |r| r.name);
        out.push_str(&fmt_line(l));
        out.push('\n');
    }
    out.push('\n');
    for r in reports {
        let mut extra = Vec::new();
        if let Some(c) = &r.criterion {
            extra.push(format!("quasi-static criterion: {c}"));
        }
        extra.extend(r.notes.iter().cloned());
        if let Some(p) = &r.plot {
            extra.push(format!("plot: {}", p.display()));
        }
        extra.push(format!("time: {:.1} s", r.seconds));
        out.push_str(&format!("{}: {}\n", r.name, extra.join("; ")));
    }
    out
}

// ----- helpers shared by the cases ------------------------------------------------------

/// Parameters of `entry` with small-strain shear modulus `mu` and bulk modulus 3μ
/// (ν = 0.35), from [`crate::fixtures::soft_tissue_params`]; link laws get k = `mu`.
pub(crate) fn law_params(entry: &heml::registry::MaterialEntry, mu: f64) -> Params {
    let nu = 0.35;
    crate::fixtures::soft_tissue_params(entry.name, 2.0 * mu * (1.0 + nu), nu)
        .unwrap_or_else(|| entry.params.iter().fold(Params::new(), |p, info| p.with(info.name, mu)))
}

/// Reads `msh/NAME.msh` from the shared mesh folder.
pub(crate) fn shared_mesh(opts: &Options, name: &str) -> Result<Option<TetMesh>> {
    let Some(dir) = opts.mesh_dir() else { return Ok(None) };
    let path = dir.join("msh").join(format!("{name}.msh"));
    if !path.is_file() {
        return Ok(None);
    }
    Ok(Some(heml::io::read_mesh(&path)?.0))
}

/// max_i |a_i − b_i| / max_i |b_i|.
pub(crate) fn rel_max_diff(a: &[heml::Vec3], b: &[heml::Vec3]) -> f64 {
    let d = a.iter().zip(b).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
    let s = b.iter().map(|q| q.norm()).fold(0.0, f64::max);
    if s > 0.0 {
        d / s
    } else {
        d
    }
}

/// Keeps the worst (largest relative residual) criterion string.
pub(crate) fn worst_criterion(report: &mut CaseReport, r: &heml::system::StaticReport, worst: &mut f64) {
    if r.relative_residual() >= *worst {
        *worst = r.relative_residual();
        report.criterion = Some(r.criterion());
    }
}
