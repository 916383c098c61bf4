//! Tool shapes and their signed distance: how deep a point is inside a rigid tool
//! and which way is out.

use crate::error::{HemlError, Result};
use crate::Vec3;
use nalgebra::Matrix3;

/// The solid a rigid tool occupies, in the tool's own frame (its [`Pose`] places it).
///
/// [`Pose`]: crate::system::control::Pose
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ToolShape {
    /// A ball of `radius` (m) centred on the pose's origin (a probe tip).
    Sphere {
        /// Radius (m), > 0.
        radius: f64,
    },
    /// The points within `radius` of the segment from −`half_length` to
    /// +`half_length` along the pose's local z axis: a laparoscopic shaft with a
    /// rounded tip.
    Capsule {
        /// Radius (m), > 0.
        radius: f64,
        /// Half the length of the axis segment (m), ≥ 0 (0: a sphere).
        half_length: f64,
    },
    /// The half-space below the plane through the pose's origin whose outward normal
    /// is the pose's local z axis (local z ≤ 0 is solid): a table, a retractor
    /// blade, a wall.
    HalfSpace,
}

impl ToolShape {
    /// Checks the sizes: finite, radius > 0, half-length ≥ 0.
    pub fn check(&self) -> Result<()> {
        let bad = |what: &str, v: f64, expected: &str| {
            Err(HemlError::Invalid(format!(
                "tool shape: {what} = {v} must be a finite number {expected}"
            )))
        };
        match *self {
            ToolShape::Sphere { radius } | ToolShape::Capsule { radius, .. }
                if !(radius.is_finite() && radius > 0.0) =>
            {
                bad("radius", radius, "> 0")
            }
            ToolShape::Capsule { half_length, .. } if !(half_length.is_finite() && half_length >= 0.0) => {
                bad("half_length", half_length, ">= 0")
            }
            _ => Ok(()),
        }
    }

    /// The penetration depth d > 0 of the local point `p` and the tool's outward unit
    /// normal at the closest surface point (the direction that pushes `p` out), or
    /// `None` when `p` is outside (d ≤ 0). At the exact centre of a sphere (or on the
    /// axis of a capsule) the normal is arbitrary but fixed: local +z (+x).
    pub fn penetration(&self, p: Vec3) -> Option<(f64, Vec3)> {
        let (q, radius, fallback) = match *self {
            ToolShape::HalfSpace => return (p.z < 0.0).then(|| (-p.z, Vec3::z())),
            ToolShape::Sphere { radius } => (p, radius, Vec3::z()),
            ToolShape::Capsule { radius, half_length } => (
                p - Vec3::new(0.0, 0.0, p.z.clamp(-half_length, half_length)),
                radius,
                Vec3::x(),
            ),
        };
        let r2 = q.norm_squared();
        if r2 >= radius * radius {
            return None;
        }
        let r = r2.sqrt();
        let n = if r > 0.0 { q / r } else { fallback };
        Some((radius - r, n))
    }

    /// ∂n/∂p: how the outward normal at the local point `p` (inside the tool) turns
    /// as `p` moves, in the tool's frame. The depth's gradient is −n (d = radius − r
    /// for the round shapes, −z for the half-space), so these two give the contact
    /// force's derivative ([`super::ToolSet::translation_stiffness`]). Sphere and
    /// spherical cap: (I − n nᵀ)/r, r the distance to the centre; beside a capsule's
    /// shaft the axial motion does not turn n: (I − n nᵀ − z zᵀ)/r; half-space and
    /// the (measure-zero) centre or axis: 0.
    pub fn normal_derivative(&self, p: Vec3) -> Matrix3<f64> {
        let (q, axial) = match *self {
            ToolShape::HalfSpace => return Matrix3::zeros(),
            ToolShape::Sphere { .. } => (p, false),
            ToolShape::Capsule { half_length, .. } => {
                let zc = p.z.clamp(-half_length, half_length);
                (p - Vec3::new(0.0, 0.0, zc), p.z.abs() < half_length)
            }
        };
        let r = q.norm();
        if r == 0.0 {
            return Matrix3::zeros();
        }
        let n = q / r;
        let mut m = Matrix3::identity() - n * n.transpose();
        if axial {
            m -= Vec3::z() * Vec3::z().transpose();
        }
        m / r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depths_and_normals_of_each_shape() {
        let s = ToolShape::Sphere { radius: 0.5 };
        let (d, n) = s.penetration(Vec3::new(0.0, 0.3, 0.0)).unwrap();
        // 0.5 − 0.3, exact up to one rounding of 0.2
        assert!((d - 0.2).abs() < 1e-16 && n == Vec3::y());
        assert!(s.penetration(Vec3::new(0.0, 0.5, 0.0)).is_none());
        let c = ToolShape::Capsule {
            radius: 0.1,
            half_length: 1.0,
        };
        // beside the shaft: radial normal; beyond the end: the spherical cap
        let (d, n) = c.penetration(Vec3::new(0.05, 0.0, 0.7)).unwrap();
        assert!((d - 0.05).abs() < 1e-16 && n == Vec3::x());
        let (d, n) = c.penetration(Vec3::new(0.0, 0.0, 1.08)).unwrap();
        assert!((d - 0.02).abs() < 1e-15 && (n - Vec3::z()).norm() < 1e-15);
        assert!(c.penetration(Vec3::new(0.0, 0.0, 1.11)).is_none());
        let h = ToolShape::HalfSpace;
        assert_eq!(h.penetration(Vec3::new(3.0, -2.0, -0.25)), Some((0.25, Vec3::z())));
        assert!(h.penetration(Vec3::new(0.0, 0.0, 1e-12)).is_none());
        assert!(ToolShape::Sphere { radius: -1.0 }.check().is_err());
        assert!(ToolShape::Capsule {
            radius: 0.1,
            half_length: f64::NAN
        }
        .check()
        .is_err());
        assert!(c.check().is_ok());
    }
}
