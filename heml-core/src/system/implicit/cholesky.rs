//! The direct linear solver of [`super::LinearSolver::Cholesky`]: a sparse LLᵀ
//! factorisation (faer, with the fill-reducing ordering of a [`CholeskyOrdering`]:
//! by default nested dissection of the node graph on all but small systems) of the
//! assembled system matrix restricted to the free coordinates of a [`DofMap`].
//!
//! The scalar lower-triangular pattern and, per entry, where its value sits in the
//! 3×3 blocks of the [`BlockMatrix`] are built once per block pattern and numbering
//! of the unknowns, together with the symbolic analysis (ordering, elimination tree,
//! supernodes). The fill it predicts is checked against a cap before the factor is
//! allocated, so that a mesh too large for a direct solve fails with a clear error
//! instead of exhausting memory. Each numeric factorisation then reuses the pattern,
//! the analysis and the buffers. The pattern is numbered in the fill-reducing order
//! itself (faer's analysis is handed P A Pᵀ with no ordering of its own), so that
//! no numeric factorisation permutes the matrix first, as faer does for an analysis
//! that holds a permutation: the same factor bits, ~14 % less factorisation time
//! on the liver (4.3–4.7 against 5.0–5.6 ms for the 12 of `heml bench
//! --implicit`'s long run, 2026-11-27); the solves permute their right-hand side
//! instead (a gather, O(unknowns)).
//!
//! The factorisation is always supernodal: faer's default picks its simplicial
//! (column-by-column, scalar) kernel below ~40 flops per factor nonzero, which is
//! where the small organ meshes fall (sofa_liver, ~490 unknowns, fill 2.1·10⁴:
//! ~20), and there it was 2.5× slower than the supernodal one (dense kernels on
//! the 3×3-node column groups; 0.27–0.46 ms against 0.63–1.2 ms per numeric
//! factorisation, same solve time, session 13). Factors below [`SEQUENTIAL_FILL`]
//! nonzeros run faer's kernels sequentially whatever the thread pool: at that size
//! the fork-join costs more than it saves (the liver's supernodal factorisation
//! took 0.48–0.80 ms on 2 threads against 0.27–0.46 ms on one).
//!
//! The triangular solves are ours (`trisolve.rs`: plain loops over faer's
//! supernodal storage, compiled for AVX2 where the CPU has it) below
//! [`OWN_SOLVE_FILL`] factor nonzeros. Against faer's sequential solve of the same
//! factor (random SPD systems on boxes, median of 9, 2026-11-25): 0.64× its time at
//! 648 unknowns (fill 6.6·10⁴), 0.69× at 1 944 (3.6·10⁵), 0.73× at 3 630 (8.4·10⁵),
//! 0.83–0.85× at 6 084 (1.7·10⁶), 0.92× at 13 872 (6.3·10⁶), 0.94× at 26 460
//! (1.5·10⁷) in f64; 0.50–0.98× in f32. Above, faer's (1.09× faster on
//! gen_kidney_100k's f32 factor, fill 3.0·10⁷). (Before session 21 the threshold
//! was 2·10⁵: ours was then ~5 % slower than faer's from 3.6·10⁵ up.)
//!
//! The numeric factor is held in f64 or, when the caller asks for it
//! ([`super::FactorPrecision`]), in f32: the same analysis and pattern, half the
//! bytes per factor value, the right-hand side rounded to f32 for the solves and
//! the solution widened back. An f32 factorisation that meets a non-positive pivot
//! is redone in f64.

use super::matrix::BlockMatrix;
use super::ordering::{etree_postorder, CholeskyOrdering};
use super::trisolve::SupernodalSolve;
use crate::error::{HemlError, Result};
use crate::system::statics::dofs::DofMap;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::linalg::{amd, SupernodalThreshold};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::traits::RealField;
use faer::{Conj, MatMut, Par, Side};

/// A sparse Cholesky factorisation of the system matrix over the free coordinates,
/// its symbolic analysis kept for refactorisations with new values.
pub(in crate::system) struct Cholesky {
    /// Lower triangle by columns (the free coordinates of the [`DofMap`] in the order
    /// of the fill-reducing permutation).
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Per entry: 9 × block index + 3 × row + column within the block.
    src: Vec<usize>,
    /// The fill-reducing permutation the pattern is numbered in: unknown `k` of
    /// the factor is free coordinate `forward[k]`, coordinate `d` is unknown
    /// `inverse[d]`.
    forward: Vec<usize>,
    inverse: Vec<usize>,
    /// A right-hand side in the factor's numbering (scratch of the solves).
    permuted: Vec<f64>,
    /// The entries' values at the last factorisation.
    values: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    /// The factor's values, in the precision it was made in.
    factor: Factor,
    /// Scratch of the numeric factorisation and of faer's solves (either precision).
    stack: MemBuffer,
    /// Our triangular solves on the supernodal factor (`trisolve.rs`; factors below
    /// [`OWN_SOLVE_FILL`] nonzeros only) and their scratch per precision.
    trisolve: Option<SupernodalSolve>,
    work64: Vec<f64>,
    work32: Vec<f32>,
}

/// A numeric factor and, for f32, the matrix values and right-hand side rounded to
/// it (buffers kept across factorisations).
#[derive(Default)]
enum Factor {
    /// None yet, or the last factorisation failed.
    #[default]
    Empty,
    Double(Vec<f64>),
    Single {
        factor: Vec<f32>,
        values: Vec<f32>,
        rhs: Vec<f32>,
    },
}

impl std::fmt::Debug for Cholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Cholesky")
            .field("unknowns", &(self.col_ptr.len() - 1))
            .field("matrix_nonzeros", &self.row_idx.len())
            .field("factor_nonzeros", &self.symbolic.len_val())
            .field("single", &matches!(self.factor, Factor::Single { .. }))
            .finish_non_exhaustive()
    }
}

/// Factor nonzeros below which faer's kernels run sequentially (see the module
/// doc): 2·10⁵ is ~6× the liver's factor, where one thread was measured 1.7× faster
/// than two; gen_kidney_20k's (4.5·10⁶) stays parallel.
const SEQUENTIAL_FILL: usize = 200_000;

/// Factor nonzeros below which the solves are ours (`trisolve.rs`) rather than
/// faer's (see the module doc): ours took 0.64–0.98× faer's time on random SPD
/// systems on boxes up to fill 1.5·10⁷, and 1.09× on gen_kidney_100k's f32 factor
/// (fill 3.0·10⁷; solve time per step of `heml bench --implicit`'s default preset,
/// 49.8 against 45.8 ms), where faer's blocked dense kernels on the widest
/// supernodes pay.
const OWN_SOLVE_FILL: usize = 16_000_000;

/// The parallelism of faer's factorisation kernels for a factor of `fill` nonzeros:
/// the calling rayon pool's threads, or sequential for a small factor (the solves
/// run two subtrees side by side on large factors, `trisolve.rs`).
fn par(fill: usize) -> Par {
    match rayon::current_num_threads() {
        _ if fill < SEQUENTIAL_FILL => Par::Seq,
        0 | 1 => Par::Seq,
        n => Par::rayon(n),
    }
}

impl Cholesky {
    /// The pattern of `matrix` over the free coordinates of `dofs` and its symbolic
    /// analysis with the fill-reducing `ordering`; an error when the factor would
    /// hold more than `max_nonzeros` values.
    pub(in crate::system) fn new(
        matrix: &BlockMatrix,
        dofs: &DofMap,
        max_nonzeros: usize,
        ordering: CholeskyOrdering,
    ) -> Result<Self> {
        let n = dofs.len();
        // (column, row, source) of the lower triangle
        let mut entries: Vec<(usize, usize, usize)> = Vec::new();
        for i in 0..matrix.n_nodes() {
            for (j, b) in matrix.row_blocks(i) {
                for r in 0..3 {
                    let Some(row) = dofs.get(i, r) else { continue };
                    for c in 0..3 {
                        match dofs.get(j, c) {
                            Some(col) if row >= col => entries.push((col, row, 9 * b + 3 * r + c)),
                            _ => {}
                        }
                    }
                }
            }
        }
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            ..Default::default()
        };
        let analysis_failed = |e: faer::sparse::FaerError| {
            HemlError::Numerical(format!("sparse Cholesky: symbolic analysis failed: {e:?}"))
        };
        // the fill-reducing permutation: ours, or faer's AMD of the pattern as
        // numbered (the call and options of faer's own analysis with AMD)
        let (forward, inverse) = match ordering.permutation(matrix, dofs)? {
            Some(forward) => {
                let mut inverse = vec![0usize; n];
                for (k, &d) in forward.iter().enumerate() {
                    inverse[d] = k;
                }
                (forward, inverse)
            }
            None => {
                let (col_ptr, row_idx, _) = compressed_columns(n, entries.clone());
                let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
                let (mut forward, mut inverse) = (vec![0usize; n], vec![0usize; n]);
                let mut scratch = MemBuffer::try_new(amd::order_maybe_unsorted_scratch::<usize>(n, row_idx.len()))
                    .map_err(|_| analysis_failed(faer::sparse::FaerError::OutOfMemory))?;
                amd::order_maybe_unsorted(
                    &mut forward,
                    &mut inverse,
                    pattern,
                    params.amd_params,
                    MemStack::new(&mut scratch),
                )
                .map_err(analysis_failed)?;
                (forward, inverse)
            }
        };
        // the lower triangle of P A Pᵀ: analysed and factored as numbered, so that
        // no factorisation permutes the matrix again (faer would, each time)
        for e in &mut entries {
            let (a, b) = (inverse[e.0], inverse[e.1]);
            (e.0, e.1) = (a.min(b), a.max(b));
        }
        // then renumbered along a postorder of its elimination tree (the same fill),
        // so that the supernodes are postordered (`trisolve.rs` splits the tree)
        let post = etree_postorder(n, &entries);
        let mut at = vec![0usize; n];
        for (k, &old) in post.iter().enumerate() {
            at[old] = k;
        }
        for e in &mut entries {
            let (a, b) = (at[e.0], at[e.1]);
            (e.0, e.1) = (a.min(b), a.max(b));
        }
        let forward: Vec<usize> = post.iter().map(|&old| forward[old]).collect();
        let inverse: Vec<usize> = inverse.iter().map(|&old| at[old]).collect();
        // (faer's analysis without an ordering reads the upper triangle, whatever
        // side it is told: so the transposed pattern)
        let upper: Vec<(usize, usize, usize)> = entries.iter().map(|&(c, r, s)| (r, c, s)).collect();
        let (upper_ptr, upper_idx, _) = compressed_columns(n, upper);
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &upper_ptr, None, &upper_idx);
        let symbolic = factorize_symbolic_cholesky(pattern, Side::Upper, SymmetricOrdering::Identity, params)
            .map_err(analysis_failed)?;
        let (col_ptr, row_idx, src) = compressed_columns(n, entries);
        let fill = symbolic.len_val();
        if fill > max_nonzeros {
            return Err(HemlError::Invalid(format!(
                "sparse Cholesky: the factor of this system ({n} unknowns, {} matrix nonzeros in the lower \
                 triangle) would hold {fill} nonzeros ({} MB in f64, half that in f32), above the limit max_factor_nonzeros = \
                 {max_nonzeros}; raise the limit or use linear_solver = \"cg\"",
                row_idx.len(),
                fill * 8 / 1_000_000
            )));
        }
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(par(fill), Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
            symbolic.factorize_numeric_llt_scratch::<f32>(par(fill), Default::default()),
            symbolic.solve_in_place_scratch::<f32>(1, Par::Seq),
        ]);
        let stack = MemBuffer::try_new(req).map_err(|_| {
            HemlError::Invalid(format!(
                "sparse Cholesky: cannot allocate the {} MB of scratch of a system with {n} unknowns",
                req.size_bytes() / 1_000_000
            ))
        })?;
        Ok(Cholesky {
            trisolve: (fill < OWN_SOLVE_FILL)
                .then(|| SupernodalSolve::new(&symbolic))
                .flatten(),
            work64: Default::default(),
            work32: Default::default(),
            values: vec![0.0; row_idx.len()],
            forward,
            inverse,
            permuted: Vec::new(),
            col_ptr,
            row_idx,
            src,
            symbolic,
            factor: Factor::Empty,
            stack,
        })
    }

    /// Nonzeros of the factor (its storage, by the symbolic analysis).
    pub(in crate::system) fn factor_nonzeros(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Factors the current values of `matrix` (the pattern the analysis was built
    /// for), in f32 when `single` (in f64 if that meets a non-positive pivot). An
    /// error when the matrix is not numerically positive definite in f64 (an
    /// unprojected, indefinite tangent) or holds a non-finite value; the previous
    /// factor is then gone.
    pub(in crate::system) fn factor(&mut self, matrix: &BlockMatrix, single: bool) -> Result<()> {
        let blocks = matrix.blocks();
        for (v, &s) in self.values.iter_mut().zip(&self.src) {
            *v = blocks[s / 9][(s % 9 / 3, s % 3)];
        }
        let (mut f64s, mut f32s) = match std::mem::take(&mut self.factor) {
            Factor::Double(f) => (f, None),
            Factor::Single { factor, values, rhs } => (Vec::new(), Some((factor, values, rhs))),
            Factor::Empty => (Vec::new(), None),
        };
        if single {
            let (mut factor, mut values, rhs) = f32s.take().unwrap_or_default();
            values.clear();
            // rounding to nearest: each entry within half an f32 ulp of the matrix's
            values.extend(self.values.iter().map(|&v| v as f32));
            if self.numeric(&values, &mut factor).is_ok() {
                self.factor = Factor::Single { factor, values, rhs };
                return Ok(());
            }
        }
        let values = std::mem::take(&mut self.values);
        let out = self.numeric(&values, &mut f64s);
        self.values = values;
        match out {
            Ok(()) => {
                self.factor = Factor::Double(f64s);
                Ok(())
            }
            Err(LltError::NonPositivePivot { index }) => Err(HemlError::Numerical(format!(
                "sparse Cholesky: the system matrix ({} unknowns) is not positive definite (pivot {index} \
                 of the reordered matrix; an unprojected tangent or a non-finite value: set \
                 project_psd = true, or use linear_solver = \"cg\")",
                self.col_ptr.len() - 1
            ))),
        }
    }

    /// The numeric factorisation of the lower triangle `values` (in the analysed
    /// pattern) into `out`, resized to the factor's nonzeros.
    fn numeric<T: RealField + Copy + Default>(
        &mut self,
        values: &[T],
        out: &mut Vec<T>,
    ) -> std::result::Result<(), LltError> {
        out.clear();
        out.resize(self.symbolic.len_val(), T::default());
        let n = self.col_ptr.len() - 1;
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let a = SparseColMatRef::new(pattern, values);
        self.symbolic
            .factorize_numeric_llt(
                out,
                a,
                Side::Lower,
                LltRegularization::default(),
                par(self.symbolic.len_val()),
                MemStack::new(&mut self.stack),
                Default::default(),
            )
            .map(|_| ())
    }

    /// Whether a factor is held.
    pub(in crate::system) fn is_factored(&self) -> bool {
        !matches!(self.factor, Factor::Empty)
    }

    /// Whether the held factor is in f32.
    pub(in crate::system) fn is_single(&self) -> bool {
        matches!(self.factor, Factor::Single { .. })
    }

    /// Solves A x = `rhs` in place with the held factor (`rhs` by free coordinate;
    /// through f32 when the factor is): below [`OWN_SOLVE_FILL`] factor nonzeros by
    /// our substitutions (`trisolve.rs`), above by faer's.
    ///
    /// Always sequential: faer's parallel supernodal solve sums in an order that
    /// depends on the thread count (a 6084-unknown system solved on 2 threads
    /// differed from 1 thread in the last bits of 803 coordinates), which broke the
    /// same-bits-for-any-thread-count rule on large meshes (gen_kidney_100k took
    /// different numbers of refactorisations on 1 and 2 threads), and it saved
    /// nothing measurable on one right-hand side (1.07–1.30 ms on 2 threads against
    /// 1.19–1.27 ms on 1, factor 1.7·10⁶ nonzeros). The factorisation stays parallel:
    /// its bits do not depend on the thread count (tested below).
    pub(in crate::system) fn solve(&mut self, rhs: &mut [f64]) {
        let mut x = std::mem::take(&mut self.permuted);
        x.clear();
        x.extend(self.forward.iter().map(|&d| rhs[d]));
        if !self.solve_own(&mut x) {
            self.solve_faer(&mut x);
        }
        for (v, &k) in rhs.iter_mut().zip(&self.inverse) {
            *v = x[k];
        }
        self.permuted = x;
    }

    /// [`Self::solve`] in the factor's numbering by our supernodal solves
    /// (`trisolve.rs`); false (nothing done) without their plan (made by `new`
    /// below [`OWN_SOLVE_FILL`] only).
    fn solve_own(&mut self, x: &mut [f64]) -> bool {
        let Some(plan) = &self.trisolve else {
            return false;
        };
        match &mut self.factor {
            Factor::Empty => panic!("solve before a factorisation"),
            Factor::Double(factor) => plan.solve(factor, x, &mut self.work64),
            Factor::Single { factor, rhs: r32, .. } => through_f32(x, r32, |r| plan.solve(factor, r, &mut self.work32)),
        }
        true
    }

    /// [`Self::solve`] in the factor's numbering by faer's supernodal solve (large
    /// factors, and the tests' reference).
    fn solve_faer(&mut self, x: &mut [f64]) {
        let n = self.col_ptr.len() - 1;
        let stack = MemStack::new(&mut self.stack);
        match &mut self.factor {
            Factor::Empty => panic!("solve before a factorisation"),
            Factor::Double(factor) => LltRef::new(&self.symbolic, factor).solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(x, n, 1),
                Par::Seq,
                stack,
            ),
            Factor::Single { factor, rhs: r32, .. } => through_f32(x, r32, |r| {
                LltRef::new(&self.symbolic, factor).solve_in_place_with_conj(
                    Conj::No,
                    MatMut::from_column_major_slice_mut(r, n, 1),
                    Par::Seq,
                    stack,
                )
            }),
        }
    }
}

/// The `entries` (column, row, source) in compressed columns, rows ascending in
/// each: (column pointers, row indices, sources). Columns and rows are below `n`
/// and no (column, row) comes twice (one entry per matrix coefficient), so two
/// counting sorts — by row, then stably by column — give the order a sort of the
/// triples would, in O(entries) instead of O(entries · log entries) (the liver's
/// ~10⁴ entries: a sort took ~0.5 ms of each `prepare`).
fn compressed_columns(n: usize, entries: Vec<(usize, usize, usize)>) -> (Vec<usize>, Vec<usize>, Vec<usize>) {
    /// `items` stably ordered by `key` (< n), and the start of each key's run.
    fn by_key(
        n: usize,
        items: &[(usize, usize, usize)],
        key: fn(&(usize, usize, usize)) -> usize,
    ) -> (Vec<(usize, usize, usize)>, Vec<usize>) {
        let mut start = vec![0usize; n + 1];
        for e in items {
            start[key(e) + 1] += 1;
        }
        for k in 0..n {
            start[k + 1] += start[k];
        }
        let mut next = start.clone();
        let mut out = vec![(0, 0, 0); items.len()];
        for e in items {
            let k = key(e);
            out[next[k]] = *e;
            next[k] += 1;
        }
        (out, start)
    }
    let (by_row, _) = by_key(n, &entries, |e| e.1);
    let (sorted, col_ptr) = by_key(n, &by_row, |e| e.0);
    let row_idx = sorted.iter().map(|e| e.1).collect();
    let src = sorted.iter().map(|e| e.2).collect();
    (col_ptr, row_idx, src)
}

/// Runs the f32 `solve` on `rhs` rounded to f32 (in the buffer `r32`) and widens
/// its solution back into `rhs`.
fn through_f32(rhs: &mut [f64], r32: &mut Vec<f32>, solve: impl FnOnce(&mut [f32])) {
    r32.clear();
    r32.extend(rhs.iter().map(|&v| v as f32));
    solve(r32);
    for (v, &w) in rhs.iter_mut().zip(r32.iter()) {
        *v = f64::from(w);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::system::implicit::matrix::tests::{rnd, setup};
    use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
    use nalgebra::{DMatrix, DVector};

    /// The supernodal factor (forced: this small system, 99 unknowns, would get the
    /// simplicial one by faer's default) solves the assembled system to the dense
    /// LLᵀ solution of the same matrix restricted to the free coordinates. Bound:
    /// both are backward-stable solves of a well-conditioned SPD matrix (random
    /// Gram stiffnesses plus a mass shift, entries O(1)), so they agree to ~1e-14
    /// relative; 1e-12 leaves 100× margin, a wrong entry or ordering errs by O(1).
    #[test]
    fn supernodal_factor_solves_like_the_dense_cholesky() {
        let (m, dofs, a) = free_system();
        let mut direct = Cholesky::new(&m, &dofs, usize::MAX, CholeskyOrdering::Auto).unwrap();
        assert!(matches!(direct.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)));
        direct.factor(&m, false).unwrap();
        assert!(!direct.is_single());
        let (x, want) = solve_random(&mut direct, &a);
        let err = (DVector::from_column_slice(&x) - &want).amax() / want.amax();
        assert!(err < 1e-12, "relative error {err:e}");
    }

    /// Our supernodal triangular solves (`trisolve.rs`) give faer's solution of the
    /// same factor, in f64 and f32, on a small system (node-sized supernodes) and on
    /// a 12³-cell box (supernodes tens of columns wide). Bound: both are
    /// backward-stable substitutions with the same factor, differing only in the
    /// order of their sums, so they agree to a few units of round-off times the
    /// factor's growth (measured 4·10⁻¹⁶ in f64, 1·10⁻⁷ in f32: 1e-13 and 1e-5
    /// leave 100× margin); a wrong index or a missed block errs by O(1).
    #[test]
    fn our_triangular_solves_match_faers() {
        let (big, big_dofs) = box_system();
        let (small, small_dofs, _) = free_system();
        for (m, dofs) in [(&small, &small_dofs), (&big, &big_dofs)] {
            for (single, bound) in [(false, 1e-13), (true, 1e-5)] {
                let mut direct = Cholesky::new(m, dofs, usize::MAX, CholeskyOrdering::Auto).unwrap();
                assert!(direct.trisolve.is_some());
                direct.factor(m, single).unwrap();
                assert_eq!(direct.is_single(), single);
                let b: Vec<f64> = (0..dofs.len()).map(|i| (i as f64 * 0.7).sin()).collect();
                let (mut ours, mut theirs) = (b.clone(), b.clone());
                assert!(direct.solve_own(&mut ours));
                direct.solve_faer(&mut theirs);
                let scale = theirs.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                let err = ours.iter().zip(&theirs).fold(0.0f64, |a, (x, y)| a.max((x - y).abs())) / scale;
                assert!(
                    err < bound,
                    "{} unknowns, single {single}: relative difference {err:e}",
                    dofs.len()
                );
            }
        }
    }

    /// Our triangular solves give the same bits on every instruction set this CPU
    /// runs (the AVX2-compiled sweeps do the baseline's operations in the same
    /// order), in f64 and f32. Exact comparison: a reordered sum would change last
    /// bits somewhere among the 12³ box's 6084 unknowns.
    #[test]
    fn our_triangular_solves_have_the_same_bits_on_every_instruction_set() {
        use crate::force::assembly::SimdLevel;
        let (m, dofs) = box_system();
        for single in [false, true] {
            let mut direct = Cholesky::new(&m, &dofs, usize::MAX, CholeskyOrdering::Auto).unwrap();
            direct.factor(&m, single).unwrap();
            let b: Vec<f64> = (0..dofs.len()).map(|i| (i as f64 * 0.3).cos()).collect();
            let mut first: Option<Vec<u64>> = None;
            for level in SimdLevel::available() {
                let mut x = b.clone();
                assert!(level.run_with(|| direct.solve_own(&mut x)).unwrap());
                let bits: Vec<u64> = x.iter().map(|v| v.to_bits()).collect();
                match &first {
                    None => first = Some(bits),
                    Some(f) => assert!(*f == bits, "{} differs (single = {single})", level.name()),
                }
            }
        }
    }

    /// The pattern is analysed and factored already in its fill-reducing order
    /// (faer's analysis holds no permutation, so no numeric factorisation permutes
    /// the matrix again), with the fill faer's own analysis of the pattern as
    /// numbered gets with the same ordering — AMD (faer's) on the small system,
    /// nested dissection (ours) on the box — followed by a postorder of the
    /// elimination tree (`ordering::etree_postorder`). Exact: the same permutation
    /// gives the same elimination tree, column counts and supernodes.
    #[test]
    fn factor_is_analysed_in_its_fill_reducing_order() {
        let (big, big_dofs) = box_system();
        let (small, small_dofs, _) = free_system();
        for (m, dofs, ordering) in [
            (&small, &small_dofs, CholeskyOrdering::Amd),
            (&big, &big_dofs, CholeskyOrdering::NestedDissection),
        ] {
            let direct = Cholesky::new(m, dofs, usize::MAX, ordering).unwrap();
            assert!(direct.symbolic.perm().is_none(), "{ordering:?}: faer would permute");
            // faer's analysis of the pattern as numbered, with the same ordering
            let n = dofs.len();
            let mut entries = Vec::new();
            for (c, w) in direct.col_ptr.windows(2).enumerate() {
                for &r in &direct.row_idx[w[0]..w[1]] {
                    let (a, b) = (direct.forward[c], direct.forward[r]);
                    entries.push((a.min(b), a.max(b), 0));
                }
            }
            let (col_ptr, row_idx, _) = compressed_columns(n, entries);
            let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
            let order = ordering.permutation(m, dofs).unwrap();
            let params = CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
                ..Default::default()
            };
            let theirs = match &order {
                None => factorize_symbolic_cholesky(pattern, Side::Lower, SymmetricOrdering::Amd, params),
                Some(p) => {
                    let mut inv = vec![0; n];
                    p.iter().enumerate().for_each(|(k, &d)| inv[d] = k);
                    let perm = faer::perm::PermRef::new_checked(p, &inv, n);
                    factorize_symbolic_cholesky(pattern, Side::Lower, SymmetricOrdering::Custom(perm), params)
                }
            }
            .unwrap();
            // faer's permutation, then the postorder of the elimination tree of the
            // pattern it numbers
            let p = theirs.perm().expect("an ordering").arrays();
            let mut theirs_numbered: Vec<(usize, usize, usize)> = Vec::new();
            for (c, w) in col_ptr.windows(2).enumerate() {
                for &r in &row_idx[w[0]..w[1]] {
                    let (a, b) = (p.1[c], p.1[r]);
                    theirs_numbered.push((a.min(b), a.max(b), 0));
                }
            }
            let post = etree_postorder(n, &theirs_numbered);
            let want: Vec<usize> = post.iter().map(|&k| p.0[k]).collect();
            assert_eq!(want, direct.forward, "{ordering:?}: another permutation");
            // and the fill of faer's analysis with that permutation (its supernodes'
            // relaxation stores a few zeros more or fewer than with `theirs`' order:
            // 3 619 against 3 673 values on the small system)
            let inv: Vec<usize> = {
                let mut inv = vec![0; n];
                want.iter().enumerate().for_each(|(k, &d)| inv[d] = k);
                inv
            };
            let perm = faer::perm::PermRef::new_checked(&want, &inv, n);
            let same =
                factorize_symbolic_cholesky(pattern, Side::Lower, SymmetricOrdering::Custom(perm), params).unwrap();
            assert_eq!(direct.factor_nonzeros(), same.len_val(), "{ordering:?}");
        }
    }

    /// A random SPD system on a 12³-cell box held at x = 0 (6084 unknowns, factor
    /// fill 1.7·10⁶: faer's kernels parallel, supernodes tens of columns wide).
    fn box_system() -> (BlockMatrix, DofMap) {
        use crate::mesh::generate::{box_mesh, HexSplit};
        let mesh = box_mesh([1.0, 1.0, 1.0], [12, 12, 12], HexSplit::Six).unwrap();
        let held: Vec<[bool; 3]> = mesh.nodes().iter().map(|p| [p.x == 0.0; 3]).collect();
        let m = crate::system::implicit::matrix::tests::random_system(&mesh, &held);
        (m, DofMap::new(&held, mesh.tets()))
    }

    /// The test system ([`setup`]: a 3×2×2 box, two nodes partly held), its
    /// numbering of the free coordinates and the dense matrix over them.
    fn free_system() -> (BlockMatrix, DofMap, DMatrix<f64>) {
        let (m, dense, mask) = setup();
        let held: Vec<[bool; 3]> = mask.chunks_exact(3).map(|c| [!c[0], !c[1], !c[2]]).collect();
        let mesh =
            crate::mesh::generate::box_mesh([3.0, 2.0, 2.0], [3, 2, 2], crate::mesh::generate::HexSplit::Six).unwrap();
        let dofs = DofMap::new(&held, mesh.tets());
        // the dense matrix over the free coordinates, numbered as the DofMap does
        let n = dofs.len();
        let mut a = DMatrix::zeros(n, n);
        let mut number = vec![None; mask.len()];
        for (d, slot) in number.iter_mut().enumerate() {
            *slot = dofs.get(d / 3, d % 3);
        }
        for r in 0..mask.len() {
            for c in 0..mask.len() {
                if let (Some(i), Some(j)) = (number[r], number[c]) {
                    a[(i, j)] = dense[(r, c)];
                }
            }
        }
        (m, dofs, a)
    }

    /// `direct`'s solution of a x = b for a random b, and the dense LLᵀ one.
    fn solve_random(direct: &mut Cholesky, a: &DMatrix<f64>) -> (Vec<f64>, DVector<f64>) {
        let mut s = 5u64;
        let b: Vec<f64> = (0..a.nrows()).map(|_| rnd(&mut s)).collect();
        let mut x = b.clone();
        direct.solve(&mut x);
        (
            x,
            a.clone()
                .cholesky()
                .expect("SPD")
                .solve(&DVector::from_column_slice(&b)),
        )
    }

    /// An f32 factor solves to f32 accuracy, and iterating on it (x += A32⁻¹(b − A x),
    /// the residual in f64, as the chord iterations do) reaches the f64 solution.
    /// Bounds: a backward-stable f32 solve errs by ≲ κ·ε32 relative (κ the
    /// condition number, computed here; ε32 = 1.2·10⁻⁷), so 10·κ·ε32 leaves margin
    /// and 10⁻¹⁰ below it shows the solve was not f64's; each refinement step
    /// contracts the error by ~κ·ε32, so 5 steps reach the f64 round-off (10⁻¹² as
    /// in the f64 test).
    #[test]
    fn single_factor_solves_to_f32_accuracy_and_refines_to_f64() {
        let (m, dofs, a) = free_system();
        let mut direct = Cholesky::new(&m, &dofs, usize::MAX, CholeskyOrdering::Auto).unwrap();
        direct.factor(&m, true).unwrap();
        assert!(direct.is_single());
        let (mut x, want) = solve_random(&mut direct, &a);
        let eig = a.clone().symmetric_eigenvalues();
        let kappa = eig.max() / eig.min();
        let err = (DVector::from_column_slice(&x) - &want).amax() / want.amax();
        let bound = 10.0 * kappa * f64::from(f32::EPSILON);
        assert!(
            err > 1e-10 && err < bound,
            "relative error {err:e}, bound {bound:e} (κ {kappa:.1})"
        );
        let b = &a * &want;
        for _ in 0..5 {
            let r = &b - &a * DVector::from_column_slice(&x);
            let mut dx = r.as_slice().to_vec();
            direct.solve(&mut dx);
            x.iter_mut().zip(&dx).for_each(|(x, d)| *x += d);
        }
        let err = (DVector::from_column_slice(&x) - &want).amax() / want.amax();
        assert!(err < 1e-12, "refined: relative error {err:e}");
    }

    /// A matrix whose entries underflow in f32 (here all of them, scaled by 10⁻⁵⁰:
    /// SPD in f64, zero in f32) is factored in f64 instead, and solves as f64 does.
    /// Bound: as in the f64 test, on the scaled system (relative errors are
    /// scale-free).
    #[test]
    fn single_factor_falls_back_to_f64_on_a_non_positive_pivot() {
        let (mut m, dofs, a) = free_system();
        crate::system::implicit::matrix::tests::scale(&mut m, 1e-50);
        let mut direct = Cholesky::new(&m, &dofs, usize::MAX, CholeskyOrdering::Auto).unwrap();
        direct.factor(&m, true).unwrap();
        assert!(!direct.is_single());
        let (x, want) = solve_random(&mut direct, &(a * 1e-50));
        let err = (DVector::from_column_slice(&x) - &want).amax() / want.amax();
        assert!(err < 1e-12, "relative error {err:e}");
    }

    /// A factor above [`SEQUENTIAL_FILL`] (faer's kernels parallel) is made and used
    /// with the same bits on 1 and 2 threads (at 2 the triangular solves run two
    /// groups of subtrees side by side, `trisolve.rs`): the rule every replay test
    /// relies on, which the small test systems (sequential kernels) cannot check. Exact
    /// comparison: any reordering of a sum changes last bits somewhere among
    /// 1.7·10⁶ factor values and 6084 solution coordinates.
    #[test]
    fn parallel_factor_and_solve_have_the_same_bits_on_1_and_2_threads() {
        let (m, dofs) = box_system();
        let run = |threads: usize, single: bool| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut direct = Cholesky::new(&m, &dofs, usize::MAX, CholeskyOrdering::Auto).unwrap();
                assert!(direct.factor_nonzeros() > SEQUENTIAL_FILL);
                // the solves run two subtrees side by side at 2 threads
                assert!(direct.trisolve.as_ref().is_some_and(|t| t.splits()));
                direct.factor(&m, single).unwrap();
                let bits: Vec<u64> = match &direct.factor {
                    Factor::Double(f) => f.iter().map(|v| v.to_bits()).collect(),
                    Factor::Single { factor, .. } => factor.iter().map(|v| u64::from(v.to_bits())).collect(),
                    Factor::Empty => unreachable!("factored"),
                };
                let mut x: Vec<f64> = (0..dofs.len()).map(|i| (i as f64).sin()).collect();
                direct.solve(&mut x);
                (bits, x.iter().map(|v| v.to_bits()).collect::<Vec<u64>>())
            })
        };
        for single in [false, true] {
            let (f1, x1) = run(1, single);
            let (f2, x2) = run(2, single);
            assert!(f1 == f2, "factor bits differ (single = {single})");
            let differ = x1.iter().zip(&x2).filter(|(a, b)| a != b).count();
            assert_eq!(
                differ, 0,
                "solution bits differ in {differ} coordinates (single = {single})"
            );
        }
    }
}
