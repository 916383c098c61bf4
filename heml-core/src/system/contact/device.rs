//! The device side of a haptic loop: a fixed-rate thread that publishes the tool
//! pose and renders the newest [`LocalModel`] at it, never waiting for the
//! simulation.

use super::handoff::DeviceEnd;
use super::local_model::LocalModel;
use crate::system::control::Pose;
use crate::Vec3;
use std::time::{Duration, Instant};

/// Spin (yielding) instead of sleeping for the last part of a wait: an OS sleep
/// overshoots by the timer slack and the scheduler's wake-up latency, 0.05–0.1 ms
/// idle and more under load, which a 1 ms period cannot absorb.
const SPIN: Duration = Duration::from_micros(200);

/// Waits until `deadline`: sleeps until [`SPIN`] before it, then yields until it.
fn wait_until(deadline: Instant) {
    let now = Instant::now();
    if deadline > now + SPIN {
        std::thread::sleep(deadline - now - SPIN);
    }
    while Instant::now() < deadline {
        std::thread::yield_now();
    }
}

/// What a device thread ([`run_device`]) recorded, one entry per tick.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DeviceLog {
    /// Wall time between successive ticks (s): the device loop's period.
    pub gaps: Vec<f64>,
    /// Wall time each tick spent reading the model and rendering it (s).
    pub work: Vec<f64>,
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
/// `max_force`). Wait-free on the simulation: a stalled simulation leaves the
/// device rendering its last model, which only ages.
pub fn run_device(
    device: &mut DeviceEnd,
    path: impl Fn(f64) -> Pose,
    rate: f64,
    ticks: u64,
    max_force: f64,
    start: Instant,
) -> DeviceLog {
    let n = ticks as usize;
    let mut log = DeviceLog {
        gaps: Vec::with_capacity(n),
        work: Vec::with_capacity(n),
        ages: Vec::with_capacity(n),
        forces: Vec::with_capacity(n),
        fresh: 0,
    };
    let period = 1.0 / rate;
    let mut last: Option<Instant> = None;
    let mut last_model: Option<Instant> = None;
    let step = Duration::from_secs_f64(period);
    let mut deadline = start;
    for k in 0..ticks {
        if k > 0 {
            deadline += step;
            // a device thread the OS kept off the CPU for more than a period
            // resumes one period from now rather than bursting through the ticks
            // it missed (a burst renders nothing the motors could follow)
            let now = Instant::now();
            if now > deadline + step {
                deadline = now;
            }
        }
        wait_until(deadline);
        let now = Instant::now();
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
