//! The two triangular solves with a supernodal Cholesky factor held in faer's
//! storage (`cholesky.rs`), written out as plain loops over each supernode's dense
//! column block.
//!
//! Why not faer's own `solve_in_place`: it hands every supernode to its general
//! dense kernels (a triangular solve and a matrix product each way, with their
//! dispatch, shape checks and scratch), which is right for the wide supernodes of
//! large 3-D factors but dominates on small ones — the node-sized supernodes (3 to
//! a few tens of columns) of an organ mesh with a few hundred nodes, where the
//! triangular solves were ~40 % of a chord iteration (sofa_liver, session 18) and
//! ~27 % of the whole long run (session 20). Here each supernode is two short loops
//! whose inner loops run over contiguous values (vectorised by the compiler), in a
//! fixed order: the result does not depend on the thread count.
//!
//! Storage (faer's supernodal layout): supernode s owns columns
//! `begin[s]..end[s]` (w columns) and a column-major block of w + p rows — its
//! dense lower-triangular diagonal block, then the p rows of its off-diagonal
//! pattern `row_idx[...]` — starting at `col_ptr_for_val[s]`.

#[cfg(target_arch = "x86_64")]
use crate::force::assembly::simd::Avx2Token;
use crate::force::assembly::simd::Isa;
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};

/// The arithmetic the solves need, for both factor precisions.
pub(super) trait Real:
    Copy
    + Default
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::SubAssign
    + std::ops::AddAssign
{
    /// 1.
    const ONE: Self;
}

impl Real for f64 {
    const ONE: Self = 1.0;
}
impl Real for f32 {
    const ONE: Self = 1.0;
}

/// One supernode's place in the factor.
#[derive(Debug, Clone, Copy)]
struct Supernode {
    /// First column.
    start: usize,
    /// Columns (w).
    width: usize,
    /// Offset of its value block in the factor's values.
    values: usize,
    /// Its off-diagonal rows: `rows[pattern..pattern + len]`.
    pattern: usize,
    /// Its off-diagonal rows' count (p).
    len: usize,
}

/// The supernodes of a symbolic factorisation (of a matrix numbered in its
/// fill-reducing order: `cholesky.rs` permutes the right-hand sides), copied out
/// once per analysis.
#[derive(Debug)]
pub(super) struct SupernodalSolve {
    nodes: Vec<Supernode>,
    rows: Vec<usize>,
    /// Factor values expected (faer's `len_val`).
    len_val: usize,
    /// The longest off-diagonal pattern: the scratch the solves need.
    longest: usize,
}

impl SupernodalSolve {
    /// The layout of `symbolic`; `None` for a simplicial factorisation (not made
    /// here: `cholesky.rs` always asks for the supernodal one).
    pub(super) fn new(symbolic: &SymbolicCholesky<usize>) -> Option<Self> {
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            return None;
        };
        let (begin, end) = (sn.supernode_begin(), sn.supernode_end());
        let (row_ptr, val_ptr) = (sn.col_ptr_for_row_idx(), sn.col_ptr_for_val());
        let nodes: Vec<Supernode> = (0..sn.n_supernodes())
            .map(|s| {
                let width = end[s] - begin[s];
                // the value block is (w + p) × w
                let len = (val_ptr[s + 1] - val_ptr[s]) / width - width;
                Supernode {
                    start: begin[s],
                    width,
                    values: val_ptr[s],
                    pattern: row_ptr[s],
                    len,
                }
            })
            .collect();
        Some(SupernodalSolve {
            rows: sn.row_idx().to_vec(),
            len_val: symbolic.len_val(),
            longest: nodes.iter().map(|s| s.len).max().unwrap_or(0),
            nodes,
        })
    }

    /// Solves L Lᵀ x = `x` in place, with the factor `values` in faer's supernodal
    /// layout; `tmp` is scratch (resized here).
    pub(super) fn solve<T: Real>(&self, values: &[T], x: &mut [T], tmp: &mut Vec<T>) {
        assert_eq!(values.len(), self.len_val, "factor of another analysis");
        tmp.clear();
        tmp.resize(self.longest, T::default());
        match Isa::current().avx2() {
            // SAFETY: the token proves the CPU has avx2 and fma, the features
            // `sweeps_avx2` enables (it does the same safe, bounds-checked work as
            // `sweeps`)
            #[cfg(target_arch = "x86_64")]
            Some(t) => unsafe { sweeps_avx2(t, self, values, x, tmp) },
            _ => sweeps(self, values, x, tmp),
        }
    }
}

/// The forward sweep over the supernodes, then the backward one.
#[inline(always)]
fn sweeps<T: Real>(plan: &SupernodalSolve, values: &[T], x: &mut [T], tmp: &mut [T]) {
    for s in &plan.nodes {
        forward(s, values, &plan.rows, x, tmp);
    }
    for s in plan.nodes.iter().rev() {
        backward(s, values, &plan.rows, x, tmp);
    }
}

/// [`sweeps`] compiled with AVX2 enabled: its contiguous loops run four f64 (eight
/// f32) per instruction instead of the baseline target's two (SSE2), the same
/// operations in the same order (no fused multiply-add: Rust does not contract), so
/// the same bits on every instruction set. The solves are mostly latency-bound (each
/// column waits on the last), so this gained 7 % on a 648-unknown system (29.1 →
/// 27.2 µs), the pivots' reciprocals off the chain 7 % more and two dot-product
/// chains instead of one 5 % more (23.9 µs in all; session 21).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn sweeps_avx2<T: Real>(_: Avx2Token, plan: &SupernodalSolve, values: &[T], x: &mut [T], tmp: &mut [T]) {
    sweeps(plan, values, x, tmp);
}

/// x_s ← L_ss⁻¹ x_s, then x_pattern −= L_ps x_s (summed into `tmp` column by
/// column: contiguous, vectorisable, then scattered once).
#[inline(always)]
fn forward<T: Real>(s: &Supernode, values: &[T], rows: &[usize], x: &mut [T], tmp: &mut [T]) {
    let (w, p) = (s.width, s.len);
    let ld = w + p;
    let block = &values[s.values..s.values + ld * w];
    let top = &mut x[s.start..s.start + w];
    let acc = &mut tmp[..p];
    acc.fill(T::default());
    for c in 0..w {
        let col = &block[c * ld..(c + 1) * ld];
        // times the pivot's reciprocal: its division does not wait on x (the
        // out-of-order core runs it ahead), a product is all the chain waits for
        let xc = top[c] * (T::ONE / col[c]);
        top[c] = xc;
        for (xr, &l) in top[c + 1..].iter_mut().zip(&col[c + 1..w]) {
            *xr -= l * xc;
        }
        for (a, &l) in acc.iter_mut().zip(&col[w..]) {
            *a += l * xc;
        }
    }
    for (&r, &a) in rows[s.pattern..s.pattern + p].iter().zip(acc.iter()) {
        x[r] -= a;
    }
}

/// x_s −= L_psᵀ x_pattern, then x_s ← L_ss⁻ᵀ x_s, column by column from the last
/// (each a contiguous dot product).
#[inline(always)]
fn backward<T: Real>(s: &Supernode, values: &[T], rows: &[usize], x: &mut [T], tmp: &mut [T]) {
    let (w, p) = (s.width, s.len);
    let ld = w + p;
    let block = &values[s.values..s.values + ld * w];
    let below = &mut tmp[..p];
    for (b, &r) in below.iter_mut().zip(&rows[s.pattern..s.pattern + p]) {
        *b = x[r];
    }
    let top = &mut x[s.start..s.start + w];
    for c in (0..w).rev() {
        let col = &block[c * ld..(c + 1) * ld];
        let xc = top[c] - dot(&col[w..], below) - dot(&col[c + 1..w], &top[c + 1..]);
        top[c] = xc * (T::ONE / col[c]);
    }
}

/// Σ aᵢ bᵢ in eight interleaved partial sums (two AVX vectors: two add chains
/// instead of one; a fixed order, so the same bits on every run and instruction
/// set).
#[inline(always)]
fn dot<T: Real>(a: &[T], b: &[T]) -> T {
    let mut s = [T::default(); 8];
    let (a8, b8) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (a8.remainder(), b8.remainder());
    for (ca, cb) in a8.zip(b8) {
        for k in 0..8 {
            s[k] += ca[k] * cb[k];
        }
    }
    for (k, (&x, &y)) in ra.iter().zip(rb).enumerate() {
        s[k] += x * y;
    }
    ((s[0] + s[4]) + (s[1] + s[5])) + ((s[2] + s[6]) + (s[3] + s[7]))
}
