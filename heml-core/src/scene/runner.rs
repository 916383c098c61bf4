//! Stepping a [`Simulation`] to its duration, with output and a progress callback.

use std::ops::ControlFlow;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use super::build::Simulation;
use super::output::Output;
use crate::error::{HemlError, Result};
use crate::system::{AdaptiveStep, DtReason, Energies, TimeStepPolicy};

/// Where a run is, passed to the progress callback after every step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Steps done.
    pub step: u64,
    /// Steps in the run.
    pub steps: u64,
    /// Simulated time.
    pub time: f64,
    /// Simulated time at the end of the run.
    pub duration: f64,
    /// Frames written so far.
    pub frames: usize,
    /// Conjugate-gradient iterations of the last step (0 for explicit integrators).
    pub cg_iterations: usize,
}

/// What a completed run did.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSummary {
    /// Steps taken.
    pub steps: u64,
    /// Final simulated time.
    pub time: f64,
    /// Step size asked for (the base step of an adaptive run).
    pub dt: f64,
    /// Smallest and largest step taken (both `dt` with a fixed step).
    pub dt_range: (f64, f64),
    /// Smallest J over the invariant regions seen by the adaptive step's checks
    /// (`None` with a fixed step).
    pub min_j: Option<f64>,
    /// The system's stable time-step estimate.
    pub stable_dt: f64,
    /// Wall-clock time of the run (output included).
    pub wall: Duration,
    /// VTU frames written.
    pub frames: usize,
    /// Write calls that went to `energy.csv` (header included): one per frame
    /// boundary with rows, however many rows.
    pub csv_writes: u64,
    /// Bytes written to `energy.csv`: its length, as it is appended, never rewritten.
    pub csv_bytes: u64,
    /// Largest nodal displacement at the end (m).
    pub max_displacement: f64,
    /// Energies at the end.
    pub energies: Energies,
    /// The output directory.
    pub out_dir: PathBuf,
    /// Whether the progress callback of [`Simulation::run_until`] ended the run
    /// before its duration.
    pub stopped: bool,
}

impl std::fmt::Display for RunSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let e = &self.energies;
        write!(
            f,
            "{}{} steps ({}), {:.4} s simulated in {:.2} s wall; {} frames in {}; \
             max displacement {:.4e} m; energies (J): kinetic {:.4e}, elastic {:.4e}, gravity {:.4e}, total {:.4e}",
            if self.stopped { "stopped early: " } else { "" },
            self.steps,
            match self.min_j {
                None => format!("dt = {:.3e} s", self.dt),
                Some(j) => format!(
                    "adaptive dt {:.3e}..{:.3e} s, min J {j:.3}",
                    self.dt_range.0, self.dt_range.1
                ),
            },
            self.time,
            self.wall.as_secs_f64(),
            self.frames,
            self.out_dir.display(),
            self.max_displacement,
            e.kinetic,
            e.elastic,
            e.gravity,
            e.total
        )
    }
}

impl Simulation {
    /// Runs to the duration: frame 0 at t = 0, then a frame every
    /// [`Simulation::frame_every`] steps and a CSV row every
    /// [`Simulation::csv_every`] steps (and both at the last step), calling
    /// `progress` after every step. The output directory is created.
    ///
    /// With `dt_policy = "adapt"` the step follows the stiffness ([`AdaptiveStep`],
    /// never above [`Simulation::dt`]); frames and rows are then written at the
    /// same simulated times as with the fixed step (`frame_every`·`dt` apart), the
    /// steps being shortened to land on them, and the run stops with an error
    /// after [`Simulation::max_steps`] steps.
    ///
    /// [`Simulation::warnings`] and [`Simulation::plan`] are the caller's to show
    /// (the dt warning is not repeated by the system). On a failed step (NaN/∞: the
    /// error names the step and the node) the system is back at its last good state
    /// — one whose positions, velocities and forces are all finite — which is
    /// written as a last frame (and the CSV flushed) before the error is returned.
    pub fn run(&mut self, mut progress: impl FnMut(&Progress)) -> Result<RunSummary> {
        self.run_until(|p| {
            progress(p);
            ControlFlow::Continue(())
        })
    }

    /// [`Simulation::run`] whose progress callback may end the run early by
    /// returning [`ControlFlow::Break`]: the state after that step is written as a
    /// last frame (and CSV row) and the summary says [`RunSummary::stopped`] — a
    /// user interface's stop button, a Ctrl-C seen by the caller, or a condition on
    /// the motion.
    ///
    /// (Not run here: heml-core's own doctests have no integrator registered; through
    /// the `heml` facade it runs as it is, and `tests/tests/suite/scene.rs` runs it.)
    ///
    /// ```no_run
    /// use std::ops::ControlFlow;
    /// let dir = std::env::temp_dir().join(format!("heml-doc-run-until-{}", std::process::id()));
    /// let scene = heml_core::scene::Scene::from_toml_str(
    ///     r#"
    ///     [mesh]
    ///     generate = { kind = "box", size = [0.1, 0.02, 0.02], cells = [4, 1, 1] }
    ///     [[material]]
    ///     energy = "mu/2*(I1-3) - mu*ln(J) + lam/2*ln(J).powi(2)"
    ///     params = { mu = 1e3, lam = 1e4 }
    ///     density = 1000.0
    ///     [[fix]]
    ///     plane = { point = [0, 0, 0], normal = [1, 0, 0] }
    ///     [loads]
    ///     gravity = [0, 0, -9.81]
    ///     [solver]
    ///     dt = 1e-4
    ///     duration = 1.0
    ///     [output]
    ///     vtu = false
    ///     "#,
    ///     ".",
    /// )?;
    /// let mut sim = scene.build()?;
    /// sim.out_dir = dir.clone();
    /// // stop after 25 of the 10 000 steps
    /// let summary = sim.run_until(|p| if p.step >= 25 { ControlFlow::Break(()) } else { ControlFlow::Continue(()) })?;
    /// assert!(summary.stopped && summary.steps == 25);
    /// assert!((summary.time - 25.0 * 1e-4).abs() < 1e-12);
    /// # std::fs::remove_dir_all(&dir).ok();
    /// # Ok::<(), heml_core::HemlError>(())
    /// ```
    pub fn run_until(&mut self, mut progress: impl FnMut(&Progress) -> ControlFlow<()>) -> Result<RunSummary> {
        let start = Instant::now();
        if self.dt > self.system.stable_dt() && self.dt_policy == TimeStepPolicy::Warn {
            // the warning is in `self.warnings` already
            self.system.set_time_step_policy(TimeStepPolicy::Ignore);
        }
        let mut out = Output::create(
            &self.out_dir,
            self.vtu,
            (self.vtu_encoding, self.vtu_precision),
            self.csv,
            &self.system,
            self.node_order.as_ref(),
            self.tools.iter().map(|t| (t.id, t.name.clone())).collect(),
        )?;
        let sys = &mut self.system;
        let event_tol = 1e-9 * self.dt;
        if let Err(e) = self.surgery.before_step(sys, event_tol) {
            return Err(fail(&mut out, sys, e));
        }
        if let Err(e) = sys.compute_forces() {
            return Err(fail(&mut out, sys, e));
        }
        // an implicit integrator's pattern and symbolic analysis, before the first step
        if let Err(e) = self.integrator.prepare(sys) {
            return Err(fail(&mut out, sys, e));
        }
        let mut adapt =
            (self.dt_policy == TimeStepPolicy::Adapt).then(|| AdaptiveStep::new(sys, self.dt, self.adapt_every));
        let first_reason = if adapt.is_some() {
            DtReason::Base
        } else {
            DtReason::Fixed
        };
        if out.wants_csv() {
            let e = sys.energies()?;
            out.row(sys, &e, self.dt, first_reason, 0);
        }
        out.frame(sys)?;
        out.flush_csv()?;
        // output times of the adaptive run: multiples of these spans
        let frame_span = self.frame_every as f64 * self.dt;
        let row_span = self.csv_every as f64 * self.dt;
        let tol = 1e-9 * self.dt;
        let (mut next_frame, mut next_row) = (1u64, 1u64);
        let (mut dt_min, mut dt_max) = (f64::INFINITY, 0.0_f64);
        let mut k = 0u64;
        let mut stopped = false;
        loop {
            k += 1;
            // the step taken, and the controller's step and reason (the CSV's: a step
            // shortened to land on an output time is not a decision of the controller)
            let (dt, chosen, reason) = match &mut adapt {
                None => (self.dt, self.dt, DtReason::Fixed),
                Some(a) => {
                    if k > self.max_steps {
                        let e = HemlError::Numerical(format!(
                            "the adaptive step needed more than max_steps = {} steps (t = {:e} s of {:e} s, \
                             dt = {:e} s): the tissue is too stiff for the step (raise `[solver] max_steps`, \
                             or soften the motion)",
                            self.max_steps,
                            sys.time(),
                            self.duration,
                            a.dt()
                        ));
                        return Err(fail(&mut out, sys, e));
                    }
                    let (dt, reason) = a.next(sys);
                    if dt < MIN_ADAPTIVE_FRACTION * self.dt {
                        let e = HemlError::Numerical(format!(
                            "the adaptive step fell to {dt:e} s, below {MIN_ADAPTIVE_FRACTION:e} of the base step \
                             {:e} s, at t = {:e} s: the tissue's stiffness ran away (a law far outside its \
                             range, or a crushed tet); soften the motion or check the material",
                            self.dt,
                            sys.time()
                        ));
                        return Err(fail(&mut out, sys, e));
                    }
                    let t = sys.time();
                    let stop = (next_frame as f64 * frame_span)
                        .min(next_row as f64 * row_span)
                        .min(self.duration);
                    // land on the stop in equal steps no longer than the
                    // controller's: the output times are evenly spaced, so the step
                    // stays constant while the controller's does. (Full steps then a
                    // shorter last one alternated two sizes every output time —
                    // every step or two with a CSV row per base step — and that
                    // periodic modulation pumped the modes it resonates with: a
                    // poked kidney at mass damping 20/s kept ~1e-5 J of jitter
                    // instead of coming to rest, and a crushed one diverged.)
                    let rem = stop - t;
                    let n = ((rem - tol) / dt).ceil().max(1.0);
                    (rem / n, dt, reason)
                }
            };
            if let Err(e) = script_step(&mut self.surgery, &self.tools, sys, dt, event_tol) {
                return Err(fail(&mut out, sys, e));
            }
            let stats = match self.integrator.step(sys, dt) {
                Ok(stats) => stats,
                Err(e) => return Err(fail(&mut out, sys, e)),
            };
            dt_min = dt_min.min(dt);
            dt_max = dt_max.max(dt);
            let (last, row_due, frame_due) = match adapt {
                None => {
                    let last = k == self.steps;
                    (
                        last,
                        k.is_multiple_of(self.csv_every) || last,
                        k.is_multiple_of(self.frame_every) || last,
                    )
                }
                Some(_) => {
                    let t = sys.time();
                    let due = |n: &mut u64, span: f64| {
                        let hit = t >= *n as f64 * span - tol;
                        while t >= *n as f64 * span - tol {
                            *n += 1;
                        }
                        hit
                    };
                    let last = t >= self.duration - tol;
                    (
                        last,
                        due(&mut next_row, row_span) || last,
                        due(&mut next_frame, frame_span) || last,
                    )
                }
            };
            if out.wants_csv() && row_due {
                let e = sys.energies()?;
                out.row(sys, &e, chosen, reason, stats.cg_iterations);
            }
            if frame_due {
                out.frame(sys)?;
                out.flush_csv()?;
            }
            let asked = progress(&Progress {
                step: k,
                steps: self.steps.max(k),
                time: sys.time(),
                duration: self.duration,
                frames: out.frames(),
                cg_iterations: stats.cg_iterations,
            });
            if last {
                break;
            }
            if asked.is_break() {
                // the state the run stops at is its last frame and row
                if out.wants_csv() && !row_due {
                    let e = sys.energies()?;
                    out.row(sys, &e, chosen, reason, stats.cg_iterations);
                }
                if !frame_due {
                    out.frame(sys)?;
                }
                out.flush_csv()?;
                stopped = true;
                break;
            }
        }
        let (csv_writes, csv_bytes) = out.csv_io();
        Ok(RunSummary {
            steps: k,
            time: sys.time(),
            dt: self.dt,
            dt_range: (dt_min, dt_max),
            min_j: adapt.as_ref().map(AdaptiveStep::min_j),
            stable_dt: sys.stable_dt(),
            wall: start.elapsed(),
            frames: out.frames(),
            csv_writes,
            csv_bytes,
            max_displacement: sys.displacements().iter().map(|d| d.norm()).fold(0.0, f64::max),
            energies: sys.energies()?,
            out_dir: self.out_dir.clone(),
            stopped,
        })
    }
}

/// The smallest adaptive step, as a fraction of the base step, before a run stops
/// with an error rather than grind on: the kidney crushed to a tenth of its height
/// needs 0.015 of it (`scenes/crush_kidney.toml`); an Ogden beam with α = 1000,
/// whose stiffness runs away, collapsed towards 0 and ran for minutes on a plan of
/// 23 steps.
const MIN_ADAPTIVE_FRACTION: f64 = 1e-4;

impl Simulation {
    /// What the scene scripts before a step of `dt` from the system's current time:
    /// the `[[cut]]`s whose time has come, the ramped `[[surface_load]]`s at their
    /// value now and the scripted `[[tool]]`s at their path's pose at the end of the
    /// step. [`Simulation::run`] does this before every step; a program that steps
    /// the system itself (say, `heml view`'s live loop) calls it so that the scene
    /// plays as it does in `heml run`. Returns whether a cut changed the mesh (its
    /// boundary surface then changed too).
    ///
    /// (Not run here: heml-core's own doctests have no integrator registered; through
    /// the `heml` facade it runs as it is, and `heml view`'s protocol test runs it.)
    ///
    /// ```no_run
    /// let scene = heml_core::scene::Scene::from_toml_str(
    ///     r#"
    ///     [mesh]
    ///     generate = { kind = "box", size = [0.04, 0.01, 0.01], cells = [4, 1, 1] }
    ///     [[material]]
    ///     energy = "mu/2*(I1-3) - mu*ln(J) + lam/2*ln(J).powi(2)"
    ///     params = { mu = 1e3, lam = 1e4 }
    ///     density = 1000.0
    ///     [[fix]]
    ///     plane = { point = [0, 0, 0], normal = [1, 0, 0] }
    ///     [solver]
    ///     dt = 1e-4
    ///     duration = 1.0
    ///     [[cut]]
    ///     time = 0.0
    ///     triangle = [[0.025, -0.1, 0.1], [0.025, 0.1, 0.1], [0.025, 0.0, -0.1]]
    ///     "#,
    ///     ".",
    /// )?;
    /// let mut sim = scene.build()?;
    /// let tets = sim.system.n_tets_alive();
    /// // stepping by hand: the cut at t = 0 comes with the first step
    /// assert!(sim.before_step(sim.dt)?);
    /// assert!(sim.system.n_tets_alive() < tets);
    /// let dt = sim.dt;
    /// sim.integrator.step(&mut sim.system, dt)?;
    /// assert!(!sim.before_step(dt)?);
    /// # Ok::<(), heml_core::HemlError>(())
    /// ```
    pub fn before_step(&mut self, dt: f64) -> Result<bool> {
        script_step(&mut self.surgery, &self.tools, &mut self.system, dt, 1e-9 * self.dt)
    }
}

/// [`Simulation::before_step`] on the simulation's parts (the run loop holds the
/// system borrowed); `tol`: how early a cut's time counts as come.
fn script_step(
    surgery: &mut super::Surgery,
    tools: &[super::tools::ScriptedTool],
    sys: &mut crate::system::System,
    dt: f64,
    tol: f64,
) -> Result<bool> {
    let cuts = surgery.reports.len();
    surgery.before_step(sys, tol)?;
    let t = sys.time();
    for tool in tools {
        sys.set_tool_pose(tool.id, tool.path.at(t + dt))?;
    }
    Ok(surgery.reports.len() != cuts)
}

/// Saves the last good state as a frame, flushes the CSV, and adds where to the
/// error.
fn fail(out: &mut Output, sys: &mut crate::system::System, e: HemlError) -> HemlError {
    let saved = match out.frame(sys) {
        // the system's error already names the state it kept (step and time)
        Ok(Some(path)) if e.to_string().contains("keeps its last good state") => {
            format!("; that state is saved as {}", path.display())
        }
        Ok(Some(path)) => format!(
            "; the last good state (step {}, t = {:e} s) is saved as {}",
            sys.step_count(),
            sys.time(),
            path.display()
        ),
        Ok(None) => String::new(),
        Err(w) => format!("; saving the last good state failed too: {w}"),
    };
    let flushed = match out.flush_csv() {
        Ok(()) => String::new(),
        Err(w) => format!("; writing the CSV failed: {w}"),
    };
    match e {
        HemlError::Numerical(msg) => HemlError::Numerical(format!("{msg}{saved}{flushed}")),
        HemlError::Invalid(msg) => HemlError::Invalid(format!("{msg}{saved}{flushed}")),
        other => HemlError::Numerical(format!("{other}{saved}{flushed}")),
    }
}
