//! `heml bench --haptic`: the 1 kHz haptic loop (device, simulation and display
//! threads, `heml::system::contact::run_haptic_loop`) palpating the kidney meshes
//! gen_kidney_20k and gen_kidney_100k, with symplectic Euler (the explicit scheme
//! with one force evaluation per step, substepped at its stable step) and with
//! backward Euler (one step per device period).
//!
//! Each case runs once per way of timing the device thread, in one go so that they
//! share the machine's load: sleeping to each tick, or sleeping to 200 µs before
//! it and busy-waiting (`HapticOptions::device_spin`), each at the normal
//! scheduling priority and at a real-time one (SCHED_FIFO, when the OS allows:
//! Linux needs CAP_SYS_NICE or an rtprio limit). With fewer simulation threads than
//! CPUs the device thread is also pinned to a CPU the simulation's pinned pool
//! leaves free.

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

/// Device time of each run (s).
const SECONDS: f64 = 3.0;

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

/// One way of timing the device thread.
#[derive(Debug, Clone, Copy)]
struct Timing {
    /// Busy-wait before each tick (s).
    spin: f64,
    /// Ask for SCHED_FIFO.
    realtime: bool,
}

impl Timing {
    const ALL: [Timing; 4] = [
        Timing {
            spin: 0.0,
            realtime: false,
        },
        Timing {
            spin: 2e-4,
            realtime: false,
        },
        Timing {
            spin: 0.0,
            realtime: true,
        },
        Timing {
            spin: 2e-4,
            realtime: true,
        },
    ];
}

/// Prepares the device thread: pins it to `cpu`, and gives it a real-time priority
/// when `realtime`. Returns what it got, for the report.
fn device_setup(cpu: Option<core_affinity::CoreId>, realtime: bool) -> String {
    let mut got = Vec::new();
    if let Some(c) = cpu {
        if core_affinity::set_for_current(c) {
            got.push(format!("pinned to CPU {}", c.id));
        }
    }
    if realtime {
        // mid-range FIFO priority: above every normal thread, below the kernel's
        // own real-time threads
        let fifo = ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo);
        let priority = ThreadPriority::Crossplatform(50u8.try_into().expect("within 0..=99"));
        match set_thread_priority_and_policy(thread_native_id(), priority, fifo) {
            Ok(()) => got.push("SCHED_FIFO".into()),
            Err(e) => got.push(format!("normal priority (SCHED_FIFO refused: {e})")),
        }
    } else {
        got.push("normal priority".into());
    }
    got.join(", ")
}

/// Runs the loop on each mesh with both integrators and each device [`Timing`] in
/// `pool` (of `threads` pinned workers when `pinned`) and prints the reports.
pub fn run(mesh: Option<&PathBuf>, pool: &rayon::ThreadPool, threads: usize, pinned: bool) -> heml::Result<()> {
    outln!("haptic loop: 1 kHz device, {SECONDS} s of device time per run, {threads} simulation thread(s)");
    // a CPU the pinned pool leaves free, for the device thread
    let free_cpu = if pinned {
        core_affinity::get_core_ids().and_then(|c| c.get(threads).copied())
    } else {
        None
    };
    for path in meshes(mesh)? {
        let name = path
            .file_name()
            .map_or(path.display().to_string(), |n| n.to_string_lossy().into());
        for explicit in [true, false] {
            for timing in Timing::ALL {
                let mut sys = Palpation::tissue(read_mesh(&path)?.0.scaled(1e-3)?)?; // millimetres
                let law = ContactLaw {
                    stiffness: 200.0,
                    damping: 0.002,
                };
                let (tool, palpation) = Palpation::on_top(&mut sys, 0.004, 0.01, law, 1.0)?;
                let (mut integrator, opts): (Box<dyn Integrator>, _) = if explicit {
                    (Box::new(SymplecticEuler), HapticOptions::explicit(&sys, SECONDS))
                } else {
                    (
                        Box::new(BackwardEuler::default()),
                        HapticOptions {
                            duration: SECONDS,
                            ..HapticOptions::default()
                        },
                    )
                };
                let opts = HapticOptions {
                    device_spin: timing.spin,
                    ..opts
                };
                let got = Mutex::new(String::new());
                let setup = || *got.lock().unwrap_or_else(|e| e.into_inner()) = device_setup(free_cpu, timing.realtime);
                let report = pool.install(|| {
                    run_haptic_loop_with(&mut sys, integrator.as_mut(), tool, |t| palpation.at(t), &opts, setup)
                })?;
                let got = got.into_inner().unwrap_or_else(|e| e.into_inner());
                let wait = if timing.spin > 0.0 {
                    format!("sleep + {:.0} µs spin", timing.spin * 1e6)
                } else {
                    "sleep".into()
                };
                outln!(
                    "{name} ({} tets), {}, device {wait}, {got}: {report}",
                    sys.mesh().n_tets(),
                    integrator.name()
                );
            }
        }
    }
    Ok(())
}
