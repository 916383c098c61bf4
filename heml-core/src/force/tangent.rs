//! The exact tangent stiffness K = ∂²W/∂x² of a law over (a region of) a mesh, from
//! the generated second derivatives, for implicit integration (and any Newton solve
//! that wants a matrix-free operator).
//!
//! Per tet, W = Vol·w(I1, I2, J) is a function of the seven quantities
//! q = (l_1..l_6, J) (DESIGN §1), so the chain rule gives the 12×12 stiffness
//!
//! K = G H Gᵀ + Σ_e g_e ∇²l_e + w_J ∇²vol,
//!
//! with G = [∇l_1 … ∇l_6 ∇J] (12×7; ∇l_e = ±2 v_e on the edge's head/tail,
//! ∇J = ∇vol/Vol from the cross products), H = ∂²W/∂q² (7×7: the law's `d2w` in
//! (I1, I2, J) pulled back through I1 = vtr·l, I2 = ½(I1² − lᵀMtr l), whose own
//! second derivative vtr vtrᵀ − Mtr adds w2·(vtr vtrᵀ − Mtr)), g_e = ∂W/∂l_e,
//! ∇²l_e = 2[[I, −I], [−I, I]] on the edge's two nodes and ∇²vol the constant-
//! coefficient bilinear form of the triple product. Below J0 the law's `*_ext`
//! derivatives are used, on exactly the force kernel's branch, so K is the exact
//! derivative of the forces the system integrates. Link laws have the per-edge
//! closed form K = Σ_e (w''(l_e) ∇l_e∇l_eᵀ + w'(l_e) ∇²l_e).
//!
//! **Definiteness.** The exact K is indefinite for compressed or inverted tets (and
//! for link springs under compression), which a conjugate-gradient solve cannot
//! accept. With `project_psd` each tet's 12×12 matrix is replaced by its projection
//! onto the positive semi-definite cone in the translation-free coordinates (the
//! 9×9 Hessian in the edge vectors from node 0, negative eigenvalues clamped to 0).
//! The projected matrix keeps the translations as null modes (and the rotations at
//! rest) and equals K wherever K is already semi-definite, e.g. near the rest state
//! (detected by a Cholesky factorisation). Invariant laws are isotropic: their
//! stiffness is built in 3×3 node blocks straight from F and the law's second
//! derivatives, definiteness is decided from the closed-form eigenvalues of ∂²Ψ/∂F²
//! (after a cheaper sufficient test on C and J for laws without I2,
//! `force/definite.rs`) and an indefinite tet gets rank-one corrections along its negative modes
//! (`force/invariant_blocks.rs`; the iterative SVD of `force/eigensystem.rs` only
//! where the closed-form one is inaccurate); link laws, and a tet whose SVD fails,
//! go through the numerical eigen-decomposition of K₉ ([`project_psd`]). The
//! implicit integrators project by default.
//!
//! The per-tet matrices are computed once per [`TangentOperator::update`] (in
//! parallel) and stored as their ten distinct 3×3 blocks ([`TetBlocks`], 90 numbers
//! per tet); the product y += K·dx gathers, per node, the block rows of its incident
//! tets, in parallel over nodes: race-free and bit-for-bit deterministic for any
//! thread count.

// The 12×12 assembly indexes node blocks and coordinates in lock-step; iterator
// chains over several arrays would obscure the formulas.
#![allow(clippy::needless_range_loop)]

use super::eigensystem::{edge_hessian, eigensystem, EdgeHessian};
use super::field::{check_sizes, selection};
use super::heml::{invariant_terms, volume_terms};
use super::invariant_blocks::{exact_blocks, project_blocks, TetState};
use super::ForceOptions;
use crate::error::{HemlError, Result};
use crate::law::{InvariantLaw, LinkLaw};
use crate::mesh::TetMesh;
use crate::rest::{edge_vectors, rest_edge_matrix, RestTet, EDGES};
use crate::Vec3;
use nalgebra::{Matrix3, SMatrix, SymmetricEigen};

/// A 12×12 tet stiffness, rows and columns ordered (node 0 x, y, z, node 1 x, …).
pub type TetStiffness = SMatrix<f64, 12, 12>;

/// The ten distinct 3×3 node blocks (a, b), a ≤ b, of a symmetric tet stiffness, in
/// the order of [`BLOCK_PAIRS`] (block (b, a) is the transpose of (a, b)): what a
/// [`TangentField`] stores per tet, 720 bytes instead of the 1152 of a 12×12.
pub type TetBlocks = [Matrix3<f64>; 10];

/// The node pairs (a, b), a ≤ b, of the blocks of a [`TetBlocks`].
pub const BLOCK_PAIRS: [(usize, usize); 10] = [
    (0, 0),
    (0, 1),
    (0, 2),
    (0, 3),
    (1, 1),
    (1, 2),
    (1, 3),
    (2, 2),
    (2, 3),
    (3, 3),
];

/// Tets per call of a tangent update's loop body (`parallel::for_each_chunk_mut`):
/// each a few microseconds of Hessian work, so one call per 64 costs nothing.
const UPDATE_CHUNK: usize = 64;
/// Nodes per call of a product's loop body (each node a few dozen 3×3 blocks).
const PRODUCT_CHUNK: usize = 256;

/// Index in [`BLOCK_PAIRS`] of the block (min(a, b), max(a, b)).
const BLOCK_INDEX: [[usize; 4]; 4] = [[0, 1, 2, 3], [1, 4, 5, 6], [2, 5, 7, 8], [3, 6, 8, 9]];

/// Block (a, b) of a symmetric tet stiffness held as [`TetBlocks`].
#[inline(always)]
pub fn tet_block(k: &TetBlocks, a: usize, b: usize) -> Matrix3<f64> {
    let m = k[BLOCK_INDEX[a][b]];
    if a <= b {
        m
    } else {
        m.transpose()
    }
}

/// The blocks of the symmetric part of a 12×12 tet stiffness.
pub fn stiffness_to_blocks(k: &TetStiffness) -> TetBlocks {
    BLOCK_PAIRS.map(|(a, b)| {
        let m = k.fixed_view::<3, 3>(3 * a, 3 * b).into_owned();
        (m + k.fixed_view::<3, 3>(3 * b, 3 * a).transpose()) * 0.5
    })
}

/// The 12×12 stiffness of blocks `k`.
pub fn blocks_to_stiffness(k: &TetBlocks) -> TetStiffness {
    let mut out = TetStiffness::zeros();
    for (m, &(a, b)) in BLOCK_PAIRS.iter().enumerate() {
        out.fixed_view_mut::<3, 3>(3 * a, 3 * b).copy_from(&k[m]);
        if a != b {
            out.fixed_view_mut::<3, 3>(3 * b, 3 * a).copy_from(&k[m].transpose());
        }
    }
    out
}

/// The tangent stiffness of a force field as a matrix-free operator.
pub trait TangentOperator: Send + Sync {
    /// Number of nodes the vectors must have.
    fn n_nodes(&self) -> usize;
    /// Global ids of the tets it covers, in its order.
    fn tet_ids(&self) -> &[usize];
    /// Recomputes the per-tet stiffness at positions `x`. Errors on a non-finite
    /// stiffness (naming the tet) or wrong sizes.
    fn update(&mut self, x: &[Vec3]) -> Result<()>;
    /// y += K·dx with K from the last [`TangentOperator::update`] (zero before it).
    fn add_product(&self, dx: &[Vec3], y: &mut [Vec3]) -> Result<()>;
    /// Adds the 3×3 diagonal blocks of K (per node) to `d`: the block-Jacobi
    /// preconditioner's input.
    fn add_diagonal_blocks(&self, d: &mut [Matrix3<f64>]) -> Result<()>;
    /// The stored (possibly projected) stiffness of the operator's `k`-th tet.
    fn tet_stiffness(&self, k: usize) -> TetStiffness;
    /// The blocks (a, b), b = 0..4, of row `a` of the `k`-th tet's stiffness: what an
    /// assembly by node rows reads. The default copies them out of
    /// [`Self::tet_stiffness`]; operators that store blocks return them directly.
    fn tet_row(&self, k: usize, a: usize) -> [Matrix3<f64>; 4] {
        let m = self.tet_stiffness(k);
        std::array::from_fn(|b| m.fixed_view::<3, 3>(3 * a, 3 * b).into_owned())
    }
    /// Whether each tet's stiffness is projected to positive semi-definite.
    fn projects(&self) -> bool;

    /// Whether K has a part that couples nodes beyond a tet (the nodal volumetric
    /// term of [`super::NodalVolumeField`]) and so is not held by
    /// [`Self::tet_stiffness`]: solvers that assemble the per-tet blocks must add it
    /// with [`Self::add_nonlocal_product`]. False by default.
    fn has_nonlocal(&self) -> bool {
        false
    }
    /// y += K_nonlocal·dx, the part of K not in the per-tet blocks (none by default;
    /// [`Self::add_product`] already includes it).
    fn add_nonlocal_product(&self, dx: &[Vec3], y: &mut [Vec3]) -> Result<()> {
        let _ = (dx, y);
        Ok(())
    }
    /// Adds the 3×3 diagonal blocks of K_nonlocal to `d` (none by default;
    /// [`Self::add_diagonal_blocks`] already includes them).
    fn add_nonlocal_diagonal(&self, d: &mut [Matrix3<f64>]) -> Result<()> {
        let _ = d;
        Ok(())
    }
    /// Calls `f(i, j, block)` with parts of the 3×3 blocks of K_nonlocal (rows of
    /// node i, columns of node j) that sum to K_nonlocal, for solvers that assemble
    /// K in full (the banded static solve). None by default.
    fn for_each_nonlocal_block(&self, f: &mut dyn FnMut(usize, usize, &Matrix3<f64>)) {
        let _ = f;
    }
}

/// The stiffness of one tet from its current vertex positions.
pub trait TetHessian: Send + Sync {
    /// ∂²W/∂x² of the `k`-th tet of the operator at vertex positions `p`.
    fn hessian(&self, k: usize, p: &[Vec3; 4]) -> TetStiffness;
    /// The stiffness projected to positive semi-definite (equal to
    /// [`TetHessian::hessian`] where that already is). The default projects the
    /// finite stiffness with [`project_psd`]; kernels with a cheaper exact projection
    /// override it.
    fn projected(&self, k: usize, p: &[Vec3; 4]) -> TetStiffness {
        let h = self.hessian(k, p);
        if h.iter().all(|c| c.is_finite()) {
            project_psd(&h)
        } else {
            h
        }
    }
    /// The blocks of [`Self::projected`] (`project`) or [`Self::hessian`]: what a
    /// [`TangentField`] stores. The default takes them from the 12×12 matrix; kernels
    /// that build the blocks directly override it.
    fn blocks(&self, k: usize, p: &[Vec3; 4], project: bool) -> TetBlocks {
        let m = if project {
            self.projected(k, p)
        } else {
            self.hessian(k, p)
        };
        stiffness_to_blocks(&m)
    }

    /// [`Self::blocks`] written into `out`, where a [`TangentField`] keeps them:
    /// kernels that build the blocks in place override it (a tangent update then
    /// moves no 720-byte value per tet).
    fn blocks_into(&self, k: usize, p: &[Vec3; 4], project: bool, out: &mut TetBlocks) {
        *out = self.blocks(k, p, project);
    }
}

/// ∇l_e of the six squared edge lengths: 2 v_e on the head, −2 v_e on the tail.
pub(super) fn length_gradients(v: &[Vec3; 6]) -> [[f64; 12]; 6] {
    let mut g = [[0.0; 12]; 6];
    for (e, &(tail, head)) in EDGES.iter().enumerate() {
        for a in 0..3 {
            g[e][3 * head + a] = 2.0 * v[e][a];
            g[e][3 * tail + a] = -2.0 * v[e][a];
        }
    }
    g
}

/// Adds Σ_e c_e ∇²l_e, with ∇²l_e = 2[[I, −I], [−I, I]] on the edge's (tail, head).
pub(super) fn add_length_curvature(k: &mut TetStiffness, c: &[f64; 6]) {
    for (e, &(tail, head)) in EDGES.iter().enumerate() {
        let s = 2.0 * c[e];
        for a in 0..3 {
            k[(3 * tail + a, 3 * tail + a)] += s;
            k[(3 * head + a, 3 * head + a)] += s;
            k[(3 * tail + a, 3 * head + a)] -= s;
            k[(3 * head + a, 3 * tail + a)] -= s;
        }
    }
}

/// The stiffness of an invariant law's tets: rest data of its own, one [`RestTet`]
/// per tet (`Mtr` is needed here: the I2 curvature is w2·(vtr vtrᵀ − Mtr)).
#[derive(Debug, Clone)]
pub struct InvariantHessian<M: InvariantLaw> {
    law: M,
    opts: ForceOptions,
    rest: Vec<RestTet>,
    /// D_m⁻ᵀ per tet (the inverse transposed rest edge matrix), for the analytic
    /// projection.
    dm_inv_t: Vec<Matrix3<f64>>,
}

/// The law's derivatives (w₁, w₂, w_J) and second derivatives at one tet, zero for
/// the invariants the law does not use.
type LawDerivatives = ([f64; 3], [[f64; 3]; 3]);

impl<M: InvariantLaw> TetHessian for InvariantHessian<M> {
    fn hessian(&self, k: usize, p: &[Vec3; 4]) -> TetStiffness {
        blocks_to_stiffness(&self.blocks(k, p, false))
    }

    fn projected(&self, k: usize, p: &[Vec3; 4]) -> TetStiffness {
        blocks_to_stiffness(&self.blocks(k, p, true))
    }

    /// Tets whose analytic spectrum is semi-definite are returned unchanged, the
    /// others with their negative modes clamped (the internal `project_blocks`); a
    /// tet whose closed-form SVD is not accurate enough goes through the iterative
    /// SVD's eigensystem (or, failing that, the numerical projection).
    fn blocks(&self, k: usize, p: &[Vec3; 4], project: bool) -> TetBlocks {
        let mut out = [Matrix3::zeros(); 10];
        self.blocks_into(k, p, project, &mut out);
        out
    }

    fn blocks_into(&self, k: usize, p: &[Vec3; 4], project: bool, out: &mut TetBlocks) {
        let (st, (d, h)) = self.state(k, p);
        *out = exact_blocks(&st, d, h, Self::USED);
        if !project || !all_finite(out) || project_blocks(out, &st, d, h) {
            return;
        }
        let exact = blocks_to_stiffness(out);
        if is_semi_definite(&exact) {
            return;
        }
        *out = stiffness_to_blocks(&match eigensystem(&st.f, d, h) {
            Some(modes) => expand_translation_free(&edge_hessian(&modes, &self.dm_inv_t[k], self.rest[k].vol, true)),
            None => project_psd(&exact),
        });
    }
}

/// Whether every entry of the blocks is finite: one pass without early exit, so
/// that it vectorises (`all` branched on each of the 90 entries: ~8 % of a
/// projected tangent update, with the check before the projection).
#[inline(always)]
fn all_finite(k: &TetBlocks) -> bool {
    k.iter().flat_map(|b| b.iter()).fold(true, |ok, c| ok & c.is_finite())
}

impl<M: InvariantLaw> InvariantHessian<M> {
    /// Which of (I1, I2, J) the law uses.
    const USED: [bool; 3] = [true, M::USES_I2, M::USES_J];

    /// The `k`-th tet's state at positions `p` and the law's derivatives there (zero
    /// for the invariants the law does not use), on the force kernel's branch: the
    /// same I1, I2, J to the bit, the `*_ext` derivatives below J0.
    fn state(&self, k: usize, p: &[Vec3; 4]) -> (TetState, LawDerivatives) {
        let r = &self.rest[k];
        let vol = r.vol;
        let v = edge_vectors(p);
        let l = crate::rest::squared_lengths(&v);
        let (i1, i2, _) = invariant_terms(&r.vtr, &l, M::USES_I2);
        let (j, crosses) = if M::USES_J {
            volume_terms(&v, vol)
        } else {
            (1.0, [Vec3::zeros(); 3])
        };
        let (d, h) = if self.opts.extend(M::INVERSION_FIX, j) {
            let j0 = self.opts.j0;
            (self.law.dw_ext(i1, i2, j, j0), self.law.d2w_ext(i1, i2, j, j0))
        } else {
            (self.law.dw(i1, i2, j), self.law.d2w(i1, i2, j))
        };
        let dm = &self.dm_inv_t[k];
        let f = Matrix3::from_columns(&[v[0], v[1], v[2]]) * dm.transpose();
        let (n1, n2, n3) = (
            dm.column(0).into_owned(),
            dm.column(1).into_owned(),
            dm.column(2).into_owned(),
        );
        let sc = 1.0 / (6.0 * vol);
        let gj = [crosses[0] * sc, crosses[1] * sc, crosses[2] * sc];
        let st = TetState {
            f,
            n: [-(n1 + n2 + n3), n1, n2, n3],
            gj: [-(gj[0] + gj[1] + gj[2]), gj[0], gj[1], gj[2]],
            edges: [v[0], v[1], v[2]],
            i1,
            vol,
        };
        let used = Self::USED;
        let (mut du, mut hu) = ([0.0; 3], [[0.0; 3]; 3]);
        for a in 0..3 {
            if used[a] {
                du[a] = d.d[a];
                for b in 0..3 {
                    if used[b] {
                        hu[a][b] = h[a][b];
                    }
                }
            }
        }
        (st, (du, hu))
    }
}

/// K = G H Gᵀ + Σ_e g_e ∇²l_e + w_J ∇²vol of a tet whose energy is a function of
/// q = (l_1..l_6, J), in the edge vectors v_i = x_i − x0 (i = 1..3): `hq` = ∂²W/∂q²,
/// `ge` = ∂W/∂l_e, `v` the edge vectors, `vol` the rest volume, and `volume` = (the
/// cross products of [`volume_terms`], ∂W/∂J) when W depends on J. Returns P₉, with
/// K = Bᵀ P₉ B ([`expand_translation_free`]): W depends on the positions
/// through the v_i only, so the chain rule runs on 9 coordinates instead of 12 (the
/// products G H Gᵀ cost 9·7·16 multiply-adds instead of 12·7·19), and P₉ is what
/// the projection works on. Shared by the fibre and principal-stretch tangents.
pub(super) fn edge_hessian_from_q(
    hq: &SMatrix<f64, 7, 7>,
    ge: &[f64; 6],
    v: &[Vec3; 6],
    vol: f64,
    volume: Option<([Vec3; 3], f64)>,
) -> EdgeHessian {
    // ∇l_e = ±2 v_e on the edge's nodes other than node 0 (whose coordinates are
    // not among the v_i)
    let mut g = SMatrix::<f64, 9, 7>::zeros();
    for (e, &(tail, head)) in EDGES.iter().enumerate() {
        for (node, sign) in [(head, 2.0), (tail, -2.0)] {
            if node > 0 {
                for a in 0..3 {
                    g[(3 * (node - 1) + a, e)] = sign * v[e][a];
                }
            }
        }
    }
    if let Some((crosses, _)) = volume {
        // ∇J = ∇vol/Vol, ∂vol/∂v_c = the c-th cross product / 6
        let s = 1.0 / (6.0 * vol);
        for (c, cross) in crosses.iter().enumerate() {
            for a in 0..3 {
                g[(3 * c + a, 6)] = cross[a] * s;
            }
        }
    }
    let mut p = g * hq * g.transpose();
    // Σ_e g_e ∇²l_e: 2 g_e [[I, −I], [−I, I]] on the edge's (tail, head) blocks
    for (e, &(tail, head)) in EDGES.iter().enumerate() {
        let c = 2.0 * ge[e];
        for (n1, n2, sign) in [(tail, tail, c), (head, head, c), (tail, head, -c), (head, tail, -c)] {
            if n1 > 0 && n2 > 0 {
                for a in 0..3 {
                    p[(3 * (n1 - 1) + a, 3 * (n2 - 1) + a)] += sign;
                }
            }
        }
    }
    if let Some((_, wj)) = volume {
        // W = Vol·w with J = vol/Vol: the Vol cancels in ∂W/∂J · ∇²J;
        // ∂²vol/∂v_i∂v_j = −[v_k]×/6 for (i, j, k) cyclic, zero diagonal blocks
        let s = wj / 6.0;
        for i in 0..3 {
            let (j, m) = ((i + 1) % 3, (i + 2) % 3);
            let b = -v[m].cross_matrix() * s;
            for r in 0..3 {
                for c in 0..3 {
                    p[(3 * i + r, 3 * j + c)] += b[(r, c)];
                    p[(3 * j + c, 3 * i + r)] += b[(r, c)];
                }
            }
        }
    }
    p
}

/// The edge Hessian `p9` symmetrised and, when `project`, projected to positive
/// semi-definite as [`project_psd`] projects K = Bᵀ P₉ B (P₉ is K's K₉): kept when
/// semi-definite (the Cholesky test of [`is_semi_definite`]), else with its negative
/// eigenvalues set to zero. A non-finite `p9` is returned as it is (as
/// [`TetHessian::projected`] leaves a non-finite stiffness).
fn symmetric_edge_hessian(p9: &EdgeHessian, project: bool) -> EdgeHessian {
    if !p9.iter().all(|c| c.is_finite()) {
        return *p9;
    }
    let sym = (p9 + p9.transpose()) * 0.5;
    if !project || semi_definite_9(&sym) {
        return sym;
    }
    clamped(sym).unwrap_or(sym)
}

/// A tet stiffness computed as the Hessian P₉ in the edge vectors v_i = x_i − x0
/// ([`edge_hessian_from_q`]): the fibre and principal-stretch tangents, which have
/// no closed-form projection. [`TetHessian`] follows: K = Bᵀ P₉ B, projected on P₉,
/// and the blocks written straight from P₉ (no 12×12 matrix formed, symmetrised and
/// cut into blocks again).
pub(super) trait EdgeSpaceHessian: Send + Sync {
    /// The `k`-th tet's Hessian in its edge vectors at vertex positions `p`.
    fn edge_hessian(&self, k: usize, p: &[Vec3; 4]) -> EdgeHessian;
}

impl<T: EdgeSpaceHessian> TetHessian for T {
    fn hessian(&self, k: usize, p: &[Vec3; 4]) -> TetStiffness {
        expand_translation_free(&symmetric_edge_hessian(&self.edge_hessian(k, p), false))
    }

    fn projected(&self, k: usize, p: &[Vec3; 4]) -> TetStiffness {
        expand_translation_free(&symmetric_edge_hessian(&self.edge_hessian(k, p), true))
    }

    fn blocks_into(&self, k: usize, p: &[Vec3; 4], project: bool, out: &mut TetBlocks) {
        edge_hessian_blocks(&symmetric_edge_hessian(&self.edge_hessian(k, p), project), out);
    }
}

/// The blocks ([`BLOCK_PAIRS`]) of K = Bᵀ P₉ B for a symmetric edge Hessian `p9`,
/// written into `out` without forming the 12×12 K: blocks (a, b) of nodes 1..3 are
/// P₉'s, node 0's are minus the sums over the others (K's rows and columns sum to
/// zero: W does not change under a translation).
fn edge_hessian_blocks(p9: &EdgeHessian, out: &mut TetBlocks) {
    let blk = |i: usize, j: usize| -> Matrix3<f64> { p9.fixed_view::<3, 3>(3 * i, 3 * j).into_owned() };
    // column sums over the row blocks: c[j] = Σ_i P(i, j), the block (0, j + 1) negated
    let c: [Matrix3<f64>; 3] = std::array::from_fn(|j| blk(0, j) + blk(1, j) + blk(2, j));
    for (m, &(a, b)) in BLOCK_PAIRS.iter().enumerate() {
        out[m] = match (a, b) {
            (0, 0) => c[0] + c[1] + c[2],
            (0, b) => -c[b - 1],
            (a, b) => blk(a - 1, b - 1),
        };
    }
}

/// The stiffness of a link law's tets: the rest squared lengths of each tet's edges.
#[derive(Debug, Clone)]
pub struct LinkHessian<M: LinkLaw> {
    law: M,
    rest_l: Vec<[f64; 6]>,
}

impl<M: LinkLaw> TetHessian for LinkHessian<M> {
    fn hessian(&self, k: usize, p: &[Vec3; 4]) -> TetStiffness {
        let v = edge_vectors(p);
        let gl = length_gradients(&v);
        let mut out = TetStiffness::zeros();
        let mut g = [0.0; 6];
        for e in 0..6 {
            let (l, rl) = (v[e].norm_squared(), self.rest_l[k][e]);
            g[e] = self.law.dw(l, rl).1;
            let h = self.law.d2w(l, rl);
            for i in 0..12 {
                for j in 0..12 {
                    out[(i, j)] += h * gl[e][i] * gl[e][j];
                }
            }
        }
        add_length_curvature(&mut out, &g);
        out
    }
}

/// Projects a tet stiffness to positive semi-definite in the translation-free
/// coordinates: the stiffness of any law is invariant under translations, so
/// K = Bᵀ K₉ B exactly, with B: x ↦ (x_1 − x_0, x_2 − x_0, x_3 − x_0) and K₉ the
/// lower-right 9×9 block of K (the Hessian in the edge vectors from node 0); the
/// result is Bᵀ (K₉)₊ B, (K₉)₊ the eigen-projection (negative eigenvalues clamped
/// to 0). It is semi-definite, keeps the translations as null modes, and equals K
/// exactly when K is already semi-definite (K is semi-definite iff K₉ is); a 9×9
/// eigen-decomposition costs about 0.4 of a 12×12 one.
///
/// Most tets of a simulation near rest are semi-definite already: a Cholesky
/// factorisation of K₉ + εI (ε = 1e-12 × the largest diagonal entry, far above the
/// round-off of the rotational zero eigenvalues at rest) detects them at a small
/// fraction of the cost of the eigen-decomposition, and they are returned unchanged.
pub fn project_psd(k: &TetStiffness) -> TetStiffness {
    let sym = (k + k.transpose()) * 0.5;
    let k9: EdgeHessian = sym.fixed_view::<9, 9>(3, 3).into_owned();
    if semi_definite_9(&k9) {
        return sym;
    }
    match clamped(k9) {
        Some(p) => expand_translation_free(&p),
        None => sym,
    }
}

/// Whether the symmetric tet stiffness `sym` is semi-definite: a Cholesky
/// factorisation of its K₉ + εI succeeds (ε = 1e-12 × the largest diagonal entry,
/// far above the round-off of the rotational zero eigenvalues at rest).
pub(super) fn is_semi_definite(sym: &TetStiffness) -> bool {
    semi_definite_9(&sym.fixed_view::<9, 9>(3, 3).into_owned())
}

/// [`is_semi_definite`] on the edge Hessian K₉ itself.
fn semi_definite_9(k9: &EdgeHessian) -> bool {
    let shift = 1e-12 * k9.diagonal().amax();
    (k9 + EdgeHessian::identity() * shift).cholesky().is_some()
}

/// The symmetric `k9` with its negative eigenvalues set to zero, or `None` when it
/// has none.
fn clamped(k9: EdgeHessian) -> Option<EdgeHessian> {
    let eig = SymmetricEigen::new(k9);
    if eig.eigenvalues.iter().all(|&e| e >= 0.0) {
        return None;
    }
    let d = eig.eigenvalues.map(|e| e.max(0.0));
    let q = &eig.eigenvectors;
    Some(q * EdgeHessian::from_diagonal(&d) * q.transpose())
}

/// K = Bᵀ P₉ B for a 9×9 Hessian P₉ in the edge vectors from node 0: the rows and
/// columns of node 0 are minus the sums over nodes 1..3.
pub(super) fn expand_translation_free(p9: &EdgeHessian) -> TetStiffness {
    let mut out = TetStiffness::zeros();
    out.fixed_view_mut::<9, 9>(3, 3).copy_from(p9);
    for c in 3..12 {
        for r in 0..3 {
            let v = -(p9[(r, c - 3)] + p9[(r + 3, c - 3)] + p9[(r + 6, c - 3)]);
            out[(r, c)] = v;
            out[(c, r)] = v;
        }
    }
    for r in 0..3 {
        for c in 0..3 {
            out[(r, c)] = -(out[(r, 3 + c)] + out[(r, 6 + c)] + out[(r, 9 + c)]);
        }
    }
    out
}

/// The tangent operator of a law over (a region of) a mesh: per-tet stiffness
/// matrices from a [`TetHessian`], stored at the last update, and the node → tet
/// incidence used by the gathering product.
#[derive(Debug, Clone)]
pub struct TangentField<H: TetHessian> {
    kernel: H,
    ids: Vec<usize>,
    tets: Vec<[u32; 4]>,
    n_nodes: usize,
    project: bool,
    k: Vec<TetBlocks>,
    /// Incidences of node i: `inc[start[i]..start[i + 1]]`, as (tet, local vertex).
    start: Vec<usize>,
    inc: Vec<(u32, u8)>,
    /// Weight of each tet when the mesh's tets overlap (`crate::mesh::overlap`).
    weights: Option<Vec<f64>>,
}

/// The tets around each node of `tets` (over `n` nodes), in compressed rows: node i's
/// incidences are `inc[start[i]..start[i + 1]]`, each (tet index in `tets`, local
/// vertex), in tet order — what a node-ordered, thread-count-independent gather needs.
pub(super) fn node_incidence(tets: &[[u32; 4]], n: usize) -> (Vec<usize>, Vec<(u32, u8)>) {
    let mut start = vec![0usize; n + 1];
    for t in tets {
        for &i in t {
            start[i as usize + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut inc = vec![(0u32, 0u8); start[n]];
    for (k, t) in tets.iter().enumerate() {
        for (a, &i) in t.iter().enumerate() {
            inc[fill[i as usize]] = (k as u32, a as u8);
            fill[i as usize] += 1;
        }
    }
    (start, inc)
}

impl<H: TetHessian> TangentField<H> {
    pub(super) fn build(kernel: H, mesh: &TetMesh, ids: Vec<usize>, project: bool) -> Self {
        let tets: Vec<[u32; 4]> = ids.iter().map(|&t| mesh.tets()[t]).collect();
        let n = mesh.n_nodes();
        let (start, inc) = node_incidence(&tets, n);
        TangentField {
            kernel,
            k: vec![[Matrix3::zeros(); 10]; tets.len()],
            tets,
            n_nodes: n,
            project,
            start,
            inc,
            weights: mesh
                .overlap()
                .map(|_| ids.iter().map(|&t| mesh.tet_weight(t)).collect()),
            ids,
        }
    }
}

impl<M: InvariantLaw> TangentField<InvariantHessian<M>> {
    /// The tangent of invariant law `law` over the tets `tets` of `mesh` (all when
    /// `None`), with the same [`ForceOptions`] (J0 extension) as the force field.
    pub fn invariant(
        law: M,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: ForceOptions,
        project: bool,
    ) -> Result<Self> {
        opts.validate()?;
        let ids = selection(mesh.n_tets(), tets)?;
        let rest = ids.iter().map(|&t| RestTet::new(&mesh.tet_points(t))).collect();
        let dm_inv_t = ids
            .iter()
            .map(|&t| {
                let dm = rest_edge_matrix(&mesh.tet_points(t));
                dm.try_inverse().unwrap_or_else(Matrix3::zeros).transpose()
            })
            .collect();
        let kernel = InvariantHessian {
            law,
            opts,
            rest,
            dm_inv_t,
        };
        Ok(Self::build(kernel, mesh, ids, project))
    }
}

impl<M: LinkLaw> TangentField<LinkHessian<M>> {
    /// The tangent of link law `law` over the tets `tets` of `mesh` (all when `None`).
    pub fn link(law: M, mesh: &TetMesh, tets: Option<&[usize]>, project: bool) -> Result<Self> {
        let ids = selection(mesh.n_tets(), tets)?;
        let rest_l = ids
            .iter()
            .map(|&t| edge_vectors(&mesh.tet_points(t)).map(|v| v.norm_squared()))
            .collect();
        Ok(Self::build(LinkHessian { law, rest_l }, mesh, ids, project))
    }
}

impl<H: TetHessian> TangentOperator for TangentField<H> {
    fn n_nodes(&self) -> usize {
        self.n_nodes
    }
    fn tet_ids(&self) -> &[usize] {
        &self.ids
    }
    fn projects(&self) -> bool {
        self.project
    }
    fn tet_stiffness(&self, k: usize) -> TetStiffness {
        blocks_to_stiffness(&self.k[k])
    }
    fn tet_row(&self, k: usize, a: usize) -> [Matrix3<f64>; 4] {
        let m = &self.k[k];
        std::array::from_fn(|b| tet_block(m, a, b))
    }

    fn update(&mut self, x: &[Vec3]) -> Result<()> {
        check_sizes(self.n_nodes, x, None)?;
        let (kernel, tets, project, weights) = (&self.kernel, &self.tets, self.project, &self.weights);
        // the first tet with a non-finite entry, found in the same pass (its blocks
        // are still in L1 there; a second pass over all of them took ~8 % of an update)
        let first_bad = std::sync::atomic::AtomicUsize::new(usize::MAX);
        crate::parallel::for_each_chunk_mut(&mut self.k, UPDATE_CHUNK, true, &|c, chunk| {
            for (o, out) in chunk.iter_mut().enumerate() {
                let k = c * UPDATE_CHUNK + o;
                let p = crate::mesh::corners(x, &tets[k]);
                kernel.blocks_into(k, &p, project, out);
                // a weighted tet's stiffness is its weight times the unweighted one (the
                // projection commutes with a positive factor)
                if let Some(w) = weights {
                    for b in out.iter_mut() {
                        *b *= w[k];
                    }
                }
                if !all_finite(out) {
                    first_bad.fetch_min(k, std::sync::atomic::Ordering::Relaxed);
                }
            }
        });
        let k = first_bad.into_inner();
        if k != usize::MAX {
            return Err(HemlError::Numerical(format!(
                "non-finite tangent stiffness in tet {} (nodes {:?})",
                self.ids[k], self.tets[k]
            )));
        }
        Ok(())
    }

    fn add_product(&self, dx: &[Vec3], y: &mut [Vec3]) -> Result<()> {
        check_sizes(self.n_nodes, dx, Some(y))?;
        crate::parallel::for_each_chunk_mut(y, PRODUCT_CHUNK, true, &|c, chunk| {
            for (o, yi) in chunk.iter_mut().enumerate() {
                let i = c * PRODUCT_CHUNK + o;
                let mut acc = Vec3::zeros();
                for &(k, a) in &self.inc[self.start[i]..self.start[i + 1]] {
                    let (k, a) = (k as usize, a as usize);
                    for (b, &j) in self.tets[k].iter().enumerate() {
                        acc += tet_block(&self.k[k], a, b) * dx[j as usize];
                    }
                }
                *yi += acc;
            }
        });
        Ok(())
    }

    fn add_diagonal_blocks(&self, d: &mut [Matrix3<f64>]) -> Result<()> {
        if d.len() != self.n_nodes {
            return Err(HemlError::SizeMismatch {
                what: "diagonal blocks",
                got: d.len(),
                expected: self.n_nodes,
            });
        }
        for (k, t) in self.tets.iter().enumerate() {
            for (a, &i) in t.iter().enumerate() {
                d[i as usize] += tet_block(&self.k[k], a, a);
            }
        }
        Ok(())
    }
}
