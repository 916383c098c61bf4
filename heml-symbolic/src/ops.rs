//! How the fast kernels evaluate constant powers, so that code generated from a
//! graph and a run-time tape of it compute alike.

/// `n` when the constant exponent `b` is n/3 for a small n not divisible by 3 (the
/// isochoric powers J^(−2/3), J^(−4/3), …): a fast kernel takes a cube root instead
/// of exp(b·ln a), about half the work, vectorised alike.
pub fn thirds(b: f64) -> Option<i32> {
    let n = (3.0 * b).round();
    let exact = (3.0 * b - n).abs() <= 4.0 * f64::EPSILON * n.abs();
    (exact && n.abs() <= 12.0 && n % 3.0 != 0.0).then_some(n as i32)
}
