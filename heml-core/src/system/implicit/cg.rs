//! Preconditioned conjugate gradients, given the operator and preconditioner as
//! products: the linear solver of the implicit integrators' Newton iterations.
//!
//! The dot products are fused into the passes that produce their operands (the
//! operator product returns pᵀAp, the preconditioner rᵀz, the update of x and r
//! returns rᵀr), so an iteration reads each vector about once less; the sums run
//! over fixed chunks, in parallel, and add the chunks' partial sums in order: the
//! same bits for any thread count.

use rayon::prelude::*;
use std::ops::Range;

/// What a conjugate-gradient solve reached.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CgReport {
    /// Iterations (operator products) used.
    pub iterations: usize,
    /// Final ‖b − A x‖ / ‖b‖ (0 when b = 0), from the recursively updated residual.
    pub relative_residual: f64,
    /// Whether the relative residual reached the tolerance.
    pub converged: bool,
    /// Whether a direction of non-positive curvature (pᵀAp ≤ 0) stopped the
    /// iteration: A is not positive definite (the solution so far is kept).
    pub breakdown: bool,
}

/// Entries per chunk of the fused, parallel dot products and vector updates: fixed,
/// so the partial sums (and their order) do not depend on the thread count.
/// A multiple of 3, so that a chunk holds whole nodes.
pub(super) const CHUNK: usize = 1536;
const _: () = assert!(CHUNK.is_multiple_of(3));

/// Σ_k `part(range_k)` over the fixed chunks of `0..n`, computed in parallel and
/// added in chunk order: the same bits for any thread count.
pub(super) fn chunked_sum(n: usize, part: impl Fn(Range<usize>) -> f64 + Sync) -> f64 {
    let partial: Vec<f64> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|k| part(k * CHUNK..((k + 1) * CHUNK).min(n)))
        .collect();
    partial.iter().sum()
}

/// The dot product of two vectors (chunked: the same bits for any thread count).
pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    chunked_sum(a.len(), |r| a[r.clone()].iter().zip(&b[r]).map(|(x, y)| x * y).sum())
}

/// The operator and preconditioner of a conjugate-gradient solve, each returning the
/// dot product CG needs from its result, so that it is computed in the same pass.
pub trait CgOperator {
    /// out = A p; returns pᵀ out.
    fn apply_dot(&mut self, p: &[f64], out: &mut [f64]) -> f64;
    /// z = P⁻¹ r (P symmetric positive definite); returns rᵀ z.
    fn precondition_dot(&mut self, r: &[f64], z: &mut [f64]) -> f64;
}

/// A [`CgOperator`] from two closures (`apply(p, out)`: out = A p, `precond(r, z)`:
/// z = P⁻¹ r), the dot products taken in separate passes.
struct Closures<A, P>(A, P);

impl<A: FnMut(&[f64], &mut [f64]), P: Fn(&[f64], &mut [f64])> CgOperator for Closures<A, P> {
    fn apply_dot(&mut self, p: &[f64], out: &mut [f64]) -> f64 {
        (self.0)(p, out);
        dot(p, out)
    }
    fn precondition_dot(&mut self, r: &[f64], z: &mut [f64]) -> f64 {
        (self.1)(r, z);
        dot(r, z)
    }
}

/// Solves A x = b for symmetric positive definite A, given only the products
/// `apply(p, out)`: out = A p, and the preconditioner `precond(r, out)`: out = P⁻¹ r
/// (symmetric positive definite). `x` is the starting guess and holds the result.
/// Stops when ‖b − A x‖ ≤ `tol`·‖b‖ or after `max_iterations` products.
pub fn pcg(
    apply: impl FnMut(&[f64], &mut [f64]),
    precond: impl Fn(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    tol: f64,
    max_iterations: usize,
) -> CgReport {
    pcg_fused(&mut Closures(apply, precond), b, x, tol, max_iterations)
}

/// [`pcg`] on a [`CgOperator`], whose products return the dot products CG needs:
/// per iteration one operator product, one preconditioner application and two
/// parallel vector passes (x, r and rᵀr; then p).
pub fn pcg_fused(op: &mut impl CgOperator, b: &[f64], x: &mut [f64], tol: f64, max_iterations: usize) -> CgReport {
    let n = b.len();
    let bnorm = dot(b, b).sqrt();
    if bnorm == 0.0 {
        x.fill(0.0);
        return CgReport {
            converged: true,
            ..CgReport::default()
        };
    }
    let mut r = vec![0.0; n];
    let mut ap = vec![0.0; n];
    op.apply_dot(x, &mut ap);
    r.par_iter_mut()
        .zip(b.par_iter().zip(&ap))
        .with_min_len(CHUNK)
        .for_each(|(r, (b, ap))| *r = b - ap);
    let mut z = vec![0.0; n];
    let mut rz = op.precondition_dot(&r, &mut z);
    let mut p = z.clone();
    let mut report = CgReport::default();
    let mut rnorm = dot(&r, &r).sqrt();
    let mut it = 0;
    while rnorm > tol * bnorm && it < max_iterations {
        let pap = op.apply_dot(&p, &mut ap);
        // not `pap <= 0.0`: a NaN curvature is a breakdown too
        if pap.is_nan() || pap <= 0.0 {
            report.breakdown = true;
            break;
        }
        let alpha = rz / pap;
        rnorm = update_x_r(alpha, &p, &ap, x, &mut r).sqrt();
        it += 1;
        let rz_new = op.precondition_dot(&r, &mut z);
        let beta = rz_new / rz;
        rz = rz_new;
        p.par_chunks_mut(CHUNK)
            .zip(z.par_chunks(CHUNK))
            .for_each(|(p, z)| p.iter_mut().zip(z).for_each(|(p, z)| *p = z + beta * *p));
    }
    // a breakdown's product counts as used
    report.iterations = it + usize::from(report.breakdown);
    report.relative_residual = rnorm / bnorm;
    report.converged = rnorm <= tol * bnorm;
    report
}

/// x += α p, r −= α A p in one parallel pass over fixed chunks; returns rᵀr.
fn update_x_r(alpha: f64, p: &[f64], ap: &[f64], x: &mut [f64], r: &mut [f64]) -> f64 {
    let partial: Vec<f64> = x
        .par_chunks_mut(CHUNK)
        .zip(r.par_chunks_mut(CHUNK))
        .zip(p.par_chunks(CHUNK).zip(ap.par_chunks(CHUNK)))
        .map(|((x, r), (p, ap))| {
            let mut rr = 0.0;
            for (((x, r), p), ap) in x.iter_mut().zip(r.iter_mut()).zip(p).zip(ap) {
                *x += alpha * p;
                *r -= alpha * ap;
                rr += *r * *r;
            }
            rr
        })
        .collect();
    partial.iter().sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// A random symmetric positive definite matrix with a spread diagonal (condition
    /// number ~1e3) and a right-hand side.
    fn spd(n: usize, seed: u64) -> (DMatrix<f64>, DVector<f64>) {
        let mut s = seed;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let g = DMatrix::from_fn(n, n, |_, _| rnd());
        let d = DMatrix::from_diagonal(&DVector::from_fn(n, |i, _| 10f64.powf(3.0 * i as f64 / n as f64)));
        let a = &g * g.transpose() * 0.1 + d;
        let b = DVector::from_fn(n, |_, _| rnd());
        (a, b)
    }

    #[test]
    fn pcg_matches_a_direct_solve() {
        let n = 60;
        let (a, b) = spd(n, 0x1234_5678_9abc_def1);
        let exact = a.clone().cholesky().unwrap().solve(&b);
        for jacobi in [false, true] {
            let diag: Vec<f64> = (0..n).map(|i| a[(i, i)]).collect();
            let mut x = vec![0.0; n];
            let rep = pcg(
                |p, out| {
                    let y = &a * DVector::from_column_slice(p);
                    out.copy_from_slice(y.as_slice());
                },
                |r, out| {
                    for i in 0..n {
                        out[i] = if jacobi { r[i] / diag[i] } else { r[i] };
                    }
                },
                b.as_slice(),
                &mut x,
                1e-12,
                1000,
            );
            assert!(rep.converged && !rep.breakdown, "{rep:?}");
            // in exact arithmetic CG ends in n steps; allow the loss of orthogonality
            assert!(rep.iterations <= 3 * n, "{rep:?}");
            // ‖x − x*‖ ≤ κ·tol·‖x*‖ with κ ~ 1e3 and tol 1e-12: 1e-8 is a safe bound
            let err = (DVector::from_column_slice(&x) - &exact).norm() / exact.norm();
            assert!(err < 1e-8, "jacobi {jacobi}: relative error {err:e}");
        }
    }

    #[test]
    fn pcg_reports_an_indefinite_operator_and_the_iteration_cap() {
        let n = 10;
        // diag(1, −1, 1, …): the first direction r = b = (1, 1, …) has pᵀAp = 0
        let b = vec![1.0; n];
        let mut x = vec![0.0; n];
        let sign = |i: usize| if i.is_multiple_of(2) { 1.0 } else { -1.0 };
        let rep = pcg(
            |p, out| (0..n).for_each(|i| out[i] = sign(i) * p[i]),
            |r, out| out.copy_from_slice(r),
            &b,
            &mut x,
            1e-10,
            50,
        );
        assert!(rep.breakdown && !rep.converged, "{rep:?}");
        let (a, b) = spd(40, 99);
        let mut x = vec![0.0; 40];
        let rep = pcg(
            |p, out| out.copy_from_slice((&a * DVector::from_column_slice(p)).as_slice()),
            |r, out| out.copy_from_slice(r),
            b.as_slice(),
            &mut x,
            1e-14,
            3,
        );
        assert_eq!(rep.iterations, 3);
        assert!(!rep.converged && rep.relative_residual > 1e-14);
    }
}
