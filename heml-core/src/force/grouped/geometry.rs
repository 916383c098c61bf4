//! A tet's signed volume and its first two derivatives in the corner positions,
//! shared by the grouped terms' reference path and tangent.

use crate::Vec3;

/// The signed volume of a tet with corners `p`.
pub(crate) fn volume(p: &[Vec3; 4]) -> f64 {
    (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) / 6.0
}

/// ∇vol of a tet with corners `p` (∂vol/∂x_a, a = 0..3).
pub(crate) fn volume_gradient(p: &[Vec3; 4]) -> [Vec3; 4] {
    let (v1, v2, v3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let g1 = v2.cross(&v3) / 6.0;
    let g2 = v3.cross(&v1) / 6.0;
    let g3 = v1.cross(&v2) / 6.0;
    [-(g1 + g2 + g3), g1, g2, g3]
}

/// (∇²vol·u) at the four corners of a tet with corners `p`: the derivative of
/// ∇vol along u.
pub(crate) fn volume_curvature(p: &[Vec3; 4], u: &[Vec3; 4]) -> [Vec3; 4] {
    let (v1, v2, v3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let (u1, u2, u3) = (u[1] - u[0], u[2] - u[0], u[3] - u[0]);
    let g1 = (u2.cross(&v3) + v2.cross(&u3)) / 6.0;
    let g2 = (u3.cross(&v1) + v3.cross(&u1)) / 6.0;
    let g3 = (u1.cross(&v2) + v1.cross(&u2)) / 6.0;
    [-(g1 + g2 + g3), g1, g2, g3]
}
