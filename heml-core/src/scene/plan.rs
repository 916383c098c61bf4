//! What a run will cost, decided before it starts: steps, frames, CSV rows and output
//! bytes, checked against the warning thresholds and hard limits of `[solver]` and
//! `[output]` — so that `duration = 1e5, dt = 1e-6` (months of stepping) or
//! `every = 1` over 1e5 steps (tens of gigabytes of frames) is refused or at least
//! announced instead of starting silently.

use crate::io::{FieldPrecision, VtuEncoding};

/// Default `[solver] warn_steps`: a million steps is minutes to hours on a large mesh.
pub const DEFAULT_WARN_STEPS: u64 = 1_000_000;
/// Default `[solver] max_steps`: 1e8 steps is days even on a small mesh.
pub const DEFAULT_MAX_STEPS: u64 = 100_000_000;
/// Default `[output] warn_output_bytes`: 1 GB.
pub const DEFAULT_WARN_OUTPUT_BYTES: u64 = 1_000_000_000;
/// Default `[output] max_output_bytes`: 20 GB, more than a laptop's free disk.
pub const DEFAULT_MAX_OUTPUT_BYTES: u64 = 20_000_000_000;

/// The cost of a run, known before it starts ([`super::Simulation::plan`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RunPlan {
    /// Steps at the base step `dt` (an adaptive run takes more when the tissue
    /// stiffens).
    pub steps: u64,
    /// VTU frames (0 without VTU output).
    pub frames: u64,
    /// `energy.csv` rows (0 without CSV output).
    pub csv_rows: u64,
    /// Estimated bytes of all output files.
    pub est_bytes: u64,
    /// Whether the step adapts (`dt_policy = "adapt"`): `steps` is then a lower bound.
    pub adaptive: bool,
    /// Thresholds exceeded (steps or bytes), with the key that sets each.
    pub warnings: Vec<String>,
}

impl std::fmt::Display for RunPlan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}{} steps, {} frames, {} CSV rows, ~{} of output",
            if self.adaptive { "at least " } else { "" },
            self.steps,
            self.frames,
            self.csv_rows,
            human_bytes(self.est_bytes)
        )
    }
}

/// `1.2 GB`-style size.
pub fn human_bytes(b: u64) -> String {
    let b = b as f64;
    match b {
        b if b >= 1e9 => format!("{:.1} GB", b / 1e9),
        b if b >= 1e6 => format!("{:.1} MB", b / 1e6),
        b if b >= 1e3 => format!("{:.1} kB", b / 1e3),
        b => format!("{b} B"),
    }
}

/// Bytes of one VTU frame of the runner: positions (3 f64 per node, always), four
/// point vectors (displacement, velocity, force, reaction) and two cell scalars (J,
/// energy density) in the fields' precision, Int64 connectivity and offset, UInt8
/// type and Int32 tag per tet, base64 (4/3), plus ~1.2 kB of XML. Compressed frames
/// are bounded from above: the fields' mantissas hardly compress (counted whole) and
/// the integer arrays shrink at least 4× (measured 6–7× on the demo). Checked
/// against written runs in the tests.
pub fn frame_bytes(n_nodes: usize, n_tets: usize, encoding: VtuEncoding, precision: FieldPrecision) -> u64 {
    let width = match precision {
        FieldPrecision::Double => 8,
        FieldPrecision::Single => 4,
    };
    let (n, t) = (n_nodes as u64, n_tets as u64);
    let floats = 24 * n + 12 * width * n + 2 * width * t;
    let ints = (32 + 8 + 1 + 4) * t;
    let raw = match encoding {
        VtuEncoding::Base64Zlib => floats + ints / 4,
        _ => floats + ints,
    };
    raw / 3 * 4 + 1200
}

/// Bytes of one `energy.csv` row: 14 columns, numbers in `{:e}` form (up to 23
/// characters, ~15 on average: exact zeros are `0e0`).
pub const CSV_ROW_BYTES: u64 = 200;

/// `.pvd` entry per frame.
const PVD_ENTRY_BYTES: u64 = 96;

/// The limits a plan is checked against, with the scene keys that set them.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Limits {
    pub warn_steps: u64,
    pub max_steps: u64,
    pub warn_bytes: u64,
    pub max_bytes: u64,
}

/// The plan of a run of `steps` steps with a frame every `frame_every` and a row
/// every `csv_every` steps; `Err` names the limit exceeded and its key. `solver` and
/// `output` name the tables for messages.
#[allow(clippy::too_many_arguments)]
pub(crate) fn plan(
    steps: u64,
    (frame_every, csv_every): (u64, u64),
    (vtu, csv): (bool, bool),
    frame_size: u64,
    adaptive: bool,
    limits: Limits,
    (solver, output): (&str, &str),
) -> Result<RunPlan, String> {
    // frame 0, one per `frame_every` steps, and the last step's (the same one when
    // `frame_every` divides `steps`)
    let frames = if vtu { 1 + steps.div_ceil(frame_every) } else { 0 };
    let csv_rows = if csv { 1 + steps.div_ceil(csv_every) } else { 0 };
    let est_bytes = frames
        .saturating_mul(frame_size + PVD_ENTRY_BYTES)
        .saturating_add(csv_rows.saturating_mul(CSV_ROW_BYTES));
    let mut warnings = Vec::new();
    let at_least = if adaptive { "at least " } else { "" };
    if steps > limits.max_steps {
        return Err(format!(
            "{solver}: the run needs {at_least}{steps} steps (duration / dt), above max_steps = {}: \
             shorten `duration`, raise `dt`, or raise `max_steps` if you mean it",
            limits.max_steps
        ));
    }
    if est_bytes > limits.max_bytes {
        return Err(format!(
            "{output}: the run would write ~{} ({frames} frames, {csv_rows} CSV rows), above \
             max_output_bytes = {}: write fewer frames (`every`, `frame_interval`, `csv_every`) \
             or raise `max_output_bytes` if you mean it",
            human_bytes(est_bytes),
            human_bytes(limits.max_bytes)
        ));
    }
    if steps > limits.warn_steps {
        warnings.push(format!(
            "{solver}: the run needs {at_least}{steps} steps (above warn_steps = {})",
            limits.warn_steps
        ));
    }
    if est_bytes > limits.warn_bytes {
        warnings.push(format!(
            "{output}: the run will write ~{} ({frames} frames, {csv_rows} CSV rows; above warn_output_bytes = {})",
            human_bytes(est_bytes),
            human_bytes(limits.warn_bytes)
        ));
    }
    Ok(RunPlan {
        steps,
        frames,
        csv_rows,
        est_bytes,
        adaptive,
        warnings,
    })
}
