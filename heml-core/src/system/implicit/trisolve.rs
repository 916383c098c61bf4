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
//!
//! Large factors (from [`PARALLEL_SOLVE_FILL`] values) solve on two threads: the
//! supernodes are in postorder (`cholesky.rs` numbers the pattern along a postorder
//! of its elimination tree), so two groups of subtrees below the top separators are
//! contiguous ranges, swept side by side with the same bits ([`Split`]).

use crate::force::assembly::simd::{Avx2Token, Isa};
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
    + Send
    + Sync
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
    /// Two groups of subtrees the solves run side by side on two threads (large
    /// factors whose elimination tree splits evenly; see [`Split`]).
    split: Option<Split>,
}

/// Factor nonzeros from which the solves run two independent groups of subtrees
/// of the elimination tree side by side (when the calling pool has two threads or
/// more): below it a join costs more than half a solve saves (the liver's factor,
/// 3·10⁴ values, solves in ~25 µs; gen_kidney_20k's, 3.6·10⁶, in ~5 ms).
const PARALLEL_SOLVE_FILL: usize = 500_000;

/// The smallest share of the factor's values each group of a [`Split`] must hold:
/// a lopsided split gains little over the sequential solve.
const MIN_GROUP_SHARE: f64 = 0.15;

/// Two groups of whole subtrees of the supernodal elimination tree, A = supernodes
/// `a..b` and B = `b..c`, neither an ancestor of the other (the children of the
/// first node with two or more, split in two by their values). Supernodes are in
/// postorder, so each group is a contiguous range of supernodes and of columns,
/// and what is not in them (`..a`, none in practice, and `c..`: the separator chain
/// above them) is independent of one group or an ancestor of both.
///
/// The forward sweep runs `..a`, then A and B at once — A adds its updates of the
/// rows above both (`col_c..`) directly, B records them in order — then B's
/// recorded updates in that order, then `c..`: every row receives its updates in
/// the sequential sweep's order, so the same bits. The backward sweep runs `c..`,
/// then A and B at once (each reads only its own columns and rows above both,
/// final by then), then `..a`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Split {
    a: usize,
    b: usize,
    c: usize,
    /// First column of B, and the first column after it.
    col_b: usize,
    col_c: usize,
    /// B's updates of rows from `col_c` (the forward sweep records them).
    recorded: usize,
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
        let rows = sn.row_idx().to_vec();
        let len_val = symbolic.len_val();
        let split = if len_val >= PARALLEL_SOLVE_FILL {
            find_split(&nodes, &rows, len_val)
        } else {
            None
        };
        Some(SupernodalSolve {
            rows,
            len_val,
            longest: nodes.iter().map(|s| s.len).max().unwrap_or(0),
            nodes,
            split,
        })
    }

    /// Whether the solves can run two groups of subtrees side by side.
    #[cfg(test)]
    pub(super) fn splits(&self) -> bool {
        self.split.is_some()
    }

    /// Solves L Lᵀ x = `x` in place, with the factor `values` in faer's supernodal
    /// layout; `tmp` is scratch (resized here).
    pub(super) fn solve<T: Real>(&self, values: &[T], x: &mut [T], tmp: &mut Vec<T>) {
        assert_eq!(values.len(), self.len_val, "factor of another analysis");
        let avx2 = Isa::current().avx2();
        tmp.clear();
        if let Some(split) = self.split.filter(|_| rayon::current_num_threads() > 1) {
            tmp.resize(2 * self.longest + split.recorded, T::default());
            return split_sweeps(self, &split, avx2, values, x, tmp);
        }
        tmp.resize(self.longest, T::default());
        match avx2 {
            // SAFETY: the token proves the CPU has avx2 and fma, the features
            // `sweeps_avx2` enables (it does the same safe, bounds-checked work as
            // `sweeps`)
            #[cfg(target_arch = "x86_64")]
            Some(t) => unsafe { sweeps_avx2(t, self, values, x, tmp) },
            _ => sweeps(self, values, x, tmp),
        }
    }
}

/// The [`Split`] of `nodes` (see there), if their numbering is a postorder of the
/// elimination tree and its top splits into two groups of at least
/// [`MIN_GROUP_SHARE`] of the `len_val` values each.
fn find_split(nodes: &[Supernode], rows: &[usize], len_val: usize) -> Option<Split> {
    let n = nodes.len();
    let last = nodes.last()?;
    let n_cols = last.start + last.width;
    let mut owner = vec![0usize; n_cols];
    for (s, nd) in nodes.iter().enumerate() {
        owner[nd.start..nd.start + nd.width].fill(s);
    }
    // the parent of a supernode holds its first off-diagonal row
    let parent: Vec<Option<usize>> = nodes
        .iter()
        .map(|nd| (nd.len > 0).then(|| owner[rows[nd.pattern]]))
        .collect();
    // postorder: every parent after its children, and every subtree the range
    // first..=s (its size equals that range's length, first its lowest node)
    let (mut size, mut first) = (vec![1usize; n], (0..n).collect::<Vec<usize>>());
    let mut children = vec![Vec::new(); n];
    for s in 0..n {
        if s + 1 != size[s] + first[s] {
            return None;
        }
        if let Some(p) = parent[s] {
            if p <= s {
                return None;
            }
            size[p] += size[s];
            first[p] = first[p].min(first[s]);
            children[p].push(s);
        }
    }
    // the tops of the subtrees to split: the roots, or the children of the first
    // node below a single root with two or more
    let roots: Vec<usize> = (0..n).filter(|&s| parent[s].is_none()).collect();
    let mut top = roots;
    while let [r] = top[..] {
        top = std::mem::take(&mut children[r]);
    }
    if top.len() < 2 {
        return None;
    }
    // values of the supernodes lo..hi (their blocks are consecutive in the factor)
    let end = |s: usize| nodes[s].values + (nodes[s].width + nodes[s].len) * nodes[s].width;
    let work = |lo: usize, hi: usize| end(hi - 1) - nodes[lo].values;
    let (a, c) = (first[top[0]], top[top.len() - 1] + 1);
    let b = (1..top.len())
        .map(|j| top[j - 1] + 1)
        .min_by_key(|&b| work(a, b).abs_diff(work(b, c)))?;
    let least = work(a, b).min(work(b, c)) as f64;
    if least < MIN_GROUP_SHARE * len_val as f64 {
        return None;
    }
    let col_c = nodes.get(c).map_or(n_cols, |nd| nd.start);
    let recorded = nodes[b..c]
        .iter()
        .map(|nd| {
            rows[nd.pattern..nd.pattern + nd.len]
                .iter()
                .filter(|&&r| r >= col_c)
                .count()
        })
        .sum();
    Some(Split {
        a,
        b,
        c,
        col_b: nodes[b].start,
        col_c,
        recorded,
    })
}

/// Where a group's forward updates of rows outside its own columns go: into the
/// rows above both groups (`x[r − base]`), or recorded in order.
enum Far<'a, T> {
    Rows { x: &'a mut [T], base: usize },
    Record(&'a mut [T]),
}

/// The forward sweep over the supernodes `range`, whose columns (and rows below
/// `own`'s end) are `own` = x[`base`..]; updates of rows beyond go to `far`.
#[inline(always)]
fn forward_range<T: Real>(
    plan: &SupernodalSolve,
    range: std::ops::Range<usize>,
    values: &[T],
    own: &mut [T],
    base: usize,
    mut far: Far<'_, T>,
    tmp: &mut [T],
) {
    let mut k = 0;
    for s in &plan.nodes[range] {
        let acc = forward_block(s, values, &mut own[s.start - base..], tmp);
        for (&r, &a) in plan.rows[s.pattern..s.pattern + s.len].iter().zip(acc.iter()) {
            match own.get_mut(r.wrapping_sub(base)) {
                Some(v) => *v -= a,
                None => match &mut far {
                    Far::Rows { x, base } => x[r - *base] -= a,
                    Far::Record(out) => {
                        out[k] = a;
                        k += 1;
                    }
                },
            }
        }
    }
}

/// The backward sweep over the supernodes `range` (in reverse), whose columns are
/// `own` = x[`base`..]; rows beyond are read from `far` = x[`far_base`..].
#[inline(always)]
fn backward_range<T: Real>(
    plan: &SupernodalSolve,
    range: std::ops::Range<usize>,
    values: &[T],
    own: &mut [T],
    base: usize,
    (far, far_base): (&[T], usize),
    tmp: &mut [T],
) {
    for s in plan.nodes[range].iter().rev() {
        let below = &mut tmp[..s.len];
        for (b, &r) in below.iter_mut().zip(&plan.rows[s.pattern..s.pattern + s.len]) {
            *b = match own.get(r.wrapping_sub(base)) {
                Some(&v) => v,
                None => far[r - far_base],
            };
        }
        backward_block(s, values, &mut own[s.start - base..], below);
    }
}

/// [`forward_range`] and [`backward_range`] compiled with AVX2 enabled when the
/// token is given (as [`sweeps_avx2`]; closures do not inherit a target feature, so
/// the threads of [`split_sweeps`] call these).
macro_rules! with_avx2 {
    ($name:ident, $avx2:ident, $body:ident, ($($arg:ident: $ty:ty),*)) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        #[allow(clippy::too_many_arguments)]
        unsafe fn $avx2<T: Real>(_: Avx2Token, $($arg: $ty),*) {
            $body($($arg),*)
        }
        #[allow(clippy::too_many_arguments)]
        fn $name<T: Real>(avx2: Option<Avx2Token>, $($arg: $ty),*) {
            match avx2 {
                // SAFETY: the token proves the CPU has avx2 and fma (the same
                // safe, bounds-checked work as the baseline's)
                #[cfg(target_arch = "x86_64")]
                Some(t) => unsafe { $avx2(t, $($arg),*) },
                _ => $body($($arg),*),
            }
        }
    };
}
with_avx2!(forward_on, forward_range_avx2, forward_range, (
    plan: &SupernodalSolve, range: std::ops::Range<usize>, values: &[T], own: &mut [T], base: usize,
    far: Far<'_, T>, tmp: &mut [T]
));
with_avx2!(backward_on, backward_range_avx2, backward_range, (
    plan: &SupernodalSolve, range: std::ops::Range<usize>, values: &[T], own: &mut [T], base: usize,
    far: (&[T], usize), tmp: &mut [T]
));

/// The two sweeps with the groups of `sp` side by side (see [`Split`]); `tmp` holds
/// two scratch patterns and B's recorded updates.
fn split_sweeps<T: Real>(
    plan: &SupernodalSolve,
    sp: &Split,
    avx2: Option<Avx2Token>,
    values: &[T],
    x: &mut [T],
    tmp: &mut [T],
) {
    let n = plan.nodes.len();
    let (ta, rest) = tmp.split_at_mut(plan.longest);
    let (tb, recorded) = rest.split_at_mut(plan.longest);
    let none = || Far::Rows { x: &mut [], base: 0 };
    forward_on(avx2, plan, 0..sp.a, values, x, 0, none(), ta);
    {
        let (lo, rest) = x.split_at_mut(sp.col_b);
        let (xb, above) = rest.split_at_mut(sp.col_c - sp.col_b);
        let far_a = Far::Rows {
            x: above,
            base: sp.col_c,
        };
        rayon::join(
            || forward_on(avx2, plan, sp.a..sp.b, values, lo, 0, far_a, ta),
            || forward_on(avx2, plan, sp.b..sp.c, values, xb, sp.col_b, Far::Record(recorded), tb),
        );
    }
    let mut k = 0;
    for s in &plan.nodes[sp.b..sp.c] {
        for &r in &plan.rows[s.pattern..s.pattern + s.len] {
            if r >= sp.col_c {
                x[r] -= recorded[k];
                k += 1;
            }
        }
    }
    forward_on(avx2, plan, sp.c..n, values, x, 0, none(), ta);
    backward_on(avx2, plan, sp.c..n, values, x, 0, (&[], 0), ta);
    {
        let (lo, rest) = x.split_at_mut(sp.col_b);
        let (xb, above) = rest.split_at_mut(sp.col_c - sp.col_b);
        let above: &[T] = above;
        rayon::join(
            || backward_on(avx2, plan, sp.a..sp.b, values, lo, 0, (above, sp.col_c), ta),
            || backward_on(avx2, plan, sp.b..sp.c, values, xb, sp.col_b, (above, sp.col_c), tb),
        );
    }
    backward_on(avx2, plan, 0..sp.a, values, x, 0, (&[], 0), ta);
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
    let acc = forward_block(s, values, &mut x[s.start..], tmp);
    for (&r, &a) in rows[s.pattern..s.pattern + s.len].iter().zip(acc.iter()) {
        x[r] -= a;
    }
}

/// The dense part of [`forward`]: x_s ← L_ss⁻¹ x_s on `top` (starting at the
/// supernode's first column), and L_ps x_s in `tmp`'s first p entries, returned.
#[inline(always)]
fn forward_block<'t, T: Real>(s: &Supernode, values: &[T], top: &mut [T], tmp: &'t mut [T]) -> &'t [T] {
    let (w, p) = (s.width, s.len);
    let ld = w + p;
    let block = &values[s.values..s.values + ld * w];
    let top = &mut top[..w];
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
    acc
}

/// x_s −= L_psᵀ x_pattern, then x_s ← L_ss⁻ᵀ x_s, column by column from the last
/// (each a contiguous dot product).
#[inline(always)]
fn backward<T: Real>(s: &Supernode, values: &[T], rows: &[usize], x: &mut [T], tmp: &mut [T]) {
    let below = &mut tmp[..s.len];
    for (b, &r) in below.iter_mut().zip(&rows[s.pattern..s.pattern + s.len]) {
        *b = x[r];
    }
    backward_block(s, values, &mut x[s.start..], below);
}

/// The dense part of [`backward`], with the pattern's values gathered in `below`
/// and `top` starting at the supernode's first column.
#[inline(always)]
fn backward_block<T: Real>(s: &Supernode, values: &[T], top: &mut [T], below: &[T]) {
    let (w, p) = (s.width, s.len);
    let ld = w + p;
    let block = &values[s.values..s.values + ld * w];
    let top = &mut top[..w];
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
