//! `heml bench --haptic`: the 1 kHz haptic loop (device, simulation and display
//! threads, `heml::system::contact::run_haptic_loop`) palpating the kidney meshes
//! gen_kidney_20k and gen_kidney_100k, with symplectic Euler (the explicit scheme
//! with one force evaluation per step, substepped at its stable step) and with
//! backward Euler (one step per device period).
//!
//! Each case runs once per way of running the device thread (module
//! [`super::device_tuning`] and `Timing::ALL`), in one go so that they share the
//! machine's load: sleeping to each tick or sleeping to 200–500 µs before it and
//! busy-waiting (`HapticOptions::device_spin`); at the normal scheduling priority,
//! with a short scheduler slice, or at a real-time one (SCHED_FIFO, when the OS
//! allows: Linux needs CAP_SYS_NICE or an rtprio limit); with the default timer
//! slack or 1 ns; the simulation on every CPU or on one fewer, the device pinned to
//! the CPU left free; and last with the process's memory locked. With fewer
//! simulation threads than CPUs the device thread is pinned to a CPU the
//! simulation's pinned pool leaves free.

use super::device_tuning;
use heml::integrators::{BackwardEuler, SymplecticEuler};
use heml::prelude::*;
use heml::system::contact::{run_haptic_loop_with, ContactLaw, HapticOptions, Palpation};
use heml::system::Integrator;
use std::path::PathBuf;
use std::sync::Mutex;
use thread_priority::{
    set_thread_priority_and_policy, thread_native_id, RealtimeThreadSchedulePolicy, ThreadPriority,
    ThreadSchedulePolicy,
};

/// Device time of each run (s), unless `--haptic-seconds` says otherwise.
pub const DEFAULT_SECONDS: f64 = 3.0;

/// Bounds of `--haptic-seconds`: a run shorter than 0.1 s has too few ticks for its
/// percentiles; ten minutes per run is already hours for the 22 runs of one mesh.
const SECONDS_RANGE: std::ops::RangeInclusive<f64> = 0.1..=600.0;

/// `seconds` if it is a device time `--haptic-seconds` accepts, else an error naming
/// the flag and the range.
pub fn checked_seconds(seconds: f64) -> heml::Result<f64> {
    if SECONDS_RANGE.contains(&seconds) {
        Ok(seconds)
    } else {
        Err(HemlError::Invalid(format!(
            "--haptic-seconds {seconds}: expected the device time of each run in seconds, from {} to {}",
            SECONDS_RANGE.start(),
            SECONDS_RANGE.end()
        )))
    }
}

/// The meshes: `mesh` alone, or the two kidneys of the shared collection.
fn meshes(mesh: Option<&PathBuf>) -> heml::Result<Vec<PathBuf>> {
    if let Some(m) = mesh {
        return Ok(vec![m.clone()]);
    }
    let dir = std::env::var_os("HEML_MESHES").map_or_else(|| PathBuf::from("../shared/meshes"), PathBuf::from);
    let list: Vec<PathBuf> = ["gen_kidney_20k.msh", "gen_kidney_100k.msh"]
        .iter()
        .map(|n| dir.join("msh").join(n))
        .collect();
    if let Some(missing) = list.iter().find(|p| !p.is_file()) {
        return Err(HemlError::Invalid(format!(
            "heml bench --haptic: {} not found (set HEML_MESHES to the shared mesh folder, or give --mesh)",
            missing.display()
        )));
    }
    Ok(list)
}

/// How the device thread gets the CPU.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Priority {
    /// SCHED_OTHER as created.
    Normal,
    /// SCHED_OTHER with a 100 µs slice (EEVDF wake-up preemption, Linux ≥ 6.12).
    Slice,
    /// SCHED_FIFO 50, when the OS allows (CAP_SYS_NICE or an rtprio limit).
    Fifo,
}

/// One way of running the device thread: its wait, its priority, its timer slack,
/// whether the simulation leaves it a CPU of its own, whether memory is locked.
#[derive(Debug, Clone, Copy)]
struct Timing {
    /// Busy-wait before each tick (s).
    spin: f64,
    priority: Priority,
    /// Timer slack 1 ns.
    slack: bool,
    /// The simulation runs on one thread fewer, pinned away from the device's CPU.
    own_cpu: bool,
    /// mlockall before the run (process-wide and kept: the last variant).
    lock: bool,
}

impl Timing {
    const fn new(spin: f64, priority: Priority, slack: bool) -> Self {
        Timing {
            spin,
            priority,
            slack,
            own_cpu: false,
            lock: false,
        }
    }

    /// The variants measured, in order (the memory lock stays on once taken, so it
    /// comes last).
    const ALL: [Timing; 11] = [
        Timing::new(0.0, Priority::Normal, false),
        Timing::new(2e-4, Priority::Normal, false),
        Timing::new(2e-4, Priority::Normal, true),
        Timing::new(2e-4, Priority::Slice, true),
        Timing::new(0.0, Priority::Slice, true),
        Timing::new(0.0, Priority::Fifo, false),
        Timing::new(2e-4, Priority::Fifo, false),
        Timing::new(5e-4, Priority::Fifo, true),
        Timing {
            own_cpu: true,
            ..Timing::new(0.0, Priority::Slice, true)
        },
        Timing {
            own_cpu: true,
            ..Timing::new(2e-4, Priority::Fifo, true)
        },
        Timing {
            lock: true,
            ..Timing::new(2e-4, Priority::Fifo, true)
        },
    ];

    /// How the device waits, for the report.
    fn wait(&self) -> String {
        if self.spin > 0.0 {
            format!("sleep + {:.0} µs spin", self.spin * 1e6)
        } else {
            "sleep".into()
        }
    }
}

/// Prepares the device thread: pins it to `cpu`, sets its timer slack and its
/// priority as `timing` says. Returns what it got, for the report.
fn device_setup(cpu: Option<core_affinity::CoreId>, timing: Timing) -> String {
    let mut got = Vec::new();
    if let Some(c) = cpu {
        if core_affinity::set_for_current(c) {
            got.push(format!("pinned to CPU {}", c.id));
        }
    }
    if timing.slack {
        got.push(device_tuning::timer_slack_1ns());
    }
    match timing.priority {
        Priority::Normal => got.push("normal priority".into()),
        Priority::Slice => got.push(format!("normal priority, {}", device_tuning::short_slice(100_000))),
        Priority::Fifo => {
            // mid-range FIFO priority: above every normal thread, below the kernel's
            // own real-time threads
            let fifo = ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo);
            let priority = ThreadPriority::Crossplatform(50u8.try_into().expect("within 0..=99"));
            match set_thread_priority_and_policy(thread_native_id(), priority, fifo) {
                Ok(()) => got.push("SCHED_FIFO".into()),
                Err(e) => got.push(format!("normal priority (SCHED_FIFO refused: {e})")),
            }
        }
    }
    got.join(", ")
}

/// Runs the loop for each device [`Timing`] on each mesh with both integrators, the
/// simulation on pools from `pool` (`threads` workers, pinned to the first CPUs
/// when `pinned`), `seconds` of device time each, and prints the reports.
pub fn run(
    mesh: Option<&PathBuf>,
    pool: &dyn Fn(usize) -> heml::Result<rayon::ThreadPool>,
    threads: usize,
    pinned: bool,
    seconds: f64,
) -> heml::Result<()> {
    outln!("haptic loop: 1 kHz device, {seconds} s of device time per run, {threads} simulation thread(s)");
    let cores = core_affinity::get_core_ids().unwrap_or_default();
    let all = pool(threads)?;
    // with a CPU of its own the device takes the last one the pinned pool leaves
    let fewer = if pinned && threads >= 2 {
        Some(pool(threads - 1)?)
    } else {
        None
    };
    let paths = meshes(mesh)?;
    for timing in Timing::ALL {
        let (pool, sim_threads) = match (&fewer, timing.own_cpu) {
            (Some(p), true) => (p, threads - 1),
            (None, true) => continue,
            (_, false) => (&all, threads),
        };
        // a CPU the pinned pool leaves free, for the device thread
        let free_cpu = if pinned { cores.get(sim_threads).copied() } else { None };
        let locked = if timing.lock {
            format!(", {}", device_tuning::lock_memory())
        } else {
            String::new()
        };
        outln!(
            "-- device {}, {sim_threads} simulation thread(s){locked} (load: {})",
            timing.wait(),
            load_average()
        );
        for path in &paths {
            let name = path
                .file_name()
                .map_or(path.display().to_string(), |n| n.to_string_lossy().into());
            for explicit in [true, false] {
                let mut sys = Palpation::tissue(read_mesh(path)?.0.scaled(1e-3)?)?; // millimetres
                let law = ContactLaw {
                    stiffness: 200.0,
                    damping: 0.002,
                };
                let (tool, palpation) = Palpation::on_top(&mut sys, 0.004, 0.01, law, 1.0)?;
                let (mut integrator, opts): (Box<dyn Integrator>, _) = if explicit {
                    (Box::new(SymplecticEuler), HapticOptions::explicit(&sys, seconds))
                } else {
                    (
                        Box::new(BackwardEuler::default()),
                        HapticOptions {
                            duration: seconds,
                            ..HapticOptions::default()
                        },
                    )
                };
                let opts = HapticOptions {
                    device_spin: timing.spin,
                    ..opts
                };
                let got = Mutex::new(String::new());
                let setup = || *got.lock().unwrap_or_else(|e| e.into_inner()) = device_setup(free_cpu, timing);
                let report = pool.install(|| {
                    run_haptic_loop_with(&mut sys, integrator.as_mut(), tool, |t| palpation.at(t), &opts, setup)
                })?;
                let got = got.into_inner().unwrap_or_else(|e| e.into_inner());
                outln!(
                    "{name} ({} tets), {}, device {}, {got}: {report}",
                    sys.mesh().n_tets(),
                    integrator.name(),
                    timing.wait()
                );
            }
        }
    }
    Ok(())
}

/// The 1-minute load average (`/proc/loadavg`), or "unknown".
pub(super) fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "unknown".into())
}
