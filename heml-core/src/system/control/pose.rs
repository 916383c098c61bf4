//! Rigid poses: where a tool, a grasp target or a prescribed node group is.

use crate::error::{HemlError, Result};
use crate::Vec3;
use nalgebra::UnitQuaternion;

/// A rigid transform p ↦ R·p + t (rotation about the origin, then translation).
///
/// Tools, grasp targets and rigidly moved node groups are placed by a pose; a scene's
/// keyframed path interpolates between poses with [`Pose::lerp`].
///
/// ```
/// use heml_core::system::control::Pose;
/// use heml_core::Vec3;
/// let p = Pose::new(Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2))?;
/// // a quarter turn about z, then 1 m along x
/// assert!((p.apply(Vec3::x()) - Vec3::new(1.0, 1.0, 0.0)).norm() < 1e-15);
/// assert!(Pose::new(Vec3::new(f64::NAN, 0.0, 0.0), Vec3::zeros()).is_err());
/// # Ok::<(), heml_core::HemlError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Translation t (m).
    pub translation: Vec3,
    /// Rotation R.
    pub rotation: UnitQuaternion<f64>,
}

impl Default for Pose {
    fn default() -> Self {
        Self::identity()
    }
}

impl Pose {
    /// No motion.
    pub fn identity() -> Self {
        Self {
            translation: Vec3::zeros(),
            rotation: UnitQuaternion::identity(),
        }
    }

    /// A pure translation.
    pub fn translation(t: Vec3) -> Self {
        Self {
            translation: t,
            rotation: UnitQuaternion::identity(),
        }
    }

    /// Translation `t` and rotation vector `axis_angle` (axis × angle in radians).
    /// Refuses non-finite input, so a NaN never reaches a simulation.
    pub fn new(t: Vec3, axis_angle: Vec3) -> Result<Self> {
        let pose = Self {
            translation: t,
            rotation: UnitQuaternion::from_scaled_axis(axis_angle),
        };
        pose.check()?;
        Ok(pose)
    }

    /// Errors when any component is not finite.
    pub fn check(&self) -> Result<()> {
        let q = self.rotation.quaternion();
        if self.translation.iter().all(|c| c.is_finite()) && q.coords.iter().all(|c| c.is_finite()) {
            Ok(())
        } else {
            Err(HemlError::Invalid(format!(
                "pose is not finite: translation {:?}, rotation {:?}",
                self.translation.as_slice(),
                q.coords.as_slice()
            )))
        }
    }

    /// R·p + t.
    pub fn apply(&self, p: Vec3) -> Vec3 {
        self.rotation * p + self.translation
    }

    /// R·v (directions and forces do not translate).
    pub fn rotate(&self, v: Vec3) -> Vec3 {
        self.rotation * v
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Self {
        let r = self.rotation.inverse();
        Self {
            translation: -(r * self.translation),
            rotation: r,
        }
    }

    /// Interpolation at `s` ∈ [0, 1]: translation linearly, rotation by slerp.
    pub fn lerp(&self, other: &Pose, s: f64) -> Pose {
        Pose {
            translation: self.translation + s * (other.translation - self.translation),
            rotation: self.rotation.slerp(&other.rotation, s),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_undoes_and_lerp_hits_the_ends() {
        let a = Pose::new(Vec3::new(0.1, -0.2, 0.3), Vec3::new(0.3, 0.2, -0.1)).unwrap();
        let b = Pose::new(Vec3::new(-1.0, 0.5, 0.0), Vec3::new(0.0, 1.0, 0.5)).unwrap();
        let p = Vec3::new(0.7, -0.4, 1.1);
        // a rotation and its inverse round-trip within a few ulps of |p| ~ 1
        assert!((a.inverse().apply(a.apply(p)) - p).norm() < 1e-15);
        assert!((a.lerp(&b, 0.0).apply(p) - a.apply(p)).norm() < 1e-15);
        assert!((a.lerp(&b, 1.0).apply(p) - b.apply(p)).norm() < 1e-14);
        // rigid: distances are kept at any s
        let q = Vec3::new(-0.3, 0.2, 0.0);
        let m = a.lerp(&b, 0.37);
        assert!(((m.apply(p) - m.apply(q)).norm() - (p - q).norm()).abs() < 1e-15);
    }
}
