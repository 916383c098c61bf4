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
//! (detected by a Cholesky factorisation). Invariant laws are isotropic, so their
//! indefinite tets are projected through the closed-form eigensystem of ∂²Ψ/∂F²
//! (from the 3×3 SVD of F, `force/eigensystem.rs`: several times cheaper than the
//! 9×9 eigen-decomposition); link laws, and a tet whose SVD fails, through the
//! numerical eigen-decomposition of K₉ ([`project_psd`]). The implicit integrators
//! project by default.
//!
//! The per-tet matrices are computed once per [`TangentOperator::update`] (in
//! parallel) and stored (144 numbers per tet); the product y += K·dx gathers, per
//! node, the rows of its incident tets, in parallel over nodes: race-free and
//! bit-for-bit deterministic for any thread count.

// The 12×12 assembly indexes node blocks and coordinates in lock-step; iterator
// chains over several arrays would obscure the formulas.
#![allow(clippy::needless_range_loop)]

use super::eigensystem::{edge_hessian, eigensystem, EdgeHessian};
use super::field::{check_sizes, selection};
use super::heml::{invariant_terms, volume_terms};
use super::ForceOptions;
use crate::error::{HemlError, Result};
use crate::law::{InvariantLaw, LinkLaw};
use crate::mesh::TetMesh;
use crate::rest::{edge_vectors, mtr_index, rest_edge_matrix, RestTet, EDGES};
use crate::Vec3;
use nalgebra::{Matrix3, SMatrix, SymmetricEigen};
use rayon::prelude::*;

/// A 12×12 tet stiffness, rows and columns ordered (node 0 x, y, z, node 1 x, …).
pub type TetStiffness = SMatrix<f64, 12, 12>;

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
    fn tet_stiffness(&self, k: usize) -> &TetStiffness;
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

/// Adds c·∇²vol, vol = v1·(v2×v3)/6 with v_i = x_i − x0: in the v_i the Hessian has
/// zero diagonal blocks and ∂²vol/∂v_i∂v_j = −[v_k]×/6 for (i, j, k) cyclic; the
/// node-0 rows and columns follow from v_i = x_i − x0.
pub(super) fn add_volume_curvature(k: &mut TetStiffness, v: &[Vec3; 6], c: f64) {
    let s = c / 6.0;
    // hv[i][j]: the 3×3 block (v_{i+1}, v_{j+1})
    let mut hv = [[Matrix3::zeros(); 3]; 3];
    for i in 0..3 {
        let (j, m) = ((i + 1) % 3, (i + 2) % 3);
        let b = -v[m].cross_matrix() * s;
        hv[i][j] = b;
        hv[j][i] = b.transpose();
    }
    // x-blocks: node a ↔ coefficient of x_a in v_i (−1 for node 0, δ_ai otherwise)
    let coef = |i: usize, a: usize| -> f64 {
        if a == 0 {
            -1.0
        } else if a == i + 1 {
            1.0
        } else {
            0.0
        }
    };
    for a in 0..4 {
        for b in 0..4 {
            let mut blk = Matrix3::zeros();
            for i in 0..3 {
                for j in 0..3 {
                    let c = coef(i, a) * coef(j, b);
                    if c != 0.0 {
                        blk += hv[i][j] * c;
                    }
                }
            }
            for r in 0..3 {
                for q in 0..3 {
                    k[(3 * a + r, 3 * b + q)] += blk[(r, q)];
                }
            }
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
        self.hessian_and_derivatives(k, p).0
    }

    /// Semi-definite tets (a Cholesky factorisation of K₉ + εI succeeds, as in
    /// [`project_psd`]) are returned unchanged (symmetrised); the others through
    /// the analytic eigensystem of ∂²Ψ/∂F² with its negative eigenvalues clamped.
    fn projected(&self, k: usize, p: &[Vec3; 4]) -> TetStiffness {
        let (h, (d, d2)) = self.hessian_and_derivatives(k, p);
        if !h.iter().all(|c| c.is_finite()) {
            return h;
        }
        let sym = (h + h.transpose()) * 0.5;
        if is_semi_definite(&sym) {
            return sym;
        }
        let v = edge_vectors(p);
        let f = Matrix3::from_columns(&[v[0], v[1], v[2]]) * self.dm_inv_t[k].transpose();
        match eigensystem(&f, d, d2) {
            Some(modes) => expand_translation_free(&edge_hessian(&modes, &self.dm_inv_t[k], self.rest[k].vol, true)),
            None => project_psd(&h),
        }
    }
}

impl<M: InvariantLaw> InvariantHessian<M> {
    /// The exact stiffness of the `k`-th tet and the law's derivatives there.
    fn hessian_and_derivatives(&self, k: usize, p: &[Vec3; 4]) -> (TetStiffness, LawDerivatives) {
        let r = &self.rest[k];
        let (vtr, vol) = (r.vtr, r.vol);
        let v = edge_vectors(p);
        let l = v.map(|e| e.norm_squared());
        // the force kernel's inputs: I2 = 0 for laws without I2, J = 1 without J
        let (i1, i2, ml) = invariant_terms(&vtr, &l, M::USES_I2);
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
        let [w1, w2, wj] = d.d;
        // a_e = ∂I2/∂l_e
        let a: [f64; 6] = std::array::from_fn(|e| i1 * vtr[e] - ml[e]);
        // H = ∂²W/∂q², q = (l, J)
        let mut hq = SMatrix::<f64, 7, 7>::zeros();
        for e in 0..6 {
            for f in 0..6 {
                let mut s = h[0][0] * vtr[e] * vtr[f];
                if M::USES_I2 {
                    s += h[0][1] * (vtr[e] * a[f] + a[e] * vtr[f])
                        + h[1][1] * a[e] * a[f]
                        + w2 * (vtr[e] * vtr[f] - r.mtr[mtr_index(e, f)]);
                }
                hq[(e, f)] = vol * s;
            }
            if M::USES_J {
                let mut s = h[0][2] * vtr[e];
                if M::USES_I2 {
                    s += h[1][2] * a[e];
                }
                hq[(e, 6)] = vol * s;
                hq[(6, e)] = vol * s;
            }
        }
        if M::USES_J {
            hq[(6, 6)] = vol * h[2][2];
        }
        let ge: [f64; 6] = std::array::from_fn(|e| {
            let mut s = w1 * vtr[e];
            if M::USES_I2 {
                s += w2 * a[e];
            }
            vol * s
        });
        let vol_terms = M::USES_J.then_some((crosses, wj));
        let k = stiffness_from_q(&hq, &ge, &v, vol, vol_terms);
        let used = [true, M::USES_I2, M::USES_J];
        let d = std::array::from_fn(|a| if used[a] { d.d[a] } else { 0.0 });
        let h = std::array::from_fn(|a| std::array::from_fn(|b| if used[a] && used[b] { h[a][b] } else { 0.0 }));
        (k, (d, h))
    }
}

/// K = G H Gᵀ + Σ_e g_e ∇²l_e + w_J ∇²vol of a tet whose energy is a function of
/// q = (l_1..l_6, J): `hq` = ∂²W/∂q², `ge` = ∂W/∂l_e, `v` the edge vectors, `vol`
/// the rest volume, and `volume` = (the cross products of [`volume_terms`], ∂W/∂J)
/// when W depends on J. Shared by the invariant and principal-stretch tangents.
pub(super) fn stiffness_from_q(
    hq: &SMatrix<f64, 7, 7>,
    ge: &[f64; 6],
    v: &[Vec3; 6],
    vol: f64,
    volume: Option<([Vec3; 3], f64)>,
) -> TetStiffness {
    let gl = length_gradients(v);
    let mut g = SMatrix::<f64, 12, 7>::zeros();
    for e in 0..6 {
        for i in 0..12 {
            g[(i, e)] = gl[e][i];
        }
    }
    if let Some((crosses, _)) = volume {
        // ∇J = ∇vol/Vol: crosses/6 on nodes 1..3, minus their sum on node 0
        let s = 1.0 / (6.0 * vol);
        for (c, cross) in crosses.iter().enumerate() {
            for ax in 0..3 {
                g[(3 * (c + 1) + ax, 6)] = cross[ax] * s;
                g[(ax, 6)] -= cross[ax] * s;
            }
        }
    }
    let mut k = g * hq * g.transpose();
    add_length_curvature(&mut k, ge);
    if let Some((_, wj)) = volume {
        // W = Vol·w with J = vol/Vol: the Vol cancels in ∂W/∂J · ∇²J
        add_volume_curvature(&mut k, v, wj);
    }
    k
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
    if is_semi_definite(&sym) {
        return sym;
    }
    let k9: SMatrix<f64, 9, 9> = sym.fixed_view::<9, 9>(3, 3).into_owned();
    let eig = SymmetricEigen::new(k9);
    if eig.eigenvalues.iter().all(|&e| e >= 0.0) {
        return sym;
    }
    let d = eig.eigenvalues.map(|e| e.max(0.0));
    let q = &eig.eigenvectors;
    expand_translation_free(&(q * SMatrix::<f64, 9, 9>::from_diagonal(&d) * q.transpose()))
}

/// Whether the symmetric tet stiffness `sym` is semi-definite: a Cholesky
/// factorisation of its K₉ + εI succeeds (ε = 1e-12 × the largest diagonal entry,
/// far above the round-off of the rotational zero eigenvalues at rest).
fn is_semi_definite(sym: &TetStiffness) -> bool {
    let k9: SMatrix<f64, 9, 9> = sym.fixed_view::<9, 9>(3, 3).into_owned();
    let shift = 1e-12 * k9.diagonal().amax();
    (k9 + SMatrix::<f64, 9, 9>::identity() * shift).cholesky().is_some()
}

/// K = Bᵀ P₉ B for a 9×9 Hessian P₉ in the edge vectors from node 0: the rows and
/// columns of node 0 are minus the sums over nodes 1..3.
fn expand_translation_free(p9: &EdgeHessian) -> TetStiffness {
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
    k: Vec<TetStiffness>,
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
            k: vec![TetStiffness::zeros(); tets.len()],
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
    fn tet_stiffness(&self, k: usize) -> &TetStiffness {
        &self.k[k]
    }

    fn update(&mut self, x: &[Vec3]) -> Result<()> {
        check_sizes(self.n_nodes, x, None)?;
        let (kernel, tets, project, weights) = (&self.kernel, &self.tets, self.project, &self.weights);
        self.k.par_iter_mut().enumerate().with_min_len(64).for_each(|(k, out)| {
            let p = tets[k].map(|i| x[i as usize]);
            *out = if project {
                kernel.projected(k, &p)
            } else {
                kernel.hessian(k, &p)
            };
            if let Some(w) = weights {
                *out *= w[k];
            }
        });
        if let Some(k) = self.k.iter().position(|m| !m.iter().all(|c| c.is_finite())) {
            return Err(HemlError::Numerical(format!(
                "non-finite tangent stiffness in tet {} (nodes {:?})",
                self.ids[k], self.tets[k]
            )));
        }
        Ok(())
    }

    fn add_product(&self, dx: &[Vec3], y: &mut [Vec3]) -> Result<()> {
        check_sizes(self.n_nodes, dx, Some(y))?;
        // K is symmetric, so row 3a + r of a tet's K is its column 3a + r: 12
        // contiguous numbers in nalgebra's column-major storage (a dot product that
        // vectorises, where the row would be strided)
        y.par_iter_mut().enumerate().with_min_len(256).for_each(|(i, yi)| {
            let mut acc = [0.0; 3];
            for &(k, a) in &self.inc[self.start[i]..self.start[i + 1]] {
                let (k, a) = (k as usize, a as usize);
                let t = &self.tets[k];
                let mut d = [0.0; 12];
                for b in 0..4 {
                    let v = dx[t[b] as usize];
                    d[3 * b..3 * b + 3].copy_from_slice(v.as_slice());
                }
                let m = self.k[k].as_slice();
                for (r, out) in acc.iter_mut().enumerate() {
                    let col = &m[12 * (3 * a + r)..12 * (3 * a + r) + 12];
                    *out += col.iter().zip(&d).map(|(p, q)| p * q).sum::<f64>();
                }
            }
            *yi += Vec3::from(acc);
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
                d[i as usize] += self.k[k].fixed_view::<3, 3>(3 * a, 3 * a);
            }
        }
        Ok(())
    }
}
