//! Closed-form eigen-decomposition of a symmetric 3×3 matrix (the right
//! Cauchy–Green tensor of a tet), robust at repeated eigenvalues.
//!
//! The trigonometric formula gives the eigenvalues of the scaled deviator
//! B = (A − q I)/p in closed form, but two nearly equal eigenvalues come out of it
//! split by up to ~√ε (acos is ill-conditioned at ±1). So, following Eberly ("A Robust
//! Eigensolver for 3×3 Symmetric Matrices", Geometric Tools, 2014), only the
//! eigenvalue that is well separated from the other two (gap ≥ √3 in units of p) is
//! taken from the formula; its eigenvector comes from the largest cross product of two
//! rows of B − βI, and the other two pairs from the 2×2 symmetric problem in the
//! orthogonal complement, solved by one Jacobi rotation. Every eigenvalue then has an
//! absolute error of a few ε·‖A‖ and the eigenvectors are orthonormal to round-off,
//! whatever the multiplicity — what the stretch kernels need for forces and tangents
//! accurate to round-off at the rest state and at uniaxial or equibiaxial states.
//!
//! The separated eigenvalue is the root of the scaled deviator's characteristic
//! cubic t³ − 3t − 2r that the trigonometric formula 2 cos(acos(r)/3) names, taken by
//! two Newton steps from a polynomial guess instead (the same number to an ulp, no
//! library call); with products by reciprocals in place of the divisions, this cut
//! the Ogden force pass by about a tenth (the decomposition runs for every tet of a
//! stretch law's force pass and of a projected invariant tangent).

use crate::Vec3;
use nalgebra::Matrix3;

/// Eigenvalues (in no particular order) and orthonormal eigenvectors of the symmetric
/// matrix `a`: `a·n[i] = e[i]·n[i]`.
pub fn sym_eigen(a: &Matrix3<f64>) -> ([f64; 3], [Vec3; 3]) {
    let scale = a.amax();
    if scale == 0.0 || !scale.is_finite() {
        let e = if scale == 0.0 { 0.0 } else { f64::NAN };
        return ([e; 3], [Vec3::x(), Vec3::y(), Vec3::z()]);
    }
    // products with reciprocals rather than nine divisions each: this decomposition
    // runs for every tet of a stretch law's force pass and of a projected tangent
    // update, and its divisions were a third of its time (one chain of latencies)
    let s = a * (1.0 / scale);
    let q = s.trace() * (1.0 / 3.0);
    let b = s - Matrix3::identity() * q;
    let p2 = b.norm_squared() * (1.0 / 6.0);
    if p2 == 0.0 {
        return ([q * scale; 3], [Vec3::x(), Vec3::y(), Vec3::z()]);
    }
    let p = p2.sqrt();
    let bn = b * (1.0 / p);
    // the eigenvalues of bn are the roots of t³ − 3t − 2r; r ≥ 0: the largest is the
    // separated one, else the smallest (minus the largest root for −r)
    let r = (0.5 * bn.determinant()).clamp(-1.0, 1.0);
    let root = largest_cubic_root(r.abs());
    let beta = if r >= 0.0 { root } else { -root };
    let n0 = separated_vector(&bn, beta);
    let (u, v) = complement(&n0);
    // the 2×2 problem in span(u, v), diagonalised by one Jacobi rotation
    let (muu, muv, mvv) = (u.dot(&(bn * u)), u.dot(&(bn * v)), v.dot(&(bn * v)));
    let (c, sn) = jacobi_rotation(muu, muv, mvv);
    let n1 = u * c - v * sn;
    let n2 = u * sn + v * c;
    let rayleigh = |n: &Vec3| n.dot(&(bn * n));
    let e = [
        (q + p * rayleigh(&n0)) * scale,
        (q + p * rayleigh(&n1)) * scale,
        (q + p * rayleigh(&n2)) * scale,
    ];
    (e, [n0, n1, n2])
}

/// The largest root of t³ − 3t − 2ρ for ρ ∈ [0, 1], which lies in [√3, 2]: the
/// trigonometric formula's 2 cos(acos(ρ)/3), without the two library calls. A
/// degree-4 polynomial in ρ (a Chebyshev fit, within 1.9e-5 of the root) and two
/// Newton steps, which converge quadratically there (the cubic's slope 3t² − 3 ≥ 6,
/// its curvature 6t ≤ 12): within 1.3e-16 relative of the root over [0, 1] (tested).
#[inline(always)]
fn largest_cubic_root(rho: f64) -> f64 {
    const C: [f64; 5] = [
        1.732_068_948_216_576_5,
        0.332_751_750_239_511_2,
        -0.091_712_040_150_053_5,
        0.035_006_397_978_524_7,
        -0.008_128_714_465_237_896,
    ];
    let mut t = C[0] + rho * (C[1] + rho * (C[2] + rho * (C[3] + rho * C[4])));
    for _ in 0..2 {
        let t2 = t * t;
        t -= (t * (t2 - 3.0) - 2.0 * rho) / (3.0 * t2 - 3.0);
    }
    t
}

/// The unit eigenvector of the separated eigenvalue `beta` of `bn`: the largest
/// cross product of two rows of bn − βI (which has rank 2, its null space the vector).
fn separated_vector(bn: &Matrix3<f64>, beta: f64) -> Vec3 {
    let m = bn - Matrix3::identity() * beta;
    let rows = [m.row(0).transpose(), m.row(1).transpose(), m.row(2).transpose()];
    let cands = [
        rows[0].cross(&rows[1]),
        rows[0].cross(&rows[2]),
        rows[1].cross(&rows[2]),
    ];
    let norms = cands.map(|c| c.norm_squared());
    let k = if norms[0] >= norms[1] && norms[0] >= norms[2] {
        0
    } else if norms[1] >= norms[2] {
        1
    } else {
        2
    };
    if norms[k] > 0.0 {
        cands[k] * (1.0 / norms[k].sqrt())
    } else {
        Vec3::x()
    }
}

/// Two unit vectors completing the unit `w` to an orthonormal basis.
fn complement(w: &Vec3) -> (Vec3, Vec3) {
    let u = if w.x.abs() > w.y.abs() {
        Vec3::new(-w.z, 0.0, w.x) * (1.0 / (w.x * w.x + w.z * w.z).sqrt())
    } else {
        Vec3::new(0.0, w.z, -w.y) * (1.0 / (w.y * w.y + w.z * w.z).sqrt())
    };
    (u, w.cross(&u))
}

/// (cos θ, sin θ) of the rotation that diagonalises [[a, b], [b, d]] (stable form,
/// Golub & Van Loan §8.5.2): the columns (c, −s) and (s, c) are its eigenvectors.
fn jacobi_rotation(a: f64, b: f64, d: f64) -> (f64, f64) {
    if b == 0.0 {
        return (1.0, 0.0);
    }
    let tau = (d - a) / (2.0 * b);
    let t = tau.signum() / (tau.abs() + (1.0 + tau * tau).sqrt());
    let t = if tau == 0.0 { 1.0 } else { t };
    let c = 1.0 / (1.0 + t * t).sqrt();
    (c, t * c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Unit};

    /// ‖A n − e n‖ and ‖NᵀN − I‖ of the decomposition of `a`, relative to ‖A‖.
    fn residuals(a: &Matrix3<f64>) -> (f64, f64) {
        let (e, n) = sym_eigen(a);
        let scale = a.amax().max(f64::MIN_POSITIVE);
        let res = (0..3).map(|i| (a * n[i] - n[i] * e[i]).amax()).fold(0.0, f64::max) / scale;
        let q = Matrix3::from_columns(&n);
        (res, (q.transpose() * q - Matrix3::identity()).amax())
    }

    fn rotated(d: [f64; 3], axis: Vec3, angle: f64) -> Matrix3<f64> {
        let r = Rotation3::from_axis_angle(&Unit::new_normalize(axis), angle).into_inner();
        r * Matrix3::from_diagonal(&Vec3::from(d)) * r.transpose()
    }

    #[test]
    fn repeated_and_nearly_repeated_eigenvalues_are_resolved_to_round_off() {
        // exact and near multiplicities, rotated off the axes: the eigenvalues must
        // come back to a few ε·‖A‖ (the trigonometric formula alone errs by ~√ε ≈ 1e-8
        // on the near pairs), the vectors orthonormal to a few ε. Bound 1e-14: about
        // 50 ulp, the size of the handful of rounded products each step takes.
        let cases = [
            [1.0, 1.0, 1.0],
            [2.0, 1.0, 1.0],
            [0.5, 0.5, 3.0],
            [1.0, 1.0 + 1e-9, 2.0],
            [1.0, 1.0 + 1e-7, 1.0 - 1e-7],
            [1e-6, 1.0, 1.0],
            [4.0, 4.0, 1e-3],
            [1.0, 2.0, 3.0],
        ];
        for d in cases {
            for (axis, angle) in [
                (Vec3::new(1.0, 2.0, 3.0), 0.7),
                (Vec3::z(), 0.0),
                (Vec3::new(-1.0, 0.3, 0.1), 2.9),
            ] {
                let a = rotated(d, axis, angle);
                let (res, orth) = residuals(&a);
                assert!(
                    res < 1e-14 && orth < 1e-14,
                    "{d:?}: residual {res:e}, orthogonality {orth:e}"
                );
                let (mut e, _) = sym_eigen(&a);
                e.sort_by(f64::total_cmp);
                let mut want = d;
                want.sort_by(f64::total_cmp);
                for (x, y) in e.iter().zip(&want) {
                    assert!((x - y).abs() < 1e-14 * a.amax(), "{d:?}: {e:?}");
                }
            }
        }
    }

    #[test]
    fn random_symmetric_matrices_decompose() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for _ in 0..2000 {
            let m = Matrix3::from_fn(|_, _| rnd());
            let a = m.transpose() * m + Matrix3::identity() * rnd().abs() * 1e-3;
            let (res, orth) = residuals(&a);
            // 1e-14: as above, a few dozen ulp of ‖A‖
            assert!(
                res < 1e-14 && orth < 1e-14,
                "{a}: residual {res:e}, orthogonality {orth:e}"
            );
        }
    }

    /// The cubic's largest root without acos and cos: against the trigonometric
    /// formula on 100 001 points of [0, 1] (both ends included). Bound 4.5e-16
    /// relative: two ulp of a number in [√3, 2] — the formula's own rounding (acos,
    /// a division, cos) is about one, Newton's last step at most one more.
    #[test]
    fn largest_cubic_root_matches_the_trigonometric_formula() {
        let mut worst = 0.0f64;
        for i in 0..=100_000 {
            let rho = i as f64 / 100_000.0;
            let want = 2.0 * (rho.acos() / 3.0).cos();
            let got = largest_cubic_root(rho);
            worst = worst.max((got - want).abs() / want);
            assert!((got * got * got - 3.0 * got - 2.0 * rho).abs() < 1e-14, "{rho}: {got}");
        }
        assert!(worst < 4.5e-16, "worst relative difference {worst:e}");
    }

    #[test]
    fn zero_and_non_finite_matrices_do_not_panic() {
        assert_eq!(sym_eigen(&Matrix3::zeros()).0, [0.0; 3]);
        assert!(sym_eigen(&Matrix3::from_element(f64::NAN)).0[0].is_nan());
    }
}
