//! Kinematic constraints imposed by the system (never by an integrator): fixed nodes
//! and prescribed displacements following a time ramp.

use crate::error::{HemlError, Result};
use crate::Vec3;

/// How a prescribed displacement u is applied over time: x(t) = X + r(t)·u,
/// v(t) = r'(t)·u, with r(t) = 0 for t < 0.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Ramp {
    /// r = 1 from t = 0 on (a step: the displacement is applied at once).
    #[default]
    Step,
    /// r = t / duration until `duration`, then 1 (constant velocity u/duration).
    Linear {
        /// Ramp time (s), > 0.
        duration: f64,
    },
    /// r = 3s² − 2s³ with s = t / duration (smoothstep: zero velocity at both ends).
    Smooth {
        /// Ramp time (s), > 0.
        duration: f64,
    },
    /// Piecewise linear through `points = [[t, r], …]` (times strictly increasing,
    /// ≥ 0), held at the last value after the last time: ramps that go back down
    /// (press, hold, release). An implicit keyframe (0, 0) precedes a first time > 0.
    Keyframes {
        /// `[t, r]` pairs.
        points: Vec<[f64; 2]>,
    },
}

impl Ramp {
    /// r(t).
    pub fn value(&self, t: f64) -> f64 {
        if t < 0.0 {
            return 0.0;
        }
        match *self {
            Ramp::Step => 1.0,
            Ramp::Keyframes { ref points } => {
                let (i, (t0, r0), (t1, r1)) = keyframe_interval(points, t);
                if i == points.len() {
                    r0
                } else {
                    r0 + (r1 - r0) * ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
                }
            }
            Ramp::Linear { duration } => (t / duration).min(1.0),
            Ramp::Smooth { duration } => {
                let s = (t / duration).min(1.0);
                s * s * (3.0 - 2.0 * s)
            }
        }
    }

    /// r'(t) (0 for a step; one-sided at the corners: the rate of the interval that
    /// starts at t).
    pub fn rate(&self, t: f64) -> f64 {
        match *self {
            Ramp::Step => 0.0,
            Ramp::Keyframes { ref points } => {
                let (i, (t0, r0), (t1, r1)) = keyframe_interval(points, t);
                if t < 0.0 || i == points.len() {
                    0.0
                } else {
                    (r1 - r0) / (t1 - t0)
                }
            }
            Ramp::Linear { duration } => {
                if (0.0..duration).contains(&t) {
                    1.0 / duration
                } else {
                    0.0
                }
            }
            Ramp::Smooth { duration } => {
                if (0.0..duration).contains(&t) {
                    let s = t / duration;
                    6.0 * s * (1.0 - s) / duration
                } else {
                    0.0
                }
            }
        }
    }

    /// Checks that a ramp duration is finite and positive, and that keyframes are
    /// finite with strictly increasing times ≥ 0.
    pub fn validate(&self) -> Result<()> {
        match *self {
            Ramp::Step => Ok(()),
            Ramp::Keyframes { ref points } => {
                if points.is_empty() {
                    return Err(HemlError::Invalid("keyframes: at least one [t, r] is needed".into()));
                }
                let mut prev = None;
                for (k, &[t, r]) in points.iter().enumerate() {
                    if !(t.is_finite() && r.is_finite() && t >= 0.0) {
                        return Err(HemlError::Invalid(format!(
                            "keyframe #{} = [{t}, {r}]: the time must be finite and >= 0, the value finite",
                            k + 1
                        )));
                    }
                    if prev.is_some_and(|p| t <= p) {
                        return Err(HemlError::Invalid(format!(
                            "keyframe #{} at t = {t}: times must increase strictly (the previous one is at {})",
                            k + 1,
                            prev.unwrap_or(t)
                        )));
                    }
                    prev = Some(t);
                }
                Ok(())
            }
            Ramp::Linear { duration } | Ramp::Smooth { duration } => {
                if duration.is_finite() && duration > 0.0 {
                    Ok(())
                } else {
                    Err(HemlError::Invalid(format!(
                        "ramp duration {duration} must be a finite number > 0"
                    )))
                }
            }
        }
    }
}

/// The keyframe interval that holds `t`: its index i (the interval runs from point
/// i − 1 to point i; i = 0 is the implicit (0, 0) start, i = len past the end) and
/// its end points.
fn keyframe_interval(points: &[[f64; 2]], t: f64) -> (usize, (f64, f64), (f64, f64)) {
    let i = points.partition_point(|p| p[0] <= t);
    let end = |k: usize| (points[k][0], points[k][1]);
    match i {
        // no keyframe at all ([`Ramp::validate`] refuses it; a ramp built without
        // checking stays at r = 0 rather than panic)
        _ if points.is_empty() => (0, (0.0, 0.0), (0.0, 0.0)),
        0 => (0, (0.0, 0.0), end(0)),
        i if i == points.len() => (i, end(i - 1), end(i - 1)),
        i => (i, end(i - 1), end(i)),
    }
}

/// One node with a prescribed displacement.
#[derive(Debug, Clone, PartialEq)]
pub struct Prescribed {
    /// Node id.
    pub node: usize,
    /// Full displacement u (reached when the ramp reaches 1).
    pub displacement: Vec3,
    /// Time profile.
    pub ramp: Ramp,
}

/// The constraints of a system.
#[derive(Debug, Clone, Default)]
pub struct Constraints {
    /// Nodes held at their rest position.
    pub fixed: Vec<usize>,
    /// Nodes following a prescribed displacement.
    pub prescribed: Vec<Prescribed>,
    /// Per node: constrained (fixed or prescribed)?
    pub(crate) mask: Vec<bool>,
}

impl Constraints {
    /// Whether node `i` is constrained.
    pub fn is_constrained(&self, i: usize) -> bool {
        self.mask.get(i).copied().unwrap_or(false)
    }

    /// Ids of all constrained nodes, sorted.
    pub fn constrained_nodes(&self) -> Vec<usize> {
        self.mask
            .iter()
            .enumerate()
            .filter(|(_, c)| **c)
            .map(|(i, _)| i)
            .collect()
    }

    /// Imposes the constraints at time `t`; returns whether a position changed.
    pub(crate) fn apply(&self, t: f64, rest: &[Vec3], x: &mut [Vec3], v: &mut [Vec3]) -> bool {
        let mut moved = false;
        for &i in &self.fixed {
            moved |= x[i] != rest[i];
            x[i] = rest[i];
            v[i] = Vec3::zeros();
        }
        for p in &self.prescribed {
            let target = rest[p.node] + p.displacement * p.ramp.value(t);
            moved |= x[p.node] != target;
            x[p.node] = target;
            v[p.node] = p.displacement * p.ramp.rate(t);
        }
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramps_and_their_rates() {
        let l = Ramp::Linear { duration: 2.0 };
        assert_eq!((l.value(-1.0), l.value(1.0), l.value(3.0)), (0.0, 0.5, 1.0));
        assert_eq!((l.rate(1.0), l.rate(2.0)), (0.5, 0.0));
        let s = Ramp::Smooth { duration: 2.0 };
        assert_eq!((s.value(0.0), s.value(1.0), s.value(2.0)), (0.0, 0.5, 1.0));
        // rate = derivative of value (central difference, O(h²) = 1e-8 accurate)
        let h = 1e-4;
        let fd = (s.value(0.7 + h) - s.value(0.7 - h)) / (2.0 * h);
        assert!((s.rate(0.7) - fd).abs() < 1e-7);
        assert_eq!((Ramp::Step.value(0.0), Ramp::Step.rate(0.0)), (1.0, 0.0));
        assert!(Ramp::Linear { duration: 0.0 }.validate().is_err());
        assert!(Ramp::Smooth { duration: f64::NAN }.validate().is_err());
    }

    #[test]
    fn keyframes_go_up_hold_and_come_back_down() {
        // press over [0, 1], hold to 2, release over [2, 3]
        let k = Ramp::Keyframes {
            points: vec![[1.0, 1.0], [2.0, 1.0], [3.0, 0.0]],
        };
        k.validate().unwrap();
        assert_eq!(
            (k.value(-1.0), k.value(0.5), k.value(1.5), k.value(2.25)),
            (0.0, 0.5, 1.0, 0.75)
        );
        assert_eq!((k.value(3.0), k.value(9.0)), (0.0, 0.0));
        assert_eq!(
            (k.rate(0.5), k.rate(1.5), k.rate(2.5), k.rate(3.5)),
            (1.0, 0.0, -1.0, 0.0)
        );
        // the rate is the derivative of the value inside each interval
        let h = 1e-6;
        for t in [0.3, 1.7, 2.4] {
            let fd = (k.value(t + h) - k.value(t - h)) / (2.0 * h);
            assert!((k.rate(t) - fd).abs() < 1e-8, "t = {t}");
        }
        let bad = |points: Vec<[f64; 2]>| Ramp::Keyframes { points }.validate().unwrap_err().to_string();
        assert!(bad(vec![]).contains("at least one"));
        // unchecked, an empty list is r = 0 at every time (it used to index out of bounds)
        let empty = Ramp::Keyframes { points: vec![] };
        assert_eq!((empty.value(0.5), empty.rate(0.5), empty.value(-1.0)), (0.0, 0.0, 0.0));
        assert!(bad(vec![[1.0, 0.0], [1.0, 1.0]]).contains("#2 at t = 1"));
        assert!(bad(vec![[-1.0, 0.0]]).contains(">= 0"));
        assert!(bad(vec![[1.0, f64::NAN]]).contains("#1"));
    }
}
