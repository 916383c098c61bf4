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
//!
//! The decomposition has no branch: every special case is computed on safe values
//! and selected, so one function serves a single matrix ([`sym_eigen`]) and the four
//! tets of a batch ([`sym_eigen_lanes`], whose loop over the lanes vectorises) with
//! the same bits.

use crate::Vec3;
use nalgebra::Matrix3;

/// Eigenvalues (in no particular order) and orthonormal eigenvectors of the symmetric
/// matrix `a`: `a·n[i] = e[i]·n[i]`. The same arithmetic as each lane of
/// [`sym_eigen_lanes`] (one branch-free function serves both), so a tet gets the
/// same bits from the plain and the batched kernels.
pub fn sym_eigen(a: &Matrix3<f64>) -> ([f64; 3], [Vec3; 3]) {
    let (e, n) = eigen_sym([a[(0, 0)], a[(0, 1)], a[(0, 2)], a[(1, 1)], a[(1, 2)], a[(2, 2)]]);
    (e, n.map(Vec3::from))
}

/// [`sym_eigen`] of `N` symmetric matrices at once, given by their upper triangles
/// per lane (`a[k][lane]`, k over `[xx, xy, xz, yy, yz, zz]`): eigenvalues
/// `e[i][lane]` and eigenvectors `n[i][component][lane]`, each lane the bits
/// [`sym_eigen`] gives its matrix. The decomposition has no branch (its special cases
/// are selects), so the loop over the lanes runs four matrices per vector instruction
/// in the AVX2 block driver: its one long chain of dependent divisions and square
/// roots is paid once per four tets (the stretch kernels), where a tet at a time paid
/// it per tet.
///
/// ```
/// use heml_core::force::spectral::{sym_eigen, sym_eigen_lanes};
/// use nalgebra::Matrix3;
///
/// let m = [Matrix3::new(2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 5.0), Matrix3::identity()];
/// let a = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)].map(|(r, c)| [m[0][(r, c)], m[1][(r, c)]]);
/// let (e, n) = sym_eigen_lanes(&a);
/// let (e0, n0) = sym_eigen(&m[0]);
/// assert_eq!([e[0][0], e[1][0], e[2][0]], e0);
/// assert_eq!(n[1][2][0], n0[1][2]);
/// let mut values = e0;
/// values.sort_by(f64::total_cmp);
/// assert!((values[0] - 1.0).abs() < 1e-14 && (values[1] - 3.0).abs() < 1e-14 && (values[2] - 5.0).abs() < 1e-14);
/// assert_eq!([e[0][1], e[1][1], e[2][1]], [1.0; 3]);
/// ```
#[inline(always)]
#[allow(clippy::needless_range_loop)] // lanes in lock-step: what vectorises
pub fn sym_eigen_lanes<const N: usize>(a: &[[f64; N]; 6]) -> ([[f64; N]; 3], [[[f64; N]; 3]; 3]) {
    let mut e = [[0.0; N]; 3];
    let mut n = [[[0.0; N]; 3]; 3];
    for l in 0..N {
        let (el, nl) = eigen_sym([a[0][l], a[1][l], a[2][l], a[3][l], a[4][l], a[5][l]]);
        for i in 0..3 {
            e[i][l] = el[i];
            for c in 0..3 {
                n[i][c][l] = nl[i][c];
            }
        }
    }
    (e, n)
}

/// `if c { a } else { b }` on computed values: a select, not a branch.
#[inline(always)]
fn pick(c: bool, a: f64, b: f64) -> f64 {
    if c {
        a
    } else {
        b
    }
}

/// u × v.
#[inline(always)]
fn cross(u: [f64; 3], v: [f64; 3]) -> [f64; 3] {
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

/// u · v.
#[inline(always)]
fn dot(u: [f64; 3], v: [f64; 3]) -> f64 {
    u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
}

/// The decomposition of the symmetric matrix with upper triangle `m` (`[xx, xy, xz,
/// yy, yz, zz]`), written without a branch: every special case — a zero or
/// non-finite matrix, a multiple of the identity, the choice among the cross
/// products and of the complement, a vanishing rotation — is computed on safe
/// values and selected.
#[inline(always)]
fn eigen_sym(m: [f64; 6]) -> ([f64; 3], [[f64; 3]; 3]) {
    let finite = m.iter().fold(true, |ok, x| ok & x.is_finite());
    let scale = m.iter().fold(0.0f64, |s, x| s.max(x.abs()));
    // products with reciprocals rather than divisions: this decomposition runs for
    // every tet of a stretch law's force pass and of a projected tangent update, and
    // its divisions were a third of its time (one chain of latencies)
    let inv = 1.0 / pick(finite & (scale > 0.0), scale, 1.0);
    let s = [m[0] * inv, m[1] * inv, m[2] * inv, m[3] * inv, m[4] * inv, m[5] * inv];
    let q = (s[0] + s[3] + s[5]) * (1.0 / 3.0);
    let (b00, b11, b22) = (s[0] - q, s[3] - q, s[5] - q);
    let p2 = (b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (s[1] * s[1] + s[2] * s[2] + s[4] * s[4])) * (1.0 / 6.0);
    // a multiple of the identity (the zero matrix included): no deviator
    let round = p2 <= 0.0;
    let p = pick(round, 1.0, p2.sqrt());
    let ip = 1.0 / p;
    let bn = [b00 * ip, s[1] * ip, s[2] * ip, b11 * ip, s[4] * ip, b22 * ip];
    let [n00, n01, n02, n11, n12, n22] = bn;
    let det = n00 * (n11 * n22 - n12 * n12) - n01 * (n01 * n22 - n12 * n02) + n02 * (n01 * n12 - n11 * n02);
    // the eigenvalues of bn are the roots of t³ − 3t − 2r; r ≥ 0: the largest is the
    // separated one, else the smallest (minus the largest root for −r)
    let r = (0.5 * det).clamp(-1.0, 1.0);
    let root = largest_cubic_root(r.abs());
    let beta = pick(r >= 0.0, root, -root);
    let n0 = separated_vector(bn, beta);
    let (u, v) = complement(n0);
    // the 2×2 problem in span(u, v), diagonalised by one Jacobi rotation
    let times = |x: [f64; 3]| {
        [
            n00 * x[0] + n01 * x[1] + n02 * x[2],
            n01 * x[0] + n11 * x[1] + n12 * x[2],
            n02 * x[0] + n12 * x[1] + n22 * x[2],
        ]
    };
    let (bu, bv) = (times(u), times(v));
    let (c, sn) = jacobi_rotation(dot(u, bu), dot(u, bv), dot(v, bv));
    let n1 = [u[0] * c - v[0] * sn, u[1] * c - v[1] * sn, u[2] * c - v[2] * sn];
    let n2 = [u[0] * sn + v[0] * c, u[1] * sn + v[1] * c, u[2] * sn + v[2] * c];
    let value = |n: [f64; 3]| {
        let e = (q + p * dot(n, times(n))) * scale;
        pick(finite, pick(round, q * scale, e), f64::NAN)
    };
    let e = [value(n0), value(n1), value(n2)];
    // the axes for a multiple of the identity and a non-finite matrix
    let axes = !finite | round;
    let n = [
        [pick(axes, 1.0, n0[0]), pick(axes, 0.0, n0[1]), pick(axes, 0.0, n0[2])],
        [pick(axes, 0.0, n1[0]), pick(axes, 1.0, n1[1]), pick(axes, 0.0, n1[2])],
        [pick(axes, 0.0, n2[0]), pick(axes, 0.0, n2[1]), pick(axes, 1.0, n2[2])],
    ];
    (e, n)
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

/// The unit eigenvector of the separated eigenvalue `beta` of `bn` (upper
/// triangle): the largest cross product of two rows of bn − βI (which has rank 2, its
/// null space the vector); the x axis when all three vanish.
#[inline(always)]
fn separated_vector(bn: [f64; 6], beta: f64) -> [f64; 3] {
    let [m00, m01, m02, m11, m12, m22] = bn;
    let rows = [[m00 - beta, m01, m02], [m01, m11 - beta, m12], [m02, m12, m22 - beta]];
    let cands = [
        cross(rows[0], rows[1]),
        cross(rows[0], rows[2]),
        cross(rows[1], rows[2]),
    ];
    let norms = [
        dot(cands[0], cands[0]),
        dot(cands[1], cands[1]),
        dot(cands[2], cands[2]),
    ];
    // the first of the largest, as selects
    let first = (norms[0] >= norms[1]) & (norms[0] >= norms[2]);
    let second = !first & (norms[1] >= norms[2]);
    let best = |k: usize| pick(first, cands[0][k], pick(second, cands[1][k], cands[2][k]));
    let norm = pick(first, norms[0], pick(second, norms[1], norms[2]));
    let some = norm > 0.0;
    let inv = 1.0 / pick(some, norm, 1.0).sqrt();
    [
        pick(some, best(0) * inv, 1.0),
        pick(some, best(1) * inv, 0.0),
        pick(some, best(2) * inv, 0.0),
    ]
}

/// Two unit vectors completing the unit `w` to an orthonormal basis.
#[inline(always)]
fn complement(w: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let x_major = w[0].abs() > w[1].abs();
    // (−w_z, 0, w_x) or (0, w_z, −w_y), whichever is longer
    let u = [
        pick(x_major, -w[2], 0.0),
        pick(x_major, 0.0, w[2]),
        pick(x_major, w[0], -w[1]),
    ];
    let inv = 1.0 / dot(u, u).sqrt();
    let u = [u[0] * inv, u[1] * inv, u[2] * inv];
    (u, cross(w, u))
}

/// (cos θ, sin θ) of the rotation that diagonalises [[a, b], [b, d]] (stable form,
/// Golub & Van Loan §8.5.2): the columns (c, −s) and (s, c) are its eigenvectors.
/// (1, 0) when b = 0; a diagonal with a = d turns by 45°.
#[inline(always)]
fn jacobi_rotation(a: f64, b: f64, d: f64) -> (f64, f64) {
    let tau = (d - a) / (2.0 * pick(b == 0.0, 1.0, b));
    let t = 1.0f64.copysign(tau) / (tau.abs() + (1.0 + tau * tau).sqrt());
    let t = pick(tau == 0.0, 1.0, t);
    let c = 1.0 / (1.0 + t * t).sqrt();
    (pick(b == 0.0, 1.0, c), pick(b == 0.0, 0.0, t * c))
}

/// The divided difference (x^b − y^b)/(x − y) of the power t ↦ t^b (x, y > 0), and
/// its limit b·x^(b−1) at x = y: the coefficient a stretch law's tangent takes between
/// two eigenvalues of C (the Ogden law's terms), accurate where the plain quotient
/// loses every digit to cancellation. With y the larger and d = (x − y)/y ∈ (−1, 0],
/// it is y^(b−1)·expm1(b·ln_1p(d))/d, each factor accurate to a few ulp however close
/// x and y are. Symmetric in x and y.
///
/// ```
/// use heml_core::force::spectral::power_divided_difference;
/// // (4² − 1²)/(4 − 1) = 5, and 2·3 at coincidence
/// assert!((power_divided_difference(4.0, 1.0, 2.0) - 5.0).abs() < 1e-14);
/// assert_eq!(power_divided_difference(3.0, 3.0, 2.0), 6.0);
/// // a hair apart: the plain quotient would keep ~7 digits, this keeps ~15
/// let d = power_divided_difference(2.0, 2.0 * (1.0 - 1e-9), 0.5);
/// assert!((d - 0.5 / 2f64.sqrt()).abs() < 1e-9);
/// ```
pub fn power_divided_difference(x: f64, y: f64, b: f64) -> f64 {
    let (x, y) = if x <= y { (x, y) } else { (y, x) };
    let d = (x - y) / y;
    if d == 0.0 {
        return b * y.powf(b - 1.0);
    }
    y.powf(b - 1.0) * (b * d.ln_1p()).exp_m1() / d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::force::assembly::LANES;
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
        let mut rnd = crate::sampling::uniform(0x9e37_79b9_7f4a_7c15u64);
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

    /// The batched decomposition is the plain one lane by lane, to the bit: the
    /// batched and plain stretch kernels rely on it (same forces whichever path a
    /// tet takes). Random matrices with special ones in some lanes (zero, identity
    /// multiples, repeated eigenvalues, a NaN).
    #[test]
    fn lanes_equal_the_plain_decomposition_bit_for_bit() {
        let mut rnd = crate::sampling::uniform(0x2545_f491_4f6c_dd1du64);
        let special = [
            Matrix3::zeros(),
            Matrix3::identity() * 2.5,
            rotated([2.0, 1.0, 1.0], Vec3::new(1.0, 2.0, 3.0), 0.7),
            rotated([0.5, 0.5, 3.0], Vec3::z(), 0.0),
            Matrix3::from_element(f64::NAN),
        ];
        for round in 0..500 {
            let mats: [Matrix3<f64>; LANES] = std::array::from_fn(|l| {
                if (round + l) % 7 == 0 {
                    special[(round / 7 + l) % special.len()]
                } else {
                    let m = Matrix3::from_fn(|_, _| rnd());
                    m.transpose() * m
                }
            });
            let mut a = [[0.0; LANES]; 6];
            for (l, m) in mats.iter().enumerate() {
                for (k, (r, c)) in [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)].into_iter().enumerate() {
                    a[k][l] = m[(r, c)];
                }
            }
            let (e, n) = sym_eigen_lanes(&a);
            for (l, m) in mats.iter().enumerate() {
                let (pe, pn) = sym_eigen(m);
                for i in 0..3 {
                    assert_eq!(e[i][l].to_bits(), pe[i].to_bits(), "lane {l} of round {round}: {m}");
                    for c in 0..3 {
                        assert_eq!(n[i][c][l].to_bits(), pn[i][c].to_bits(), "lane {l} of round {round}");
                    }
                }
            }
        }
    }

    #[test]
    fn zero_and_non_finite_matrices_do_not_panic() {
        assert_eq!(sym_eigen(&Matrix3::zeros()).0, [0.0; 3]);
        assert!(sym_eigen(&Matrix3::from_element(f64::NAN)).0[0].is_nan());
    }

    #[test]
    fn divided_difference_is_accurate_near_and_at_coincidence() {
        // against the difference quotient in exact-enough form: for x, y apart
        // (1e-2 relative) the plain quotient loses only ~1e-14 relative; near
        // coincidence compare with the Taylor series b·y^(b−1)(1 + (b−1)d/2 + …)
        for b in [-2.0, -0.35, 0.5, 1.5, 4.0] {
            let (x, y) = (1.0, 1.01);
            let plain = (f64::powf(x, b) - f64::powf(y, b)) / (x - y);
            let got = power_divided_difference(x, y, b);
            assert!((got - plain).abs() <= 1e-12 * plain.abs(), "{b}: {got} vs {plain}");
            assert_eq!(power_divided_difference(y, x, b), got);
            let y = 2.0;
            let x = y * (1.0 - 1e-9);
            let d = (x - y) / y;
            let series = b * f64::powf(y, b - 1.0) * (1.0 + (b - 1.0) * d / 2.0 + (b - 1.0) * (b - 2.0) * d * d / 6.0);
            let got = power_divided_difference(x, y, b);
            assert!((got - series).abs() <= 1e-14 * series.abs(), "{b}: {got} vs {series}");
            let at = power_divided_difference(y, y, b);
            assert!((at - b * f64::powf(y, b - 1.0)).abs() <= 1e-15 * at.abs());
        }
    }
}
