//! Kinematic constraints imposed by the system (never by an integrator): fixed nodes
//! and prescribed displacements following a time ramp.

use crate::error::{HemlError, Result};
use crate::Vec3;

/// How a prescribed displacement u is applied over time: x(t) = X + r(t)·u,
/// v(t) = r'(t)·u, with r(t) = 0 for t < 0.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
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
}

impl Ramp {
    /// r(t).
    pub fn value(&self, t: f64) -> f64 {
        if t < 0.0 {
            return 0.0;
        }
        match *self {
            Ramp::Step => 1.0,
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

    /// Checks that a ramp duration is finite and positive.
    pub fn validate(&self) -> Result<()> {
        match *self {
            Ramp::Step => Ok(()),
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

/// One node with a prescribed displacement.
#[derive(Debug, Clone, Copy, PartialEq)]
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
}
