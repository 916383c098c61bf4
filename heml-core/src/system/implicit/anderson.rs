//! Anderson acceleration of the chord iterations on a kept Cholesky factor.
//!
//! A chord iteration is the fixed-point iteration x ← x + g(x), g = P⁻¹ r(x) with P
//! the kept (stale) factor: it contracts the residual only as well as P still
//! approximates the tangent, and on the ν = 0.49 liver's sag it was measured to
//! stall (contractions 0.67, 0.69, 0.78, 0.98 in a row) on the few modes the stale
//! factor misses. Anderson mixing (type II, Walker & Ni 2011) takes instead the
//! combination of the step's last iterates whose corrections g cancel best in the
//! least-squares sense: x_{k+1} = x_k + g_k − (ΔX + ΔG) γ, γ = argmin |g_k − ΔG γ|,
//! with ΔX, ΔG the differences of the current iterate and correction to the
//! earlier ones. It is a multisecant quasi-Newton method on the same equations
//! r(x) = 0 (its fixed point is the chord iteration's: the exact step), costs a few
//! vector operations per iteration (no tangent), and recovers the missed modes from
//! the residuals already evaluated. The history is the secant pairs (Δx, Δg) of
//! consecutive iterates on one factor: the step's own, completed by those of the
//! earlier steps on the same factor — the step's inertial term moves r by a
//! constant from step to step, which cancels in a difference, so those pairs still
//! describe the slowly changing tangent, and the first chord iteration of a step —
//! which had no history — is mixed too. Each mixing adds one pair and one row of
//! the least-squares problem's Gram matrix (session 25: the differences to every
//! earlier iterate and the whole matrix were formed anew each time, ~2 ms of the
//! liver's long run). Measured on `heml bench --implicit`'s default preset (session 24):
//! the liver's 12-step sag takes 3 factorisations instead of 6, its 200-step long
//! run 12 instead of 19 (328 Newton iterations instead of 371), gen_kidney_20k's long
//! run 18 instead of 21. The solver carries them with one Newton iteration per step
//! only (steps iterated to the Newton tolerance took more factorisations with
//! them). A new factor or contact correction clears both (g is then another map).
//! A correction that is not a descent direction of the line search's merit
//! (gᵀ r ≤ 0) falls back to the plain chord correction.

use nalgebra::{DMatrix, DVector};
use std::collections::VecDeque;

/// Secant pairs kept for the mixing (5: the least-squares problem stays
/// well-conditioned and the chord iterations of a step are rarely more).
const MEMORY: usize = 5;

/// The secant pairs on the current factor and the step's last iterate.
///
/// The pairs are differences of *consecutive* iterates, (x_{i+1} − x_i, g_{i+1} −
/// g_i): they span the same space as the differences of the current iterate to the
/// earlier ones (so the mixed correction is the same up to round-off), but stay the
/// same when a new iterate arrives, so that each mixing adds one pair and one row
/// of the Gram matrix ΔGᵀΔG (`MEMORY` dot products) instead of forming all the
/// differences and the whole matrix again. The step's own pairs and those carried
/// from the earlier steps are one chronological list: the newest [`MEMORY`] are the
/// step's own first, then the newest carried ones.
#[derive(Debug, Default)]
pub(super) struct Anderson {
    /// (Δx, Δg) by degree of freedom, oldest first, at most [`MEMORY`].
    pairs: VecDeque<(Vec<f64>, Vec<f64>)>,
    /// gram[i][j] = Δg_i·Δg_j of `pairs` (same order; the leading `pairs.len()`
    /// rows and columns are in use).
    gram: [[f64; MEMORY]; MEMORY],
    /// The step's last iterate and its raw correction (None at a step's start: the
    /// next step's first iterate forms no pair with the last step's, whose residual
    /// had another inertial term).
    last: Option<(Vec<f64>, Vec<f64>)>,
    /// Vectors of dropped pairs, reused for new ones (no allocation per mixing).
    spare: Vec<(Vec<f64>, Vec<f64>)>,
    /// Scratch of the mixed correction.
    out: Vec<f64>,
}

impl Anderson {
    /// Forgets the pairs and the last iterate (a new factor: g is then another
    /// map).
    pub fn clear(&mut self) {
        while let Some(p) = self.pairs.pop_front() {
            self.spare.push(p);
        }
        self.last = None;
    }

    /// Ends a step: its pairs stay (carried to the next step on the same factor),
    /// its last iterate is dropped.
    pub fn end_step(&mut self) {
        self.last = None;
    }

    /// Records iterate `x` and its correction `g` = P⁻¹ r(x), and replaces `g` by
    /// the mixed correction when the pairs allow one that is a descent direction
    /// (dot with the residual `r` positive) and finite.
    pub fn mix(&mut self, x: &[f64], g: &mut [f64], r: &[f64]) {
        // pairs of another numbering of the unknowns are of another map
        if self.pairs.front().is_some_and(|(dx, _)| dx.len() != x.len())
            || self.last.as_ref().is_some_and(|(lx, _)| lx.len() != x.len())
        {
            self.clear();
        }
        let (mut lx, mut lg) = match self.last.take() {
            Some((lx, lg)) => {
                self.push_pair(x, g, &lx, &lg);
                (lx, lg)
            }
            None => self.spare.pop().unwrap_or_default(),
        };
        lx.clear();
        lx.extend_from_slice(x);
        lg.clear();
        lg.extend_from_slice(g);
        self.last = Some((lx, lg));
        self.apply(g, r);
    }

    /// Appends the pair (x − lx, g − lg), dropping the oldest beyond [`MEMORY`],
    /// and its row of the Gram matrix.
    fn push_pair(&mut self, x: &[f64], g: &[f64], lx: &[f64], lg: &[f64]) {
        if self.pairs.len() == MEMORY {
            if let Some(p) = self.pairs.pop_front() {
                self.spare.push(p);
            }
            // the oldest pair's row and column leave: the rest moves up and left
            for i in 1..MEMORY {
                for j in 1..MEMORY {
                    self.gram[i - 1][j - 1] = self.gram[i][j];
                }
            }
        }
        let (mut dx, mut dg) = self.spare.pop().unwrap_or_default();
        difference_into(x, lx, &mut dx);
        difference_into(g, lg, &mut dg);
        let m = self.pairs.len();
        for (i, (_, q)) in self.pairs.iter().enumerate() {
            let v = dot(q, &dg);
            self.gram[i][m] = v;
            self.gram[m][i] = v;
        }
        self.gram[m][m] = dot(&dg, &dg);
        self.pairs.push_back((dx, dg));
    }

    /// g ← g − (ΔX + ΔG) γ with γ the least-squares solution of ΔG γ ≈ g (normal
    /// equations, regularised by 10⁻¹⁰ of their largest diagonal entry), when
    /// there are pairs, the equations can be solved, and the result is a finite
    /// descent direction (dot with `r` positive).
    fn apply(&mut self, g: &mut [f64], r: &[f64]) {
        let m = self.pairs.len();
        if m == 0 {
            return;
        }
        let mut gram = DMatrix::from_fn(m, m, |i, j| self.gram[i][j]);
        let scale = (0..m).map(|i| gram[(i, i)]).fold(0.0, f64::max);
        if !(scale > 0.0 && scale.is_finite()) {
            return;
        }
        for i in 0..m {
            gram[(i, i)] += 1e-10 * scale;
        }
        let rhs = DVector::from_fn(m, |i, _| dot(&self.pairs[i].1, g));
        let Some(chol) = gram.cholesky() else { return };
        let gamma = chol.solve(&rhs);
        let mut out = std::mem::take(&mut self.out);
        out.clear();
        out.extend_from_slice(g);
        for (k, (dx, dg)) in self.pairs.iter().enumerate() {
            let c = gamma[k];
            for (o, (a, b)) in out.iter_mut().zip(dx.iter().zip(dg)) {
                *o -= c * (a + b);
            }
        }
        if dot(&out, r) > 0.0 && out.iter().all(|v| v.is_finite()) {
            g.copy_from_slice(&out);
        }
        self.out = out;
    }
}

/// out = a − b, element by element (`out` resized).
fn difference_into(a: &[f64], b: &[f64], out: &mut Vec<f64>) {
    out.clear();
    out.extend(a.iter().zip(b).map(|(u, v)| u - v));
}

/// a·b.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(u, v)| u * v).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a linear fixed-point map g(x) = P⁻¹(b − A x) with a poor P (a diagonal
    /// that misses the coupling), Anderson mixing with enough memory solves the
    /// 3-unknown system in at most 4 iterations (GMRES-equivalence for linear
    /// problems: the exact solution is in the span after n + 1 iterates), where
    /// the plain iteration still errs by ~0.5 %.
    #[test]
    fn anderson_solves_a_linear_fixed_point_problem_where_richardson_crawls() {
        let a = [[4.0, 1.5, 0.0], [1.5, 3.0, 1.2], [0.0, 1.2, 2.0]];
        let b = [1.0, 2.0, 3.0];
        let p = [4.0, 3.0, 2.0];
        let residual = |x: &[f64]| -> Vec<f64> {
            (0..3)
                .map(|i| b[i] - (0..3).map(|j| a[i][j] * x[j]).sum::<f64>())
                .collect()
        };
        let correction = |r: &[f64]| -> Vec<f64> { (0..3).map(|i| r[i] / p[i]).collect() };
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let r0 = norm(&b);
        let (mut plain, mut mixed) = (vec![0.0; 3], vec![0.0; 3]);
        let mut anderson = Anderson::default();
        for _ in 0..5 {
            let g = correction(&residual(&plain));
            plain.iter_mut().zip(&g).for_each(|(x, d)| *x += d);
            let r = residual(&mixed);
            let mut g = correction(&r);
            anderson.mix(&mixed, &mut g, &r);
            mixed.iter_mut().zip(&g).for_each(|(x, d)| *x += d);
        }
        let (e_plain, e_mixed) = (norm(&residual(&plain)) / r0, norm(&residual(&mixed)) / r0);
        // exact up to the normal equations' round-off (condition ~1e8 at worst: 1e-8)
        assert!(e_mixed < 1e-8, "anderson: relative residual {e_mixed:e}");
        assert!(e_plain > 1e-3, "the plain iteration should still crawl: {e_plain:e}");
    }

    /// The pairs a step leaves carry over to the next step on the same factor:
    /// with the right-hand side moved (as a time step's inertial term moves it), the
    /// next step's first mixed iteration already solves the linear problem (the
    /// carried differences span the space and hold the map's slope exactly), where
    /// the plain chord iteration, and the mixing without carried pairs, leave a
    /// few per cent of the residual.
    #[test]
    fn carried_pairs_mix_the_first_iteration_of_the_next_step() {
        let a = [[4.0, 1.5, 0.0], [1.5, 3.0, 1.2], [0.0, 1.2, 2.0]];
        let p = [4.0, 3.0, 2.0];
        let residual = |x: &[f64], b: &[f64; 3]| -> Vec<f64> {
            (0..3)
                .map(|i| b[i] - (0..3).map(|j| a[i][j] * x[j]).sum::<f64>())
                .collect()
        };
        let correction = |r: &[f64]| -> Vec<f64> { (0..3).map(|i| r[i] / p[i]).collect() };
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let mut anderson = Anderson::default();
        // step 1: four mixed iterations from 0
        let b1 = [1.0, 2.0, 3.0];
        let mut x = vec![0.0; 3];
        for _ in 0..4 {
            let r = residual(&x, &b1);
            let mut g = correction(&r);
            anderson.mix(&x, &mut g, &r);
            x.iter_mut().zip(&g).for_each(|(x, d)| *x += d);
        }
        anderson.end_step();
        assert_eq!(anderson.pairs.len(), 3);
        assert!(anderson.last.is_none());
        // step 2: another right-hand side, one iteration from the end of step 1
        let b2 = [1.5, 1.0, 3.5];
        let r0 = residual(&x, &b2);
        let after = |g: &[f64]| -> f64 {
            let y: Vec<f64> = x.iter().zip(g).map(|(x, d)| x + d).collect();
            norm(&residual(&y, &b2)) / norm(&r0)
        };
        let plain = after(&correction(&r0));
        let mut fresh = Anderson::default();
        let mut g = correction(&r0);
        fresh.mix(&x, &mut g, &r0);
        let uncarried = after(&g);
        let mut g = correction(&r0);
        anderson.mix(&x, &mut g, &r0);
        let carried = after(&g);
        // exact but for the regularisation: step 1's last pair was taken near its
        // solution (|Δg|² ~1e-10 of the largest pair's), where the 1e-10 shift of the
        // normal equations damps it (measured 6.9e-8); the plain iteration leaves > 1e-2
        assert!(carried < 1e-6, "carried: relative residual {carried:e}");
        assert!(
            plain > 1e-2 && uncarried == plain,
            "plain {plain:e}, without carried pairs {uncarried:e}"
        );
        // a new factor forgets them
        anderson.clear();
        assert!(anderson.pairs.is_empty() && anderson.last.is_none());
    }
}
