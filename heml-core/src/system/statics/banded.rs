//! A symmetric banded matrix and its in-place LDLᵀ factorisation (no pivoting): the
//! direct solver of the Newton iterations, fed in reverse Cuthill–McKee order.

/// Largest number of stored band entries (n·(b+1) f64, 320 MB) a solve may
/// allocate; a wider band falls back to an iterative method instead.
pub(super) const MAX_ENTRIES: usize = 40_000_000;

/// A symmetric banded matrix (lower band stored by rows) and its LDLᵀ factors.
pub(super) struct BandLdl {
    n: usize,
    b: usize,
    /// Row i holds columns i−b..i−1 at [i·b .. (i+1)·b).
    low: Vec<f64>,
    diag: Vec<f64>,
}

impl BandLdl {
    /// A zero n×n matrix of half-bandwidth `b` (entries (i, j) with |i − j| ≤ b).
    pub(super) fn new(n: usize, b: usize) -> Self {
        BandLdl {
            n,
            b,
            low: vec![0.0; n * b],
            diag: vec![0.0; n],
        }
    }

    /// Whether an n×n matrix of half-bandwidth `b` fits in [`MAX_ENTRIES`].
    pub(super) fn fits(n: usize, b: usize) -> bool {
        n.saturating_mul(b + 1) <= MAX_ENTRIES
    }

    /// Adds `v` at (row, col), col <= row.
    pub(super) fn add(&mut self, row: usize, col: usize, v: f64) {
        if row == col {
            self.diag[row] += v;
        } else {
            self.low[row * self.b + col + self.b - row] += v;
        }
    }

    /// In-place LDLᵀ; false when a pivot vanishes or is not finite.
    pub(super) fn factor(&mut self) -> bool {
        let (n, b) = (self.n, self.b);
        let scale = self.diag.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
        let mut u = vec![0.0; b];
        for i in 0..n {
            let j0 = i.saturating_sub(b);
            for j in j0..i {
                let k0 = j0.max(j.saturating_sub(b));
                let mut s = self.low[i * b + j + b - i];
                for k in k0..j {
                    s -= u[k + b - i] * self.low[j * b + k + b - j];
                }
                u[j + b - i] = s;
                self.low[i * b + j + b - i] = s / self.diag[j];
            }
            let mut d = self.diag[i];
            for j in j0..i {
                d -= u[j + b - i] * self.low[i * b + j + b - i];
            }
            if !(d.is_finite() && d.abs() > 1e-13 * scale) {
                return false;
            }
            self.diag[i] = d;
        }
        true
    }

    /// Solves (L D Lᵀ) x = r in place (after a successful [`BandLdl::factor`]).
    #[allow(clippy::needless_range_loop)] // banded index arithmetic reads clearer
    pub(super) fn solve(&self, r: &mut [f64]) {
        let (n, b) = (self.n, self.b);
        for i in 0..n {
            let mut s = r[i];
            for j in i.saturating_sub(b)..i {
                s -= self.low[i * b + j + b - i] * r[j];
            }
            r[i] = s;
        }
        for i in 0..n {
            r[i] /= self.diag[i];
        }
        for i in (0..n).rev() {
            let ri = r[i];
            for j in i.saturating_sub(b)..i {
                r[j] -= self.low[i * b + j + b - i] * ri;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn banded_ldl_solves_a_tridiagonal_system() {
        // −u'' = 1 discretised: tridiagonal (−1, 2, −1), plus an indefinite shift
        for shift in [0.0, -0.5] {
            let n = 50;
            let mut k = BandLdl::new(n, 2);
            for i in 0..n {
                k.add(i, i, 2.0 + shift);
                if i > 0 {
                    k.add(i, i - 1, -1.0);
                }
            }
            let mut x = vec![1.0; n];
            assert!(k.factor());
            k.solve(&mut x);
            // residual check: the factors are exact up to round-off (condition
            // number of this matrix < 1e4), so 1e-9 leaves a wide margin
            for i in 0..n {
                let mut ax = (2.0 + shift) * x[i];
                if i > 0 {
                    ax -= x[i - 1];
                }
                if i + 1 < n {
                    ax -= x[i + 1];
                }
                assert!((ax - 1.0).abs() < 1e-9, "row {i}: {ax}");
            }
        }
    }

    #[test]
    fn a_vanishing_pivot_is_refused() {
        // [[1, 1], [1, 1]] is singular: the second pivot is 0
        let mut k = BandLdl::new(2, 1);
        k.add(0, 0, 1.0);
        k.add(1, 0, 1.0);
        k.add(1, 1, 1.0);
        assert!(!k.factor());
    }
}
