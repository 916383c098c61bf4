//! Stepping a [`Simulation`] to its duration, with output and a progress callback.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use super::build::Simulation;
use super::output::Output;
use crate::error::{HemlError, Result};
use crate::system::{Energies, TimeStepPolicy};

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
    /// Step size used.
    pub dt: f64,
    /// The system's stable time-step estimate.
    pub stable_dt: f64,
    /// Wall-clock time of the run (output included).
    pub wall: Duration,
    /// VTU frames written.
    pub frames: usize,
    /// Largest nodal displacement at the end (m).
    pub max_displacement: f64,
    /// Energies at the end.
    pub energies: Energies,
    /// The output directory.
    pub out_dir: PathBuf,
}

impl std::fmt::Display for RunSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let e = &self.energies;
        write!(
            f,
            "{} steps (dt = {:.3e} s), {:.4} s simulated in {:.2} s wall; {} frames in {}; \
             max displacement {:.4e} m; energies (J): kinetic {:.4e}, elastic {:.4e}, gravity {:.4e}, total {:.4e}",
            self.steps,
            self.dt,
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
    /// [`Simulation::warnings`] are the caller's to show (the dt warning is not
    /// repeated by the system). On a failed step (NaN/∞: the error names the step
    /// and the node) the system is back at its last good state, which is written as
    /// a last frame (and the CSV flushed) before the error is returned.
    pub fn run(&mut self, mut progress: impl FnMut(&Progress)) -> Result<RunSummary> {
        let start = Instant::now();
        if self.dt > self.system.stable_dt() && self.dt_policy == TimeStepPolicy::Warn {
            // the warning is in `self.warnings` already
            self.system.set_time_step_policy(TimeStepPolicy::Ignore);
        }
        let mut out = Output::create(
            &self.out_dir,
            self.vtu,
            self.vtu_encoding,
            self.csv,
            &self.system,
            self.node_order.as_ref(),
        )?;
        let sys = &mut self.system;
        if let Err(e) = sys.compute_forces() {
            return Err(fail(&mut out, sys, e));
        }
        if out.wants_csv() {
            let e = sys.energies()?;
            out.row(sys, &e, 0);
        }
        out.frame(sys)?;
        out.flush_csv()?;
        for k in 1..=self.steps {
            let stats = match self.integrator.step(sys, self.dt) {
                Ok(stats) => stats,
                Err(e) => return Err(fail(&mut out, sys, e)),
            };
            let last = k == self.steps;
            if out.wants_csv() && (k % self.csv_every == 0 || last) {
                let e = sys.energies()?;
                out.row(sys, &e, stats.cg_iterations);
            }
            if k % self.frame_every == 0 || last {
                out.frame(sys)?;
                out.flush_csv()?;
            }
            progress(&Progress {
                step: k,
                steps: self.steps,
                time: sys.time(),
                duration: self.duration,
                frames: out.frames(),
                cg_iterations: stats.cg_iterations,
            });
        }
        Ok(RunSummary {
            steps: self.steps,
            time: sys.time(),
            dt: self.dt,
            stable_dt: sys.stable_dt(),
            wall: start.elapsed(),
            frames: out.frames(),
            max_displacement: sys.displacements().iter().map(|d| d.norm()).fold(0.0, f64::max),
            energies: sys.energies()?,
            out_dir: self.out_dir.clone(),
        })
    }
}

/// Saves the last good state as a frame, flushes the CSV, and adds where to the
/// error.
fn fail(out: &mut Output, sys: &mut crate::system::System, e: HemlError) -> HemlError {
    let saved = match out.frame(sys) {
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
