//! The system matrix c_k K + c_m M of a tangent solve, assembled in 3×3 blocks by
//! node pairs (block compressed sparse rows, full storage), so that conjugate
//! gradients multiply by a sparse matrix (~70 bytes per stored block, ~15 blocks per
//! node) instead of re-reading every tet's 12×12 stiffness (1152 bytes per tet,
//! four times) at each iteration.
//!
//! The sparsity pattern and a per-row list of where each incident tet's blocks go
//! are built once per mesh and set of tangent operators; the values are refilled at
//! each Newton iteration, in parallel over rows, each row summing its tets in a fixed
//! order: the same bits for any thread count. The products are parallel over rows
//! too (one thread per row, fixed order). Held coordinates (fixed nodes, sliders)
//! are masked: the products and preconditioners leave zeros on them, so CG runs on
//! the free coordinates only.

mod gauss_seidel;

pub(in crate::system) use gauss_seidel::GsOrdering;

use super::cg::CHUNK;
use crate::force::TangentOperator;
use nalgebra::Matrix3;
use rayon::prelude::*;

/// One incident tet of a row: the operator, its tet, the row node's local vertex and
/// the block (index into the values) of each of the tet's four nodes in this row.
#[derive(Debug, Clone, Copy)]
struct Incidence {
    op: u32,
    tet: u32,
    local: u8,
    blocks: [u32; 4],
}

/// c_k K + c_m M in 3×3 blocks by node pairs, with the masks and preconditioners of
/// the free coordinates.
#[derive(Debug, Clone)]
pub(in crate::system) struct BlockMatrix {
    /// Blocks of row i: `start[i]..start[i + 1]`, columns ascending.
    start: Vec<usize>,
    col: Vec<u32>,
    /// Index of the diagonal block of each row.
    diag: Vec<usize>,
    val: Vec<Matrix3<f64>>,
    /// Incidences of row i: `inc[start_inc[i]..start_inc[i + 1]]`.
    start_inc: Vec<usize>,
    inc: Vec<Incidence>,
    /// The global tet ids of each operator the pattern was built for.
    built_for: Vec<Vec<usize>>,
    /// 1 on a free coordinate, 0 on a held one (3 per node).
    mask: Vec<f64>,
    /// Inverse of each node's diagonal block restricted to its free coordinates
    /// (zero rows and columns on held ones).
    dinv: Vec<Matrix3<f64>>,
}

/// Rows of at least this many nodes per parallel task.
const MIN_ROWS: usize = 128;

fn block_of(p: &[f64], j: usize) -> nalgebra::Vector3<f64> {
    nalgebra::Vector3::new(p[3 * j], p[3 * j + 1], p[3 * j + 2])
}

/// The inverse of block `b` restricted to the free coordinates `free` (zero rows and
/// columns on held ones); a block that cannot be inverted falls back to the inverse
/// of its diagonal (or 1 on a non-positive entry).
fn restricted_inverse(b: &Matrix3<f64>, free: [bool; 3]) -> Matrix3<f64> {
    let keep = |r: usize, c: usize| free[r] && free[c];
    let restricted = Matrix3::from_fn(|r, c| {
        if keep(r, c) {
            b[(r, c)]
        } else if r == c {
            1.0
        } else {
            0.0
        }
    });
    let inv = restricted.try_inverse().filter(|m| m.iter().all(|v| v.is_finite()));
    let inv = inv.unwrap_or_else(|| {
        Matrix3::from_fn(|r, c| match (r == c, b[(r, r)]) {
            (true, d) if d > 0.0 => 1.0 / d,
            (true, _) => 1.0,
            _ => 0.0,
        })
    });
    Matrix3::from_fn(|r, c| if keep(r, c) { inv[(r, c)] } else { 0.0 })
}

impl BlockMatrix {
    /// The pattern of the operators' tets (`tets` the mesh's tets, by global id) over
    /// `n` nodes; values zero until [`BlockMatrix::fill`].
    pub(in crate::system) fn new(n: usize, tets: &[[u32; 4]], ops: &[Box<dyn TangentOperator>]) -> Self {
        // incidences per node, in (operator, tet, local vertex) order
        let mut count = vec![0usize; n + 1];
        for op in ops {
            for &t in op.tet_ids() {
                for &i in &tets[t] {
                    count[i as usize + 1] += 1;
                }
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let start_inc = count.clone();
        let mut fill = count;
        let mut inc = vec![
            Incidence {
                op: 0,
                tet: 0,
                local: 0,
                blocks: [0; 4],
            };
            start_inc[n]
        ];
        for (o, op) in ops.iter().enumerate() {
            for (k, &t) in op.tet_ids().iter().enumerate() {
                for (a, &i) in tets[t].iter().enumerate() {
                    inc[fill[i as usize]] = Incidence {
                        op: o as u32,
                        tet: k as u32,
                        local: a as u8,
                        blocks: [0; 4],
                    };
                    fill[i as usize] += 1;
                }
            }
        }
        // pattern: the sorted neighbours of each node (itself included)
        let mut start = Vec::with_capacity(n + 1);
        let mut col: Vec<u32> = Vec::new();
        let mut diag = Vec::with_capacity(n);
        start.push(0);
        let mut row: Vec<u32> = Vec::new();
        for i in 0..n {
            row.clear();
            row.push(i as u32);
            for c in &inc[start_inc[i]..start_inc[i + 1]] {
                let t = ops[c.op as usize].tet_ids()[c.tet as usize];
                row.extend_from_slice(&tets[t]);
            }
            row.sort_unstable();
            row.dedup();
            let base = col.len();
            diag.push(base + row.binary_search(&(i as u32)).expect("the node itself"));
            col.extend_from_slice(&row);
            start.push(col.len());
            for c in &mut inc[start_inc[i]..start_inc[i + 1]] {
                let t = ops[c.op as usize].tet_ids()[c.tet as usize];
                for (b, &j) in tets[t].iter().enumerate() {
                    let pos = row.binary_search(&j).expect("a tet's node is a neighbour");
                    c.blocks[b] = (base + pos) as u32;
                }
            }
        }
        BlockMatrix {
            val: vec![Matrix3::zeros(); col.len()],
            start,
            col,
            diag,
            start_inc,
            inc,
            built_for: ops.iter().map(|o| o.tet_ids().to_vec()).collect(),
            mask: vec![1.0; 3 * n],
            dinv: vec![Matrix3::zeros(); n],
        }
    }

    /// Whether the pattern was built for these operators (same tets, in order).
    pub(in crate::system) fn fits(&self, n: usize, ops: &[Box<dyn TangentOperator>]) -> bool {
        self.diag.len() == n
            && self.built_for.len() == ops.len()
            && self.built_for.iter().zip(ops).all(|(b, o)| b == o.tet_ids())
    }

    /// Number of nodes (block rows).
    pub(in crate::system) fn n_nodes(&self) -> usize {
        self.diag.len()
    }

    /// Sets the values to c_k K + c_m M + E (K the operators' stored stiffness, M the
    /// lumped masses, E optional per-node 3×3 blocks added to the diagonal: grasp
    /// springs, tool contacts), the free-coordinate mask and the block-Jacobi inverses.
    pub(in crate::system) fn fill(
        &mut self,
        ops: &[Box<dyn TangentOperator>],
        ck: f64,
        cm: f64,
        mass: &[f64],
        extra_diagonal: Option<&[Matrix3<f64>]>,
        free: impl Fn(usize, usize) -> bool,
    ) {
        let n = self.n_nodes();
        // one mutable slice of values per row, filled in parallel
        let mut rows: Vec<&mut [Matrix3<f64>]> = Vec::with_capacity(n);
        let mut rest = self.val.as_mut_slice();
        for i in 0..n {
            let (row, tail) = rest.split_at_mut(self.start[i + 1] - self.start[i]);
            rows.push(row);
            rest = tail;
        }
        let (start, start_inc, inc, diag) = (&self.start, &self.start_inc, &self.inc, &self.diag);
        rows.par_iter_mut()
            .enumerate()
            .with_min_len(MIN_ROWS)
            .for_each(|(i, row)| {
                row.fill(Matrix3::zeros());
                let base = start[i];
                for c in &inc[start_inc[i]..start_inc[i + 1]] {
                    let k = ops[c.op as usize].tet_row(c.tet as usize, c.local as usize);
                    for (b, &blk) in c.blocks.iter().enumerate() {
                        row[blk as usize - base] += k[b] * ck;
                    }
                }
                row[diag[i] - base] += Matrix3::identity() * (cm * mass[i]);
                if let Some(extra) = extra_diagonal {
                    row[diag[i] - base] += extra[i];
                }
            });
        for i in 0..n {
            for a in 0..3 {
                self.mask[3 * i + a] = if free(i, a) { 1.0 } else { 0.0 };
            }
        }
        let (val, mask) = (&self.val, &self.mask);
        self.dinv
            .par_iter_mut()
            .enumerate()
            .with_min_len(MIN_ROWS)
            .for_each(|(i, d)| {
                let f = [mask[3 * i] > 0.0, mask[3 * i + 1] > 0.0, mask[3 * i + 2] > 0.0];
                *d = restricted_inverse(&val[diag[i]], f);
            });
    }

    /// The stored blocks of row `i` as (column node, block index into
    /// [`Self::blocks`]), columns ascending: the direct solver's pattern.
    pub(in crate::system) fn row_blocks(&self, i: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        (self.start[i]..self.start[i + 1]).map(|b| (self.col[b] as usize, b))
    }

    /// The values of the stored blocks (unmasked), by block index.
    pub(in crate::system) fn blocks(&self) -> &[Matrix3<f64>] {
        &self.val
    }

    /// 1 on a free coordinate (flat index, 3 per node), 0 on a held one.
    pub(in crate::system) fn mask(&self, i: usize) -> f64 {
        self.mask[i]
    }

    /// out = A p on the free coordinates (zero on held ones), p by node (3 per node,
    /// zero on held coordinates); returns pᵀ out, summed over fixed chunks of rows in
    /// order (the same bits for any thread count).
    pub(in crate::system) fn apply(&self, p: &[f64], out: &mut [f64]) -> f64 {
        let (start, col, val, mask) = (&self.start, &self.col, &self.val, &self.mask);
        let partial: Vec<f64> = out
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(k, o)| {
                let first = k * CHUNK / 3;
                let mut pap = 0.0;
                for (r, o) in o.chunks_exact_mut(3).enumerate() {
                    let i = first + r;
                    let mut acc = nalgebra::Vector3::zeros();
                    for b in start[i]..start[i + 1] {
                        acc += val[b] * block_of(p, col[b] as usize);
                    }
                    for a in 0..3 {
                        o[a] = acc[a] * mask[3 * i + a];
                        pap += o[a] * p[3 * i + a];
                    }
                }
                pap
            })
            .collect();
        partial.iter().sum()
    }

    /// out = D⁻¹ r: the 3×3 block-Jacobi preconditioner; returns rᵀ out (chunked as
    /// [`Self::apply`]).
    pub(in crate::system) fn block_jacobi(&self, r: &[f64], out: &mut [f64]) -> f64 {
        let dinv = &self.dinv;
        let partial: Vec<f64> = out
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(k, o)| {
                let first = k * CHUNK / 3;
                let mut rz = 0.0;
                for (i, o) in o.chunks_exact_mut(3).enumerate() {
                    let (ri, zi) = (block_of(r, first + i), dinv[first + i] * block_of(r, first + i));
                    o.copy_from_slice(zi.as_slice());
                    rz += ri.dot(&zi);
                }
                rz
            })
            .collect();
        partial.iter().sum()
    }

    /// out = M⁻¹ r with M = (D + L) D⁻¹ (D + U) the symmetric block Gauss–Seidel
    /// (SSOR, ω = 1) preconditioner: a forward and a backward sweep over the blocks.
    /// Symmetric positive definite whenever the diagonal blocks are; sequential (the
    /// sweeps' order is the node order), hence deterministic. Returns rᵀ out.
    pub(in crate::system) fn symmetric_gauss_seidel(&self, r: &[f64], out: &mut [f64]) -> f64 {
        let n = self.n_nodes();
        let (start, col, val, dinv, diag) = (&self.start, &self.col, &self.val, &self.dinv, &self.diag);
        // (D + L) y = r
        for i in 0..n {
            let mut t = block_of(r, i);
            for b in start[i]..diag[i] {
                t -= val[b] * block_of(out, col[b] as usize);
            }
            out[3 * i..3 * i + 3].copy_from_slice((dinv[i] * t).as_slice());
        }
        // (D + U) z = D y: z_i = y_i − D_i⁻¹ Σ_{j>i} A_ij z_j
        let mut rz = 0.0;
        for i in (0..n).rev() {
            let mut t = nalgebra::Vector3::zeros();
            for b in diag[i] + 1..start[i + 1] {
                t += val[b] * block_of(out, col[b] as usize);
            }
            let z = block_of(out, i) - dinv[i] * t;
            out[3 * i..3 * i + 3].copy_from_slice(z.as_slice());
            rz += z.dot(&block_of(r, i));
        }
        rz
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::error::Result;
    use crate::force::TetStiffness;
    use crate::mesh::generate::{box_mesh, HexSplit};
    use crate::Vec3;
    use nalgebra::DMatrix;

    /// A tangent with a fixed random symmetric 12×12 matrix per tet.
    struct Fixed {
        ids: Vec<usize>,
        k: Vec<TetStiffness>,
        n: usize,
    }

    impl TangentOperator for Fixed {
        fn n_nodes(&self) -> usize {
            self.n
        }
        fn tet_ids(&self) -> &[usize] {
            &self.ids
        }
        fn update(&mut self, _: &[Vec3]) -> Result<()> {
            Ok(())
        }
        fn add_product(&self, _: &[Vec3], _: &mut [Vec3]) -> Result<()> {
            unreachable!("the assembled matrix does not use the matrix-free product")
        }
        fn add_diagonal_blocks(&self, _: &mut [Matrix3<f64>]) -> Result<()> {
            unreachable!()
        }
        fn tet_stiffness(&self, k: usize) -> TetStiffness {
            self.k[k]
        }
        fn projects(&self) -> bool {
            true
        }
    }

    pub(in crate::system::implicit) fn rnd(s: &mut u64) -> f64 {
        *s ^= *s << 13;
        *s ^= *s >> 7;
        *s ^= *s << 17;
        (*s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }

    /// The assembled K + M of one operator with a random Gram stiffness on every tet
    /// of `mesh` and unit masses, the coordinates marked in `held` held: an SPD
    /// system with the pattern of the mesh's tangent (for the direct solver's tests).
    pub(in crate::system::implicit) fn random_system(mesh: &crate::mesh::TetMesh, held: &[[bool; 3]]) -> BlockMatrix {
        let (n, nt) = (mesh.n_nodes(), mesh.n_tets());
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let k = (0..nt)
            .map(|_| {
                let g = TetStiffness::from_fn(|_, _| rnd(&mut s));
                g * g.transpose()
            })
            .collect();
        let ops: Vec<Box<dyn TangentOperator>> = vec![Box::new(Fixed {
            ids: (0..nt).collect(),
            k,
            n,
        })];
        let mut m = BlockMatrix::new(n, mesh.tets(), &ops);
        m.fill(&ops, 1.0, 1.0, &vec![1.0; n], None, |i, a| !held[i][a]);
        m
    }

    /// Two operators over halves of a 3×2×2 box (every tet once), the dense
    /// c_k K + c_m M they make, masked to the free coordinates (node 0 held, node 1
    /// held in y only), and the assembled matrix.
    pub(in crate::system::implicit) fn setup() -> (BlockMatrix, DMatrix<f64>, Vec<bool>) {
        let mesh = box_mesh([3.0, 2.0, 2.0], [3, 2, 2], HexSplit::Six).unwrap();
        let (n, nt) = (mesh.n_nodes(), mesh.n_tets());
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut ops: Vec<Box<dyn TangentOperator>> = Vec::new();
        for half in [0..nt / 2, nt / 2..nt] {
            let ids: Vec<usize> = half.collect();
            let k = ids
                .iter()
                .map(|_| {
                    let g = TetStiffness::from_fn(|_, _| rnd(&mut s));
                    g * g.transpose()
                })
                .collect();
            ops.push(Box::new(Fixed { ids, k, n }));
        }
        let (ck, cm) = (0.7, 3.0);
        let mass: Vec<f64> = (0..n).map(|i| 1.0 + 0.1 * i as f64).collect();
        let free = |i: usize, a: usize| i != 0 && !(i == 1 && a == 1);
        let mut dense = DMatrix::zeros(3 * n, 3 * n);
        for op in &ops {
            for (k, &t) in op.tet_ids().iter().enumerate() {
                let nodes = mesh.tets()[t];
                for (a, &i) in nodes.iter().enumerate() {
                    for (b, &j) in nodes.iter().enumerate() {
                        for r in 0..3 {
                            for c in 0..3 {
                                dense[(3 * i as usize + r, 3 * j as usize + c)] +=
                                    ck * op.tet_stiffness(k)[(3 * a + r, 3 * b + c)];
                            }
                        }
                    }
                }
            }
        }
        let mask: Vec<bool> = (0..3 * n).map(|d| free(d / 3, d % 3)).collect();
        for d in 0..3 * n {
            dense[(d, d)] += cm * mass[d / 3];
        }
        for r in 0..3 * n {
            for c in 0..3 * n {
                if !(mask[r] && mask[c]) {
                    dense[(r, c)] = 0.0;
                }
            }
        }
        let mut m = BlockMatrix::new(n, mesh.tets(), &ops);
        assert!(m.fits(n, &ops));
        m.fill(&ops, ck, cm, &mass, None, free);
        (m, dense, mask)
    }

    /// The assembled product equals the dense matrix's on the free coordinates.
    /// Bound: sums of ~100 O(1) terms, so 1e-12 is ~1000× the round-off.
    #[test]
    fn assembled_product_matches_the_dense_matrix() {
        let (m, dense, mask) = setup();
        let mut s = 7u64;
        let p: Vec<f64> = mask.iter().map(|&f| if f { rnd(&mut s) } else { 0.0 }).collect();
        let mut out = vec![0.0; p.len()];
        m.apply(&p, &mut out);
        let want = &dense * nalgebra::DVector::from_column_slice(&p);
        for d in 0..p.len() {
            assert!((out[d] - want[d]).abs() < 1e-12 * want.amax(), "coordinate {d}");
        }
    }

    /// Symmetric Gauss–Seidel applies the inverse of (D + L) D⁻¹ (D + U), built
    /// densely from the free part of the matrix, and leaves held coordinates at 0;
    /// it returns rᵀz. Bounds as in [`assert_inverts_splitting`].
    #[test]
    fn symmetric_gauss_seidel_inverts_its_splitting() {
        let (m, dense, mask) = setup();
        let mut s = 11u64;
        let r: Vec<f64> = mask.iter().map(|&f| if f { rnd(&mut s) } else { 0.0 }).collect();
        let mut z = vec![0.0; mask.len()];
        let rz = m.symmetric_gauss_seidel(&r, &mut z);
        let order: Vec<usize> = (0..m.n_nodes()).collect();
        assert_inverts_splitting(&dense, &mask, &order, &r, &z);
        let want: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        assert!((rz - want).abs() <= 1e-12 * want.abs(), "{rz} vs {want}");
    }

    /// Adds `block` to node `i`'s diagonal block (a contact spring in the tests of
    /// the direct solver).
    pub(in crate::system::implicit) fn add_to_diagonal(m: &mut BlockMatrix, i: usize, block: Matrix3<f64>) {
        let d = m.diag[i];
        m.val[d] += block;
    }

    /// Multiplies every stored block of `m` by `s` (the same pattern).
    pub(in crate::system::implicit) fn scale(m: &mut BlockMatrix, s: f64) {
        m.val.iter_mut().for_each(|b| *b *= s);
    }

    /// Asserts z = P⁻¹ r on the free coordinates and z = 0 on the held ones, with
    /// P = (D + L) D⁻¹ (D + U) built densely from `dense` with the nodes in the
    /// order `order` (L: the blocks (i, j) with j before i). Bound: the sweeps are
    /// backward stable on this well-conditioned (SPD, mass-shifted) matrix, so P z
    /// reproduces r (entries O(1)) to ~1e-13; 1e-10 is ample, and a wrong ordering
    /// or dropped coupling gives O(0.1) differences.
    pub(super) fn assert_inverts_splitting(dense: &DMatrix<f64>, mask: &[bool], order: &[usize], r: &[f64], z: &[f64]) {
        let nd = mask.len();
        let mut pos = vec![0; nd / 3];
        for (k, &node) in order.iter().enumerate() {
            pos[node] = k;
        }
        // D: the 3×3 diagonal blocks (identity on held coordinates), L / U: the rest
        let mut d = DMatrix::zeros(nd, nd);
        let mut l = DMatrix::zeros(nd, nd);
        for i in 0..nd {
            for j in 0..nd {
                if i / 3 == j / 3 {
                    d[(i, j)] = if mask[i] && mask[j] {
                        dense[(i, j)]
                    } else {
                        f64::from(u8::from(i == j))
                    };
                } else if pos[j / 3] < pos[i / 3] {
                    l[(i, j)] = dense[(i, j)];
                }
            }
        }
        let u = l.transpose();
        let prec = (&d + &l) * d.clone().try_inverse().unwrap() * (&d + &u);
        let back = prec * nalgebra::DVector::from_column_slice(z);
        for i in 0..nd {
            if mask[i] {
                assert!(
                    (back[i] - r[i]).abs() < 1e-10,
                    "coordinate {i}: {} vs {}",
                    back[i],
                    r[i]
                );
            } else {
                assert_eq!(z[i], 0.0, "held coordinate {i}");
            }
        }
    }
}
