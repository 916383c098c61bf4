//! The blade of a cut: a segment swept between two poses (a quad, two triangles) or
//! a single triangle, and the test of which tets it meets.

use crate::error::{HemlError, Result};
use crate::system::control::Pose;
use crate::Vec3;

/// The surface a cut sweeps, in world coordinates (the deformed configuration: a cut
/// removes the tets the blade meets where they are now).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Blade {
    /// The segment `a0`–`b0` moved to `a1`–`b1` (a scalpel's edge between two
    /// poses): the quad a0, b0, b1, a1, as the triangles (a0, b0, b1) and
    /// (a0, b1, a1).
    Sweep {
        /// First end of the edge at the start.
        a0: Vec3,
        /// Second end of the edge at the start.
        b0: Vec3,
        /// First end of the edge at the end.
        a1: Vec3,
        /// Second end of the edge at the end.
        b1: Vec3,
    },
    /// One triangle.
    Triangle([Vec3; 3]),
}

impl Blade {
    /// The edge `a`–`b`, given in a tool's own frame, swept from pose `from` to pose
    /// `to` (see [`Pose`]): what a scalpel held by a device cuts in one move.
    pub fn swept(a: Vec3, b: Vec3, from: &Pose, to: &Pose) -> Blade {
        Blade::Sweep {
            a0: from.apply(a),
            b0: from.apply(b),
            a1: to.apply(a),
            b1: to.apply(b),
        }
    }

    /// Its triangles (one or two).
    pub fn triangles(&self) -> Vec<[Vec3; 3]> {
        match *self {
            Blade::Sweep { a0, b0, a1, b1 } => vec![[a0, b0, b1], [a0, b1, a1]],
            Blade::Triangle(t) => vec![t],
        }
    }

    /// Checks that every point is finite and that the blade has an area (> 0).
    pub fn check(&self) -> Result<()> {
        let tris = self.triangles();
        for (k, p) in tris.iter().flatten().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(HemlError::Invalid(format!(
                    "blade point #{} = {:?} is not finite",
                    k + 1,
                    p.as_slice()
                )));
            }
        }
        let area: f64 = tris.iter().map(|[a, b, c]| 0.5 * (b - a).cross(&(c - a)).norm()).sum();
        if area.is_nan() || area <= 0.0 {
            return Err(HemlError::Invalid(
                "blade has no area (its points are collinear or equal): it would cut nothing".into(),
            ));
        }
        Ok(())
    }
}

/// Whether the segment `p`–`q` meets the closed triangle `t` (a crossing or a touch;
/// a segment lying in the triangle's plane counts when it crosses one of its edges,
/// which the caller tests from the other side).
pub(crate) fn segment_meets_triangle(p: Vec3, q: Vec3, t: &[Vec3; 3]) -> bool {
    let [a, b, c] = *t;
    let n = (b - a).cross(&(c - a));
    let (dp, dq) = (n.dot(&(p - a)), n.dot(&(q - a)));
    if dp * dq > 0.0 || (dp == 0.0 && dq == 0.0) {
        return false;
    }
    // the point where the segment meets the plane, then inside-triangle by the signs
    // of the three sub-areas (all ≥ 0 along n)
    let s = dp / (dp - dq);
    let x = p + (q - p) * s;
    let inside = |u: Vec3, v: Vec3| n.dot(&(v - u).cross(&(x - u))) >= 0.0;
    inside(a, b) && inside(b, c) && inside(c, a)
}

/// Whether point `x` lies in the closed tet `p` (positively or negatively oriented).
fn point_in_tet(x: Vec3, p: &[Vec3; 4]) -> bool {
    let vol = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| (b - a).cross(&(c - a)).dot(&(d - a));
    let v = vol(p[0], p[1], p[2], p[3]);
    if v == 0.0 {
        return false;
    }
    let s = [
        vol(x, p[1], p[2], p[3]),
        vol(p[0], x, p[2], p[3]),
        vol(p[0], p[1], x, p[3]),
        vol(p[0], p[1], p[2], x),
    ];
    s.iter().all(|&si| si * v >= 0.0)
}

/// The six edges of a tet, as pairs of corners.
const EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// Whether the closed triangle `t` meets the tet with corners `p`: a tet edge
/// crosses the triangle, a triangle edge crosses a tet face, or the triangle lies
/// inside the tet.
pub(crate) fn triangle_meets_tet(t: &[Vec3; 3], p: &[Vec3; 4]) -> bool {
    if EDGES.iter().any(|&(i, j)| segment_meets_triangle(p[i], p[j], t)) {
        return true;
    }
    let faces = [
        [p[1], p[2], p[3]],
        [p[0], p[2], p[3]],
        [p[0], p[1], p[3]],
        [p[0], p[1], p[2]],
    ];
    for k in 0..3 {
        let (u, v) = (t[k], t[(k + 1) % 3]);
        if faces.iter().any(|f| segment_meets_triangle(u, v, f)) {
            return true;
        }
    }
    point_in_tet(t[0], p)
}

/// Axis-aligned bounding box of some points.
pub(crate) fn bounds<'a>(pts: impl IntoIterator<Item = &'a Vec3>) -> (Vec3, Vec3) {
    pts.into_iter().fold(
        (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    )
}

/// The box `lo`–`hi` as "x a–b, y c–d, z e–f m" (4 significant digits), for
/// error messages that say where a blade and the body are.
pub(crate) fn span(lo: Vec3, hi: Vec3) -> String {
    let sig = |v: f64| {
        let decimals = if v == 0.0 || !v.is_finite() {
            0
        } else {
            (3 - v.abs().log10().floor() as i32).max(0) as usize
        };
        format!("{v:.decimals$}")
    };
    let axis = |d: usize, name: &str| format!("{name} {}–{}", sig(lo[d]), sig(hi[d]));
    format!("{}, {}, {} m", axis(0, "x"), axis(1, "y"), axis(2, "z"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_tet() -> [Vec3; 4] {
        [Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()]
    }

    #[test]
    fn a_plane_through_the_tet_meets_it_one_beside_does_not() {
        let p = unit_tet();
        // the plane x = 0.2 crosses edges 0-1 and others: a big triangle in it
        let big = [
            Vec3::new(0.2, -5.0, -5.0),
            Vec3::new(0.2, 10.0, -5.0),
            Vec3::new(0.2, -5.0, 10.0),
        ];
        assert!(triangle_meets_tet(&big, &p));
        let beside = big.map(|q| q + Vec3::new(1.0, 0.0, 0.0));
        assert!(!triangle_meets_tet(&beside, &p));
        // a tiny triangle inside the tet: no edge crosses anything, it is inside
        let c = Vec3::repeat(0.2);
        let tiny = [c, c + Vec3::x() * 1e-3, c + Vec3::y() * 1e-3];
        assert!(triangle_meets_tet(&tiny, &p));
        // a thin triangle piercing one face: its edges cross the tet's faces
        let pierce = [
            Vec3::new(0.2, 0.2, -1.0),
            Vec3::new(0.2, 0.2, 0.1),
            Vec3::new(0.21, 0.2, -1.0),
        ];
        assert!(triangle_meets_tet(&pierce, &p));
    }

    #[test]
    fn sweeps_are_checked() {
        let s = Blade::Sweep {
            a0: Vec3::zeros(),
            b0: Vec3::x(),
            a1: Vec3::y(),
            b1: Vec3::new(1.0, 1.0, 0.0),
        };
        assert!(s.check().is_ok());
        assert_eq!(s.triangles().len(), 2);
        let flat = Blade::Triangle([Vec3::zeros(), Vec3::x(), Vec3::x() * 2.0]);
        assert!(flat.check().unwrap_err().to_string().contains("no area"));
        let nan = Blade::Triangle([Vec3::zeros(), Vec3::x(), Vec3::new(0.0, f64::NAN, 0.0)]);
        assert!(nan.check().unwrap_err().to_string().contains("#3"));
    }
}
