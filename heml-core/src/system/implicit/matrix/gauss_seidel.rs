//! Symmetric block Gauss–Seidel in a separator ordering: the parallel, deterministic
//! default preconditioner of the implicit solves.
//!
//! The nodes are cut into a fixed number of contiguous ranges (parts, balanced by
//! stored blocks; the number depends on the mesh only, never on the thread count).
//! A node coupled to a node of another part is a separator node; the others are
//! interior, and interior nodes of different parts are never coupled. The sweeps
//! run in the ordering "all interior nodes (by part, ascending), then the separator
//! nodes (ascending)": the forward sweep does every part's interior in parallel,
//! then the separator sequentially, the backward sweep the separator backwards, then
//! every part's interior backwards in parallel. This is the symmetric block
//! Gauss–Seidel splitting (D + L) D⁻¹ (D + U) of the symmetrically permuted matrix —
//! every coupling kept, so symmetric positive definite whenever the matrix is, with
//! about the iteration count of the sweep in node order — and each node's arithmetic
//! is fixed by the ordering: the same bits for any thread count. Nodes are numbered
//! along a Morton curve at load, so a range is a compact piece of the organ and the
//! separator a thin layer.
//!
//! (Dropping the couplings between the parts instead — block-Jacobi over the parts,
//! Gauss–Seidel inside — took 35 % more iterations with 2 parts and 60 % with 8 on
//! gen_kidney_20k at ν = 0.49: at this incompressibility the cut couplings matter.)

use super::{block_of, BlockMatrix};
use nalgebra::Vector3;
use rayon::prelude::*;

/// Nodes per part at least (below it, a part's sweep is too short to be worth a task).
const MIN_PART_NODES: usize = 128;
/// Parts at most. More parts serve more threads but enlarge the sequential
/// separator; 2 suit the 2-core machines this library is tuned on (measured in
/// `docs/journal/implicit-steps.md`).
const MAX_PARTS: usize = 2;

/// The parallel Gauss–Seidel ordering of a [`BlockMatrix`]'s pattern.
#[derive(Debug, Clone)]
pub(in crate::system) struct GsOrdering {
    /// First node of each part, and n at the end.
    bounds: Vec<usize>,
    /// Whether each node is a separator node.
    separator: Vec<bool>,
    /// The separator nodes, ascending.
    separator_nodes: Vec<u32>,
}

impl BlockMatrix {
    /// The ordering of the parallel Gauss–Seidel sweeps: `parts` contiguous node
    /// ranges with about the same number of stored blocks each (fewer when the
    /// matrix is small: at least 128 nodes a part, at most 2 parts when `parts` is
    /// `None`), and their separator.
    pub(in crate::system) fn gauss_seidel_ordering(&self, parts: Option<usize>) -> GsOrdering {
        let n = self.n_nodes();
        let count = parts.unwrap_or((n / MIN_PART_NODES).clamp(1, MAX_PARTS)).max(1);
        let nnz = self.start[n];
        let mut bounds: Vec<usize> = (0..=count)
            .map(|k| self.start.partition_point(|&s| s < k * nnz / count).min(n))
            .collect();
        bounds[0] = 0;
        bounds[count] = n;
        bounds.dedup();
        let mut separator = vec![false; n];
        for w in bounds.windows(2) {
            let (lo, hi) = (w[0], w[1]);
            for (i, s) in separator[lo..hi].iter_mut().enumerate() {
                let row = &self.col[self.start[lo + i]..self.start[lo + i + 1]];
                // columns ascending: the first and last tell whether any lies outside
                *s = row.first().is_some_and(|&j| (j as usize) < lo) || row.last().is_some_and(|&j| j as usize >= hi);
            }
        }
        let separator_nodes = (0..n as u32).filter(|&i| separator[i as usize]).collect();
        GsOrdering {
            bounds,
            separator,
            separator_nodes,
        }
    }

    /// z = P⁻¹ r, P the symmetric block Gauss–Seidel splitting of the matrix in the
    /// separator ordering `ord` (see the module); returns rᵀz. Held coordinates get 0
    /// (their inverse diagonal rows are zero).
    pub(in crate::system) fn parallel_gauss_seidel(&self, ord: &GsOrdering, r: &[f64], z: &mut [f64]) -> f64 {
        let sep = &ord.separator;
        // forward, interiors: lower = interior neighbours before i (all in i's part)
        self.for_each_part(ord, z, |lo, z| {
            for i in lo..lo + z.len() / 3 {
                if !sep[i] {
                    let t = self.lower_sum(i, block_of(r, i), |j| !sep[j] && j < i, |j| block_of(z, j - lo));
                    set(z, i - lo, self.dinv[i] * t);
                }
            }
            0.0
        });
        // forward then backward, separator: lower = every interior neighbour and the
        // separator nodes before i; upper = the separator nodes after i
        for &i in &ord.separator_nodes {
            let i = i as usize;
            let t = self.lower_sum(i, block_of(r, i), |j| !sep[j] || j < i, |j| block_of(z, j));
            set(z, i, self.dinv[i] * t);
        }
        let mut rz_separator = 0.0;
        for &i in ord.separator_nodes.iter().rev() {
            let i = i as usize;
            let t = self.lower_sum(i, Vector3::zeros(), |j| sep[j] && j > i, |j| block_of(z, j));
            let zi = block_of(z, i) + self.dinv[i] * t;
            set(z, i, zi);
            rz_separator += zi.dot(&block_of(r, i));
        }
        // backward, interiors: upper = interior neighbours after i and every
        // separator neighbour (all in i's part)
        let rz_interior = self.for_each_part(ord, z, |lo, z| {
            let mut rz = 0.0;
            for i in (lo..lo + z.len() / 3).rev() {
                if !sep[i] {
                    let t = self.lower_sum(i, Vector3::zeros(), |j| sep[j] || j > i, |j| block_of(z, j - lo));
                    let zi = block_of(z, i - lo) + self.dinv[i] * t;
                    set(z, i - lo, zi);
                    rz += zi.dot(&block_of(r, i));
                }
            }
            rz
        });
        rz_interior + rz_separator
    }

    /// t − Σ A_ij v(j) over the off-diagonal blocks of row i whose column j passes
    /// `take` (in column order): the forward sweep's right-hand side from t = r_i,
    /// the backward sweep's correction −Σ_upper A_ij z_j from t = 0.
    #[inline]
    fn lower_sum(
        &self,
        i: usize,
        mut t: Vector3<f64>,
        take: impl Fn(usize) -> bool,
        v: impl Fn(usize) -> Vector3<f64>,
    ) -> Vector3<f64> {
        for b in self.start[i]..self.start[i + 1] {
            let j = self.col[b] as usize;
            if j != i && take(j) {
                t -= self.val[b] * v(j);
            }
        }
        t
    }

    /// Runs `sweep(first node, that part's slice of z)` on every part in parallel;
    /// returns the sum of its results in part order.
    fn for_each_part(&self, ord: &GsOrdering, z: &mut [f64], sweep: impl Fn(usize, &mut [f64]) -> f64 + Sync) -> f64 {
        let mut pieces: Vec<(usize, &mut [f64])> = Vec::with_capacity(ord.bounds.len());
        let mut rest = z;
        for w in ord.bounds.windows(2) {
            let (piece, tail) = rest.split_at_mut(3 * (w[1] - w[0]));
            pieces.push((w[0], piece));
            rest = tail;
        }
        let partial: Vec<f64> = pieces.into_par_iter().map(|(lo, z)| sweep(lo, z)).collect();
        partial.iter().sum()
    }
}

/// Writes node `i`'s block of `z`.
#[inline]
fn set(z: &mut [f64], i: usize, v: Vector3<f64>) {
    z[3 * i..3 * i + 3].copy_from_slice(v.as_slice());
}

#[cfg(test)]
mod tests {
    use super::super::tests::{assert_inverts_splitting, rnd, setup};

    /// The parallel sweeps apply the inverse of the symmetric Gauss–Seidel splitting
    /// of the matrix in their ordering (interior nodes, then the separator: every
    /// coupling kept), built densely, and return rᵀz; with 2 parts on a 36-node box
    /// (a separator with interior nodes on both sides: the ordering differs from the
    /// node order) and 3 (all separator). Bounds as in `assert_inverts_splitting`; rᵀz is a sum of 100 O(1)
    /// terms, 1e-12 relative is ~100× its round-off.
    #[test]
    fn parallel_gauss_seidel_inverts_the_splitting_of_its_ordering() {
        let (m, dense, mask) = setup();
        let mut s = 5u64;
        let r: Vec<f64> = mask.iter().map(|&f| if f { rnd(&mut s) } else { 0.0 }).collect();
        for parts in [2, 3] {
            let ord = m.gauss_seidel_ordering(Some(parts));
            assert_eq!(ord.bounds.len(), parts + 1);
            // on this small box 2 parts leave interior nodes; with 3, every node is
            // next to another part (the ordering is then the node order)
            let n_sep = ord.separator_nodes.len();
            assert!(
                n_sep > 0 && (parts == 3 || n_sep < m.n_nodes()),
                "{parts} parts: {n_sep} separator nodes"
            );
            let mut order: Vec<usize> = (0..m.n_nodes()).filter(|&i| !ord.separator[i]).collect();
            order.extend(ord.separator_nodes.iter().map(|&i| i as usize));
            let mut z = vec![0.0; mask.len()];
            let rz = m.parallel_gauss_seidel(&ord, &r, &mut z);
            assert_inverts_splitting(&dense, &mask, &order, &r, &z);
            let want: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
            assert!((rz - want).abs() <= 1e-12 * want.abs(), "{parts} parts: {rz} vs {want}");
        }
    }

    /// The preconditioner is symmetric positive definite (sᵀP⁻¹r = rᵀP⁻¹s to 1e-12
    /// relative — round-off of sums of ~100 O(1) terms is ~1e-15 — and rᵀP⁻¹r > 0 for
    /// random r), and its result has the same bits on 1, 2 and 3 threads.
    #[test]
    fn parallel_gauss_seidel_is_spd_and_thread_independent() {
        let (m, _, mask) = setup();
        let ord = m.gauss_seidel_ordering(Some(3));
        let mut seed = 17u64;
        let mut random = || -> Vec<f64> { mask.iter().map(|&f| if f { rnd(&mut seed) } else { 0.0 }).collect() };
        let dot = |a: &[f64], b: &[f64]| -> f64 { a.iter().zip(b).map(|(x, y)| x * y).sum() };
        for _ in 0..5 {
            let (r, s) = (random(), random());
            let (mut zr, mut zs) = (vec![0.0; r.len()], vec![0.0; r.len()]);
            let rzr = m.parallel_gauss_seidel(&ord, &r, &mut zr);
            m.parallel_gauss_seidel(&ord, &s, &mut zs);
            let (a, b) = (dot(&s, &zr), dot(&r, &zs));
            assert!(
                (a - b).abs() <= 1e-12 * a.abs().max(b.abs()),
                "sᵀP⁻¹r {a} vs rᵀP⁻¹s {b}"
            );
            assert!(rzr > 0.0, "rᵀP⁻¹r = {rzr}");
        }
        let r = random();
        let bits: Vec<Vec<u64>> = [1, 2, 3]
            .iter()
            .map(|&threads| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let mut z = vec![0.0; r.len()];
                let rz = pool.install(|| m.parallel_gauss_seidel(&ord, &r, &mut z));
                z.iter().chain([&rz]).map(|v| v.to_bits()).collect()
            })
            .collect();
        assert!(
            bits[0] == bits[1] && bits[0] == bits[2],
            "results differ between thread counts"
        );
    }
}
