//! The device side of a haptic loop: a fixed-rate thread that publishes the tool
//! pose and renders the newest [`LocalModel`] at it, never waiting for the
//! simulation.

use super::handoff::DeviceEnd;
use super::local_model::LocalModel;
use crate::system::control::Pose;
use crate::Vec3;
use std::time::{Duration, Instant};

/// Waits until `deadline`: sleeps until `spin` before it, then busy-waits.
///
/// Why busy-wait: an OS sleep overshoots by the timer slack (50 µs by default)
/// and the scheduler's wake-up latency, 0.05–0.1 ms idle and milliseconds when the
/// simulation's threads fill every core, which a 1 ms period cannot absorb; and
/// yielding while waiting (`sched_yield`) hands the core to a runnable simulation
/// thread for a whole time slice. Busy-waiting costs a core for `spin` per period
/// (200 µs at 1 kHz: 20 % of one core) and keeps it.
fn wait_until(deadline: Instant, spin: Duration) {
    let now = Instant::now();
    if deadline > now + spin {
        std::thread::sleep(deadline - now - spin);
    }
    while Instant::now() < deadline {
        std::hint::spin_loop();
    }
}

/// An empty vector with room for `n` values whose memory has been written once:
/// the first write to a fresh page faults into the kernel, which a tick should not
/// wait for (a fault may queue behind the simulation's own allocations).
fn touched<T: Default + Clone>(n: usize) -> Vec<T> {
    let mut v = Vec::with_capacity(n);
    v.resize(n, T::default());
    v.clear();
    v
}

/// What a device thread ([`run_device`]) recorded, one entry per tick.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DeviceLog {
    /// Wall time between successive ticks (s): the device loop's period.
    pub gaps: Vec<f64>,
    /// Wall time each tick spent reading the model and rendering it (s).
    pub work: Vec<f64>,
    /// How late each tick started after its deadline (s): the wake-up latency
    /// the device period's jitter comes from.
    pub late: Vec<f64>,
    /// Age of the rendered model at each tick (s): wall time since the
    /// simulation published it.
    pub ages: Vec<f64>,
    /// Device time, tool translation and rendered force of each tick.
    pub forces: Vec<(f64, Vec3, Vec3)>,
    /// Ticks that rendered a model newer than the previous tick's.
    pub fresh: u64,
}

/// Runs a device of `ticks` ticks at `rate` Hz from `start` (tick k at
/// start + k/rate, or one period after the previous tick when the thread was held
/// off the CPU for more than a period): each tick publishes the pose `path(t)` (t = k/rate, device
/// time; a non-finite pose is skipped and the last one kept) and renders the
/// newest local model at that pose ([`LocalModel::force_at`], clamped to
/// `max_force`, and to the model's reach: [`LocalModel::bound`]). Each wait
/// sleeps until `spin` before the tick, then busy-waits (0: sleep only; see the
/// module source for the cost). Wait-free on the simulation and allocation-free
/// per tick (the log is reserved up front): a stalled simulation leaves the
/// device rendering its last model, which only ages.
pub fn run_device(
    device: &mut DeviceEnd,
    path: impl Fn(f64) -> Pose,
    rate: f64,
    ticks: u64,
    max_force: f64,
    start: Instant,
    spin: Duration,
) -> DeviceLog {
    let n = ticks as usize;
    let mut log = DeviceLog {
        gaps: touched(n),
        work: touched(n),
        late: touched(n),
        ages: touched(n),
        forces: touched(n),
        fresh: 0,
    };
    let period = 1.0 / rate;
    let mut last: Option<Instant> = None;
    let mut last_model: Option<Instant> = None;
    let step = Duration::from_secs_f64(period);
    let mut deadline = start;
    for k in 0..ticks {
        // when the tick was due, before a missed period moves the deadline
        let mut due = deadline;
        if k > 0 {
            deadline += step;
            due = deadline;
            // a device thread the OS kept off the CPU for more than a period
            // resumes one period from now rather than bursting through the ticks
            // it missed (a burst renders nothing the motors could follow)
            let now = Instant::now();
            if now > deadline + step {
                deadline = now;
            }
        }
        wait_until(deadline, spin);
        let now = Instant::now();
        log.late.push(now.saturating_duration_since(due).as_secs_f64());
        if let Some(l) = last {
            log.gaps.push((now - l).as_secs_f64());
        }
        last = Some(now);
        let t = k as f64 * period;
        let pose = path(t);
        let _ = device.publish_pose(pose, t);
        let model: LocalModel = device.model();
        let force = model.force_at(pose.translation, max_force);
        log.fresh += u64::from(last_model.is_some_and(|p| model.published > p));
        last_model = Some(model.published);
        let done = Instant::now();
        log.work.push((done - now).as_secs_f64());
        log.ages
            .push(now.saturating_duration_since(model.published).as_secs_f64());
        log.forces.push((t, pose.translation, force));
    }
    log
}
