//! A haptic loop: a device thread at a fixed rate (1 kHz) publishes a tool pose
//! and renders the force, the simulation runs on its own thread as fast as real
//! time allows, a display thread takes position snapshots at 30–60 Hz — all three
//! exchanging data through [`latest`] triple buffers, none waiting for another.
//!
//! **Multirate.** The device does not wait for the simulation: with each state the
//! simulation publishes a [`LocalModel`] (the tool force and its stiffness around
//! the tool's pose, [`StiffnessEstimator`]), and every device period the device
//! renders the newest model at its current pose ([`run_device`]). The device loop's
//! period is then the OS timer's, whatever a step costs; what a slow simulation
//! costs is the model's staleness and the error of the first-order extrapolation,
//! both measured ([`HapticReport`]).
//!
//! The device here is a stand-in: it follows a scripted path and records the force
//! it renders. The simulation thread picks up the newest pose, advances the system
//! by one device period T of simulated time (in substeps no longer than
//! [`HapticOptions::max_substep`], e.g. the explicit stable step, the simulated tool
//! following the device pose at most at [`HapticOptions::max_tool_speed`]),
//! publishes the tool's wrench, the local model and a snapshot when one is due,
//! then sleeps to the next period if it is ahead of real time.

use super::device::run_device;
use super::handoff::{haptic_link, latest};
use super::local_model::{LocalModel, StiffnessEstimator};
use super::tool::ToolId;
use crate::error::{HemlError, Result};
use crate::system::control::Pose;
use crate::system::{Integrator, System};
use crate::Vec3;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Settings of [`run_haptic_loop`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HapticOptions {
    /// Device rate (Hz); the simulation advances 1/rate per iteration (default 1000).
    pub device_rate: f64,
    /// Device time to run (s).
    pub duration: f64,
    /// Display snapshot rate (Hz), 30–60 for a screen (default 60).
    pub snapshot_rate: f64,
    /// Largest simulation step (s): each iteration takes ⌈T/max_substep⌉ equal
    /// substeps (default: one step per period; see [`HapticOptions::explicit`]).
    pub max_substep: f64,
    /// Fastest the simulated tool follows the device (m/s, default 0.25). The
    /// simulated tool is a proxy that moves towards the newest device pose by at
    /// most this speed × the device period, once per iteration: when the simulation falls behind real time
    /// the device pose jumps between iterations, and a tool teleported millimetres
    /// into the tissue would meet it with forces an explicit step cannot take.
    pub max_tool_speed: f64,
    /// Largest force the device renders (N, default 10: a desktop device's peak).
    pub max_force: f64,
    /// How long before each device tick the device thread stops sleeping and
    /// busy-waits (s, default 200 µs; 0: sleep only). An OS sleep wakes 50 µs to
    /// milliseconds late when the simulation fills the cores; the busy-wait costs
    /// this much CPU per period (20 % of a core at 1 kHz by default).
    pub device_spin: f64,
}

impl HapticOptions {
    /// Options for an explicit integrator on `sys`: substeps no longer than the
    /// stable step of the tissue and the tightest tool contact together,
    /// 1/√(1/dt_e² + 1/dt_c²) (the frequencies add: ω² = ω_e² + ω_c²), with dt_e
    /// the system's stable step and dt_c 0.9 × the contact's critical step on the
    /// lightest node ([`super::ContactLaw::critical_dt`]).
    pub fn explicit(sys: &System, duration: f64) -> Self {
        let m = sys
            .masses()
            .iter()
            .copied()
            .filter(|&m| m > 0.0)
            .fold(f64::INFINITY, f64::min);
        let contact = sys
            .tools()
            .ids()
            .filter_map(|id| sys.tools().get(id))
            .map(|t| t.law.critical_dt(m))
            .fold(f64::INFINITY, f64::min);
        HapticOptions {
            duration,
            max_substep: 1.0 / (sys.stable_dt().powi(-2) + (0.9 * contact).powi(-2)).sqrt(),
            ..HapticOptions::default()
        }
    }
}

impl Default for HapticOptions {
    fn default() -> Self {
        HapticOptions {
            device_rate: 1000.0,
            duration: 1.0,
            snapshot_rate: 60.0,
            max_substep: f64::INFINITY,
            max_tool_speed: 0.25,
            max_force: 10.0,
            device_spin: 2e-4,
        }
    }
}

/// Median, 99th percentile and maximum of a set of durations (s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Percentiles {
    /// Median.
    pub p50: f64,
    /// 99th percentile (nearest rank).
    pub p99: f64,
    /// Maximum.
    pub max: f64,
}

impl Percentiles {
    /// Of `samples` (sorted in place; all zero when empty).
    pub fn of(samples: &mut [f64]) -> Self {
        if samples.is_empty() {
            return Percentiles::default();
        }
        samples.sort_by(f64::total_cmp);
        let rank = |q: f64| samples[((q * samples.len() as f64).ceil() as usize).clamp(1, samples.len()) - 1];
        Percentiles {
            p50: rank(0.5),
            p99: rank(0.99),
            max: samples[samples.len() - 1],
        }
    }
}

impl std::fmt::Display for Percentiles {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
            self.p50 * 1e3,
            self.p99 * 1e3,
            self.max * 1e3
        )
    }
}

/// What a [`run_haptic_loop`] measured.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct HapticReport {
    /// Device ticks done.
    pub ticks: u64,
    /// Simulation iterations (one device period of simulated time each).
    pub iterations: u64,
    /// Substeps per iteration.
    pub substeps: usize,
    /// Simulated time at the end (s).
    pub sim_time: f64,
    /// Wall time of the run (s).
    pub wall: f64,
    /// Compute time of a simulation iteration (pose pickup, substeps, wrench and
    /// model publication).
    pub compute: Percentiles,
    /// Wall time between successive model publications.
    pub period: Percentiles,
    /// Wall time between successive device ticks: the haptic loop's period.
    pub device_period: Percentiles,
    /// Wall time a device tick spends reading and rendering the model.
    pub device_work: Percentiles,
    /// How late device ticks started after their deadlines (wake-up latency).
    pub device_late: Percentiles,
    /// Age of the model each device tick rendered (wall time since published).
    pub staleness: Percentiles,
    /// Fraction of device ticks that rendered a model newer than the previous tick's.
    pub fresh: f64,
    /// Relative error of each published model's force, extrapolated to the tool
    /// pose of the next state, against the force the simulation computed there
    /// (|F_model(x₁) − F₁| / |F₁|, over states whose force is at least 10 % of the
    /// run's peak: near lift-off the relative error of any predictor is meaningless).
    pub model_error: Percentiles,
    /// The same for a zero-order hold (the last force, no stiffness): the baseline.
    pub hold_error: Percentiles,
    /// The same with the contact stiffness of a still tissue
    /// ([`System::tool_stiffness`]) instead of the estimated one.
    pub still_error: Percentiles,
    /// The force the device rendered at each tick: (device time, force on the tool).
    pub forces: Vec<(f64, Vec3)>,
    /// The largest tool force (norm, N) the simulation published.
    pub peak_force: f64,
    /// Snapshots the display thread received.
    pub snapshots: u64,
    /// Their rate (Hz) over the run.
    pub snapshot_rate: f64,
    /// Wall time between the snapshots the display received.
    pub snapshot_interval: Percentiles,
}

impl HapticReport {
    /// Simulation steps (substeps) per wall second.
    pub fn steps_per_second(&self) -> f64 {
        (self.iterations * self.substeps as u64) as f64 / self.wall.max(f64::MIN_POSITIVE)
    }

    /// Simulated time per wall second (1: real time).
    pub fn real_time_factor(&self) -> f64 {
        self.sim_time / self.wall.max(f64::MIN_POSITIVE)
    }
}

/// `p50 a %, p99 b %` of relative errors.
fn percent(p: &Percentiles) -> String {
    format!("median {:.1} %, p99 {:.1} %", 100.0 * p.p50, 100.0 * p.p99)
}

impl std::fmt::Display for HapticReport {
    /// Five lines: counts and rates, the device loop, the simulation, staleness and
    /// model error, snapshots and forces.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let felt = self.forces.iter().map(|(_, f)| f.norm()).fold(0.0, f64::max);
        writeln!(
            f,
            "{} device ticks, {} iterations × {} substeps: {:.0} steps/s, {:.3} s simulated per wall s",
            self.ticks,
            self.iterations,
            self.substeps,
            self.steps_per_second(),
            self.real_time_factor()
        )?;
        writeln!(
            f,
            "  device period:  {} (late p50 {:.1} µs, p99 {:.1} µs; work per tick p99 {:.1} µs)",
            self.device_period,
            self.device_late.p50 * 1e6,
            self.device_late.p99 * 1e6,
            self.device_work.p99 * 1e6
        )?;
        writeln!(f, "  sim iteration:  {}", self.compute)?;
        writeln!(
            f,
            "  model age:      {}; fresh on {:.0} % of ticks; model error {} (hold {}, still-tissue K {})",
            self.staleness,
            100.0 * self.fresh,
            percent(&self.model_error),
            percent(&self.hold_error),
            percent(&self.still_error)
        )?;
        write!(
            f,
            "  {} snapshots ({:.1} Hz, interval p50 {:.1} ms, max {:.1} ms); peak force {:.4} N (rendered {felt:.4} N)",
            self.snapshots,
            self.snapshot_rate,
            self.snapshot_interval.p50 * 1e3,
            self.snapshot_interval.max * 1e3,
            self.peak_force
        )
    }
}

/// Relative errors of the previous model against a new state, per predictor.
#[derive(Default)]
struct Errors {
    /// (|F₁|, model, hold, still) per new state after a contact state.
    samples: Vec<(f64, f64, f64, f64)>,
}

impl Errors {
    fn add(&mut self, prev: &LocalModel, still: &nalgebra::Matrix3<f64>, new: &LocalModel) {
        if prev.force == Vec3::zeros() || new.force == Vec3::zeros() {
            return;
        }
        let n = new.force.norm();
        let dx = new.position - prev.position;
        let model = prev.force_at(new.position, f64::INFINITY);
        let still = prev.force + still * dx;
        self.samples.push((
            n,
            (model - new.force).norm() / n,
            (prev.force - new.force).norm() / n,
            (still - new.force).norm() / n,
        ));
    }

    /// Percentiles of each predictor over the states with |F₁| ≥ 10 % of `peak`.
    fn percentiles(&self, peak: f64) -> [Percentiles; 3] {
        let pick = |k: usize| {
            let mut v: Vec<f64> = self
                .samples
                .iter()
                .filter(|s| s.0 >= 0.1 * peak)
                .map(|s| [s.1, s.2, s.3][k])
                .collect();
            Percentiles::of(&mut v)
        };
        [pick(0), pick(1), pick(2)]
    }
}

/// Runs a device thread moving tool `tool` of `sys` along `path` (device time →
/// pose) for [`HapticOptions::duration`] and rendering the simulation's local
/// models, the simulation stepping with `integrator` on the calling thread's rayon
/// pool (wrap the call in a pool's `install` to choose it) and a display thread
/// reading snapshots. Returns when the device is done; the first simulation error
/// stops the loop and is returned. One warm-up step of the simulation precedes the
/// loop (one-time setup, such as an implicit integrator's operators, is not timed).
///
/// Snapshots are taken by the wall clock: after the first iteration that ends at
/// least 1/[`HapticOptions::snapshot_rate`] after the last snapshot, so a display
/// gets them at that rate whenever the simulation iterates faster, and after every
/// iteration when it iterates slower.
pub fn run_haptic_loop(
    sys: &mut System,
    integrator: &mut dyn Integrator,
    tool: ToolId,
    path: impl Fn(f64) -> Pose + Sync,
    opts: &HapticOptions,
) -> Result<HapticReport> {
    run_haptic_loop_with(sys, integrator, tool, path, opts, || {})
}

/// [`run_haptic_loop`], with `device_setup` called first on the device thread:
/// the place for what the library does not do itself, such as raising the
/// thread's scheduling priority or pinning it to a core (`heml bench --haptic`
/// gives it a real-time priority when the OS allows).
pub fn run_haptic_loop_with(
    sys: &mut System,
    integrator: &mut dyn Integrator,
    tool: ToolId,
    path: impl Fn(f64) -> Pose + Sync,
    opts: &HapticOptions,
    device_setup: impl FnOnce() + Send,
) -> Result<HapticReport> {
    let rate_ok = |r: f64| r.is_finite() && r > 0.0;
    if !(rate_ok(opts.device_rate) && rate_ok(opts.snapshot_rate) && rate_ok(opts.duration))
        || opts.max_tool_speed.is_nan()
        || opts.max_tool_speed <= 0.0
        || opts.max_substep.is_nan()
        || opts.max_substep <= 0.0
        || opts.max_force.is_nan()
        || opts.max_force <= 0.0
        || !(opts.device_spin.is_finite() && opts.device_spin >= 0.0)
    {
        return Err(HemlError::Invalid(format!(
            "haptic loop: rates, duration, max_substep, max_tool_speed and max_force must be > 0, device_spin finite and ≥ 0: {opts:?}"
        )));
    }
    let period = 1.0 / opts.device_rate;
    let substeps = ((period / opts.max_substep).ceil() as usize).max(1);
    let h = period / substeps as f64;
    let first = path(0.0);
    first.check()?;
    sys.set_tool_pose(tool, first)?;
    // one warm-up step before the clocks start: one-time setup (an implicit
    // integrator's tangent operators) is not part of the loop
    integrator.step(sys, h)?;
    let (mut device, mut sim) = haptic_link(first);
    // the simulated tool travels at most this far per iteration: the next state's
    // force is computed within it of the model's pose, and no further is vouched for
    let mut estimator = StiffnessEstimator::default();
    estimator.reach = opts.max_tool_speed * period;
    let mut model = estimator.model(sys, tool)?;
    let mut still = sys.tool_stiffness(tool)?;
    sim.publish_model(model);
    let (mut snap_tx, mut snap_rx) = latest((0.0f64, sys.positions().to_vec()));
    let frame = Duration::from_secs_f64(1.0 / opts.snapshot_rate);
    let spin = Duration::from_secs_f64(opts.device_spin);
    let done = AtomicBool::new(false);
    let ticks = (opts.duration * opts.device_rate).round() as u64;
    let start = Instant::now();
    let at = |k: f64| start + Duration::from_secs_f64(k * period);

    std::thread::scope(|s| -> Result<HapticReport> {
        let device_thread = s.spawn(|| {
            device_setup();
            let log = run_device(&mut device, &path, opts.device_rate, ticks, opts.max_force, start, spin);
            done.store(true, Ordering::Release);
            log
        });
        let display_thread = s.spawn(|| {
            // a display refreshing at twice the snapshot rate (a 120 Hz screen for
            // 60 Hz snapshots) sees each snapshot the simulation publishes
            let refresh = frame / 2;
            let mut received: Vec<Instant> =
                Vec::with_capacity((2.0 * opts.duration / frame.as_secs_f64()) as usize + 2);
            let mut next = Instant::now();
            while !done.load(Ordering::Acquire) {
                next += refresh;
                if let Some(wait) = next.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
                if snap_rx.updated() {
                    let (_, x) = snap_rx.read();
                    if !x.is_empty() {
                        received.push(Instant::now());
                    }
                }
            }
            received
        });

        let mut compute = Vec::with_capacity(ticks as usize);
        let mut periods = Vec::with_capacity(ticks as usize);
        let mut errors = Errors::default();
        let mut last_snapshot = start;
        let mut iterations = 0u64;
        let mut peak_force = 0.0f64;
        let mut last_publish: Option<Instant> = None;
        let mut error = None;
        while !done.load(Ordering::Acquire) {
            let t0 = Instant::now();
            let step = (|| -> Result<()> {
                // the proxy moves once per iteration (moving it every substep would
                // discard the forces each explicit step reuses from the last one)
                let target = sim.take().pose;
                let proxy = sys.tools().get(tool).map_or(target, |t| t.pose);
                let gap = (target.translation - proxy.translation).norm();
                let s = if gap > 0.0 {
                    (opts.max_tool_speed * period / gap).min(1.0)
                } else {
                    1.0
                };
                sys.set_tool_pose(tool, proxy.lerp(&target, s))?;
                for _ in 0..substeps {
                    integrator.step(sys, h)?;
                }
                sim.publish(sys, tool)?;
                let next = estimator.model(sys, tool)?;
                sim.publish_model(next);
                errors.add(&model, &still, &next);
                model = next;
                still = sys.tool_stiffness(tool)?;
                Ok(())
            })();
            if let Err(e) = step {
                error = Some(e);
                done.store(true, Ordering::Release);
                break;
            }
            let now = Instant::now();
            peak_force = peak_force.max(model.force.norm());
            compute.push((now - t0).as_secs_f64());
            if let Some(p) = last_publish {
                periods.push((now - p).as_secs_f64());
            }
            last_publish = Some(now);
            iterations += 1;
            if now >= last_snapshot + frame {
                last_snapshot = now;
                let time = sys.time();
                let x = sys.positions();
                snap_tx.publish_with(|(t, buf)| {
                    *t = time;
                    buf.clear();
                    buf.extend_from_slice(x);
                });
            }
            // real time at most: the next iteration starts at the next device period
            let next = at(iterations as f64);
            if next > Instant::now() {
                std::thread::sleep(next - Instant::now());
            }
        }
        let mut log = device_thread.join().expect("the device thread does not panic");
        let snapshot_times = display_thread.join().expect("the display thread does not panic");
        if let Some(e) = error {
            return Err(e);
        }
        let wall = start.elapsed().as_secs_f64();
        let [model_error, hold_error, still_error] = errors.percentiles(peak_force);
        Ok(HapticReport {
            ticks,
            iterations,
            substeps,
            sim_time: sys.time(),
            wall,
            compute: Percentiles::of(&mut compute),
            period: Percentiles::of(&mut periods),
            device_period: Percentiles::of(&mut log.gaps),
            device_work: Percentiles::of(&mut log.work),
            device_late: Percentiles::of(&mut log.late),
            staleness: Percentiles::of(&mut log.ages),
            fresh: log.fresh as f64 / ticks.max(1) as f64,
            model_error,
            hold_error,
            still_error,
            forces: log.forces.iter().map(|&(t, _, f)| (t, f)).collect(),
            peak_force,
            snapshots: snapshot_times.len() as u64,
            snapshot_rate: snapshot_times.len() as f64 / wall,
            snapshot_interval: Percentiles::of(
                &mut snapshot_times
                    .windows(2)
                    .map(|w| (w[1] - w[0]).as_secs_f64())
                    .collect::<Vec<_>>(),
            ),
        })
    })
}

#[cfg(test)]
mod tests {
    use super::Percentiles;

    #[test]
    fn percentiles_by_nearest_rank() {
        let mut v: Vec<f64> = (1..=200).rev().map(f64::from).collect();
        let p = Percentiles::of(&mut v);
        // nearest rank: the 100th and the 198th of 200 sorted values
        assert_eq!((p.p50, p.p99, p.max), (100.0, 198.0, 200.0));
        assert_eq!(Percentiles::of(&mut []), Percentiles::default());
    }
}

/// A scripted palpation, the stand-in for a surgeon's hand: a tool whose tip starts
/// `lift` above the surface point `top` (its local z the way down reversed, i.e. a
/// vertical capsule with its tip `tip` below its origin), pressing down to `depth`
/// below `top` and back up every `press_period` seconds while sweeping ±`sweep`
/// along x every `sweep_period` seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Palpation {
    /// The surface point pressed (m).
    pub top: Vec3,
    /// Distance from the tool's origin down to its tip (m): a capsule's
    /// half-length + radius.
    pub tip: f64,
    /// Start height of the tip above `top` (m).
    pub lift: f64,
    /// Deepest indentation below `top` (m).
    pub depth: f64,
    /// Period of one press (s).
    pub press_period: f64,
    /// Lateral amplitude along x (m).
    pub sweep: f64,
    /// Period of the sweep (s).
    pub sweep_period: f64,
}

impl Palpation {
    /// The body a palpation benchmark presses: soft tissue (neo-Hookean, E = 5 kPa,
    /// ν = 0.45, ρ = 1000 kg/m³, α = 15/s) clamped within 5 mm of its lowest point,
    /// without gravity (a soft organ sags by centimetres and would move away from
    /// the tool). The law is looked up in the registry: programs built on the `heml`
    /// facade have it. The haptic example and `heml bench --haptic` share it.
    pub fn tissue(mesh: crate::mesh::TetMesh) -> Result<System> {
        let low = mesh.nodes().iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
        let params = crate::Params::from([("E", 5e3), ("nu", 0.45)]);
        System::builder(mesh)
            .material("neo_hookean", &params)?
            .density(1000.0)
            .fix_where(|p| p.z < low + 0.005)
            .rayleigh(15.0, 0.0)
            .energy_every(0)
            .lazy_energy(true)
            .build()
    }

    /// Adds a vertical capsule (`radius`, `half_length`, contact `law`) above the
    /// highest surface node of `sys` and returns it with a palpation of that node:
    /// 2 mm lift, 4 mm deep, ±3 mm sweep, one press per `press_period` (the sweep
    /// takes twice as long). The haptic example and `heml bench --haptic` share it.
    pub fn on_top(
        sys: &mut System,
        radius: f64,
        half_length: f64,
        law: super::ContactLaw,
        press_period: f64,
    ) -> Result<(ToolId, Palpation)> {
        let x = sys.positions();
        let top = sys
            .surface()
            .nodes()
            .iter()
            .map(|&i| x[i as usize])
            .fold(Vec3::repeat(f64::NEG_INFINITY), |a, p| if p.z > a.z { p } else { a });
        let path = Palpation {
            top,
            tip: radius + half_length,
            lift: 0.002,
            depth: 0.004,
            press_period,
            sweep: 0.003,
            sweep_period: 2.0 * press_period,
        };
        let tool = super::Tool::capsule(radius, half_length, law).at(path.at(0.0));
        Ok((sys.add_tool(tool)?, path))
    }

    /// The pose at device time `t`.
    pub fn at(&self, t: f64) -> Pose {
        use std::f64::consts::TAU;
        let press = 0.5 * (1.0 - (TAU * t / self.press_period).cos());
        let z = self.top.z + self.tip + self.lift - (self.lift + self.depth) * press;
        let x = self.top.x + self.sweep * (TAU * t / self.sweep_period).sin();
        Pose::translation(Vec3::new(x, self.top.y, z))
    }
}
