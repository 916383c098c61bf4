//! Lock-free hand-off between a haptic device thread and the simulation thread.
//!
//! The device runs at ~1 kHz and must never wait for a step; the simulation must
//! never wait for the device. Each direction is a triple buffer (crate
//! `triple_buffer`): the writer fills a back buffer and swaps it in with one atomic
//! exchange, the reader swaps out the newest complete value with another. Neither
//! side blocks or allocates, values are never torn (a reader sees one whole published
//! value), intermediate values a reader did not pick up are dropped (a haptic loop
//! wants the newest pose and the newest force, not a queue).
//!
//! **Latency: one step.** A pose published at device time t is picked up by the
//! simulation at its next step boundary (at most one step later), used for the whole
//! next step, and the wrench at the end of that step is readable by the device as
//! soon as the step finishes. So the force the device reads lags the pose it sent by
//! the time to the next boundary plus one step's compute time: at most two step
//! periods, one on average.

use super::local_model::LocalModel;
use super::tool::{ToolId, Wrench};
use crate::error::Result;
use crate::system::control::Pose;
use crate::system::System;

/// The writing half of a [`latest`] channel.
pub struct Publisher<T: Send>(triple_buffer::Input<T>);

/// The reading half of a [`latest`] channel.
pub struct Reader<T: Send>(triple_buffer::Output<T>);

impl<T: Send> std::fmt::Debug for Publisher<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Publisher")
    }
}

impl<T: Send> std::fmt::Debug for Reader<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Reader")
    }
}

/// A single-producer single-consumer channel of the latest value (a triple
/// buffer), starting at `initial`. Used for poses, wrenches and visual snapshots.
///
/// ```
/// use heml_core::system::contact::latest;
/// let (mut tx, mut rx) = latest(0u64);
/// std::thread::scope(|s| {
///     s.spawn(move || (1..=1000u64).for_each(|i| tx.publish(i)));
/// });
/// assert_eq!(*rx.read(), 1000);
/// ```
pub fn latest<T: Clone + Send>(initial: T) -> (Publisher<T>, Reader<T>) {
    let (i, o) = triple_buffer::triple_buffer(&initial);
    (Publisher(i), Reader(o))
}

impl<T: Send> Publisher<T> {
    /// Publishes `value` (wait-free).
    pub fn publish(&mut self, value: T) {
        self.0.write(value);
    }

    /// Fills the back buffer in place with `fill` and publishes it: no allocation
    /// for large values such as position snapshots. The buffer holds an older value
    /// (not necessarily the last published), so `fill` must overwrite all of it.
    pub fn publish_with(&mut self, fill: impl FnOnce(&mut T)) {
        fill(self.0.input_buffer_mut());
        self.0.publish();
    }
}

impl<T: Send> Reader<T> {
    /// The newest published value (wait-free).
    pub fn read(&mut self) -> &T {
        self.0.read()
    }

    /// Whether a value newer than the last [`Reader::read`] was published.
    pub fn updated(&self) -> bool {
        self.0.updated()
    }
}

/// A tool pose sent by the device.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PoseSample {
    /// The pose.
    pub pose: Pose,
    /// Device time of the sample (s).
    pub time: f64,
    /// Sequence number (1 for the first published sample, 0 for the initial pose).
    pub seq: u64,
}

/// A tool wrench sent by the simulation.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WrenchSample {
    /// The wrench the tissue applies to the tool.
    pub wrench: Wrench,
    /// Simulated time of the state it belongs to (s).
    pub time: f64,
    /// Step count of that state.
    pub step: u64,
    /// The [`PoseSample::seq`] of the pose that step used.
    pub pose_seq: u64,
}

/// The device's end of a [`haptic_link`]: publishes poses, reads wrenches.
#[derive(Debug)]
pub struct DeviceEnd {
    poses: Publisher<PoseSample>,
    wrenches: Reader<WrenchSample>,
    models: Reader<LocalModel>,
    seq: u64,
}

/// The simulation's end of a [`haptic_link`]: reads poses, publishes wrenches.
#[derive(Debug)]
pub struct SimulationEnd {
    poses: Reader<PoseSample>,
    wrenches: Publisher<WrenchSample>,
    models: Publisher<LocalModel>,
    used: u64,
}

/// The two ends of a device ↔ simulation link for one tool, starting at `initial`.
/// Hand each end to its thread. See the module docs for the latency.
///
/// ```
/// use heml_core::system::contact::{haptic_link, Wrench};
/// use heml_core::system::control::Pose;
/// use heml_core::Vec3;
/// let (mut device, mut sim) = haptic_link(Pose::identity());
/// device.publish_pose(Pose::translation(Vec3::new(0.0, 0.0, 0.01)), 0.001)?;
/// assert_eq!(sim.pose().pose.translation.z, 0.01);
/// sim.publish_wrench(Wrench::default(), 0.001, 1);
/// assert_eq!(device.wrench().step, 1);
/// # Ok::<(), heml_core::HemlError>(())
/// ```
pub fn haptic_link(initial: Pose) -> (DeviceEnd, SimulationEnd) {
    let (pt, pr) = latest(PoseSample {
        pose: initial,
        time: 0.0,
        seq: 0,
    });
    let (wt, wr) = latest(WrenchSample::default());
    let (mt, mr) = latest(LocalModel::empty(initial.translation));
    (
        DeviceEnd {
            poses: pt,
            wrenches: wr,
            models: mr,
            seq: 0,
        },
        SimulationEnd {
            poses: pr,
            wrenches: wt,
            models: mt,
            used: 0,
        },
    )
}

impl DeviceEnd {
    /// Publishes the tool pose at device time `time`. A non-finite pose is refused
    /// here, on the device thread, so it never reaches the simulation.
    pub fn publish_pose(&mut self, pose: Pose, time: f64) -> Result<()> {
        pose.check()?;
        self.seq += 1;
        self.poses.publish(PoseSample {
            pose,
            time,
            seq: self.seq,
        });
        Ok(())
    }

    /// The newest wrench the simulation published.
    pub fn wrench(&mut self) -> WrenchSample {
        *self.wrenches.read()
    }

    /// The newest local model the simulation published (wait-free): render it at
    /// the device's pose with [`LocalModel::force_at`] every device period.
    pub fn model(&mut self) -> LocalModel {
        *self.models.read()
    }
}

impl SimulationEnd {
    /// The newest pose the device published.
    pub fn pose(&mut self) -> PoseSample {
        *self.poses.read()
    }

    /// Publishes a wrench of the state at `time`, step `step`, computed with the
    /// last pose [`SimulationEnd::apply`] used.
    pub fn publish_wrench(&mut self, wrench: Wrench, time: f64, step: u64) {
        self.wrenches.publish(WrenchSample {
            wrench,
            time,
            step,
            pose_seq: self.used,
        });
    }

    /// Publishes a local model of the force around the tool's pose
    /// ([`super::StiffnessEstimator::model`]).
    pub fn publish_model(&mut self, model: LocalModel) {
        self.models.publish(model);
    }

    /// The newest device pose, marked as the one the next published wrench
    /// answers ([`WrenchSample::pose_seq`]).
    pub fn take(&mut self) -> PoseSample {
        let s = self.pose();
        self.used = s.seq;
        s
    }

    /// Before a step: moves tool `id` of `sys` to the newest device pose.
    pub fn apply(&mut self, sys: &mut System, id: ToolId) -> Result<()> {
        let s = self.take();
        sys.set_tool_pose(id, s.pose)
    }

    /// After a step: publishes tool `id`'s wrench of the step's end state.
    pub fn publish(&mut self, sys: &System, id: ToolId) -> Result<()> {
        let w = sys.tool_wrench(id)?;
        self.publish_wrench(w, sys.time(), sys.step_count());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Vec3;

    /// Two threads: the device publishes poses whose translation components all
    /// equal its sequence number; the simulation side reads concurrently and must
    /// never see mixed components (a torn value) nor go back in time.
    #[test]
    fn values_are_never_torn_nor_stale() {
        let (mut device, mut sim) = haptic_link(Pose::identity());
        const N: u64 = 200_000;
        let reader = std::thread::spawn(move || {
            let (mut last, mut reads, mut distinct) = (0u64, 0u64, 0u64);
            while last < N {
                let s = sim.pose();
                let t = s.pose.translation;
                assert!(t.x == t.y && t.y == t.z, "torn pose {t:?}");
                assert_eq!(t.x, s.seq as f64, "pose and sequence number from different samples");
                assert_eq!(s.time, 1e-3 * s.seq as f64);
                assert!(s.seq >= last, "went back from {last} to {}", s.seq);
                distinct += u64::from(s.seq > last);
                last = s.seq;
                reads += 1;
                sim.publish_wrench(
                    Wrench {
                        force: Vec3::repeat(reads as f64),
                        torque: Vec3::repeat(-(reads as f64)),
                    },
                    0.0,
                    reads,
                );
            }
            distinct
        });
        let mut last_step = 0;
        for i in 1..=N {
            let a = i as f64;
            device
                .publish_pose(Pose::translation(Vec3::new(a, a, a)), 1e-3 * a)
                .unwrap();
            let w = device.wrench();
            assert!(w.wrench.force == Vec3::repeat(w.step as f64), "torn wrench {w:?}");
            assert!(w.wrench.torque == -w.wrench.force);
            assert!(w.step >= last_step);
            last_step = w.step;
        }
        let distinct = reader.join().unwrap();
        // the reader ends on the last sample, having seen at least it
        assert!(distinct >= 1);
        // a NaN pose is refused at the device and the sequence does not advance
        assert!(device
            .publish_pose(Pose::translation(Vec3::new(f64::NAN, 0.0, 0.0)), 0.0)
            .is_err());
        assert_eq!(device.seq, N);
    }
}
