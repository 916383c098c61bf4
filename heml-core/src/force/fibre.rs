//! Fibre-reinforced laws ([`FibreLaw`]) the HEML way: I1, I2 and J as for invariant
//! laws, plus per fibre family k
//!
//! * I4 = a·C·a = Σ_e l_e c4_e, **linear in the squared edge lengths**: with
//!   b = V⁻¹a, a·C_e·a = bᵀ D_e b (C_e = V⁻ᵀ D_e V⁻¹, DESIGN §1), six numbers per
//!   family precomputed per tet ([`FibreTet::new`]);
//! * I5 = a·C²·a = |C a|² = (D b)ᵀ B (D b) with B = V⁻¹V⁻ᵀ (recovered from `vtr`,
//!   [`b_from_vtr`]) and D = D(l): quadratic in l like I2, with
//!   ∂I5/∂l_e = 2 bᵀ D_e (B D b) and the constant Hessian 2 (D_e b)ᵀ B (D_f b).
//!
//! The link force of edge e is then −2 g_e v_e with
//! g_e = ∂W/∂l_e = Vol·Σ_v w_v ∂v/∂l_e over the variables v, plus the volume term
//! of J, exactly as for invariant laws. The P1 oracle ([`FibreP1Kernel`]) computes
//! the same law from F with P = ∂Ψ/∂F, ∂I4/∂F = 2F a⊗a and
//! ∂I5/∂F = 2F(Ca⊗a + a⊗Ca).
//!
//! The batch kernel ([`FibreKernel`]'s `batch`) runs the same steps over the
//! [`LANES`] tets of a batch at once, structure of arrays, like the invariant
//! laws' kernel: the law's `dw_fast` (branch-free `ln`/`exp`/`powf`, `max` as a
//! select) in a loop over lanes the compiler vectorises. The rest data per tet is
//! the volume, `vtr` and b_k (13 numbers); the kernel never forms c4_k: I4_k is
//! b_kᵀD(l)b_k with D(l) formed once for both families, and the fibre part of g_e
//! the edge entries of S = Σ_k ψ_k b_k b_kᵀ after the law, b_k read again (fewer
//! operations, and no c4_k held in registers through the law: about 4 % less time
//! per HGO tet, measured side by side). None of the 13 is derivable
//! from the others (b_k has one constraint, |V b_k| = 1, not worth a square root).
//! The sums I1, I4_k and g_e, the law's generated fast code and its exponentials
//! ([`super::fastmath::exp_fma`]) use fused multiply-adds (`f64::mul_add`: one
//! instruction in the FMA-enabled block drivers the kernel is inlined into, and
//! the same bits on every instruction set); measured ~10 % faster for HGO. The
//! driver prefetches the rest data of the batch two ahead
//! ([`super::assembly::prefetch`]): HGO's kernel had stalled a fifth of its time
//! on that first load.

// The kernels index fixed-size arrays in lock-step on purpose.
#![allow(clippy::needless_range_loop)]

use super::assembly::{LaneForces, LanePoints, LANES};
use super::field::{Formulation, TetField};
use super::heml::{invariant_terms, scatter_links, signed_j, volume_terms};
use super::kernel::TetKernel;
use super::lanes::{add_volume_forces, i2_lanes, link_forces, squared_lengths, volume_lanes};
use super::p1::cofactor;
use super::ForceOptions;
use crate::error::Result;
use crate::fibres::Fibres;
use crate::law::{i4_index, FibreDerivs, FibreLaw, FIBRE_VARS, HOISTED};
use crate::mesh::TetMesh;
use crate::rest::{b_from_vtr, d_of_lengths, edge_vectors, rest_edge_matrix, RestTet};
use crate::Vec3;
use nalgebra::Matrix3;
use std::sync::Arc;

/// uᵀ D_e w for the six edges e (D_e of DESIGN §1; symmetric in u and w): the
/// l-gradient of any bilinear form uᵀ D(l) w.
#[inline(always)]
pub(crate) fn edge_form(u: &[f64; 3], w: &[f64; 3]) -> [f64; 6] {
    let s01 = 0.5 * (u[0] * w[1] + u[1] * w[0]);
    let s12 = 0.5 * (u[1] * w[2] + u[2] * w[1]);
    let s02 = 0.5 * (u[0] * w[2] + u[2] * w[0]);
    edge_entries([u[0] * w[0], u[1] * w[1], u[2] * w[2]], s01, s12, s02)
}

/// [`edge_form`]`(b, b)` (a·C_e·a for b = V⁻¹a) without the symmetrisation:
/// ½(x + x) = x exactly, so the same bits for finite entries in three
/// multiplications and three additions fewer (per family and tet in the batch
/// kernel).
#[inline(always)]
pub(crate) fn edge_form_sq(b: &[f64; 3]) -> [f64; 6] {
    let (s01, s12, s02) = (b[0] * b[1], b[1] * b[2], b[0] * b[2]);
    edge_entries([b[0] * b[0], b[1] * b[1], b[2] * b[2]], s01, s12, s02)
}

/// The six edge entries of the symmetric form with diagonal `d` and off-diagonal
/// entries s01, s12, s02 (the one sum order both edge forms share).
#[inline(always)]
fn edge_entries(d: [f64; 3], s01: f64, s12: f64, s02: f64) -> [f64; 6] {
    [d[0] + s01 + s02, d[1] + s01 + s12, d[2] + s02 + s12, -s01, -s12, -s02]
}

#[inline(always)]
fn mat3_vec(m: &[[f64; 3]; 3], v: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

/// I5 = (D b)ᵀ B (D b) and its l-gradient 2·edge_form(b, B D b), for b = V⁻¹a.
#[inline(always)]
pub(crate) fn i5_terms(b: &[f64; 3], bm: &[[f64; 3]; 3], l: &[f64; 6]) -> (f64, [f64; 6]) {
    let db = mat3_vec(&d_of_lengths(l), b);
    let y = mat3_vec(bm, &db);
    let i5 = db[0] * y[0] + db[1] * y[1] + db[2] * y[2];
    (i5, edge_form(b, &y).map(|g| 2.0 * g))
}

/// D(l) = Σ_e l_e D_e of a batch (`rest::d_of_lengths`) with its off-diagonal
/// entries doubled, `[l0, l1, l2, l0 + l1 − l3, l1 + l2 − l4, l0 + l2 − l5]`
/// (`[entry][lane]`): then bᵀD(l)b = Σ_e (a·C_e·a) l_e = I4 for b = V⁻¹a, in
/// 9 operations per family instead of forming c4 = edge_form(b, b) (15) and its
/// dot product with l (6).
#[inline(always)]
pub(crate) fn doubled_d_of_lengths(len: &[[f64; LANES]; 6]) -> [[f64; LANES]; 6] {
    let mut dl = [[0.0; LANES]; 6];
    for l in 0..LANES {
        dl[0][l] = len[0][l];
        dl[1][l] = len[1][l];
        dl[2][l] = len[2][l];
        dl[3][l] = len[0][l] + len[1][l] - len[3][l];
        dl[4][l] = len[1][l] + len[2][l] - len[4][l];
        dl[5][l] = len[0][l] + len[2][l] - len[5][l];
    }
    dl
}

/// bᵀD b per lane for `dl` from [`doubled_d_of_lengths`]:
/// b0(b0 d00 + b1 e01 + b2 e02) + b1(b1 d11 + b2 e12) + b2 b2 d22.
#[inline(always)]
pub(crate) fn quadratic_form(b: &[[f64; LANES]; 3], dl: &[[f64; LANES]; 6]) -> [f64; LANES] {
    let mut out = [0.0; LANES];
    for l in 0..LANES {
        let (b0, b1, b2) = (b[0][l], b[1][l], b[2][l]);
        let x0 = b2.mul_add(dl[5][l], b1.mul_add(dl[3][l], b0 * dl[0][l]));
        let x1 = b2.mul_add(dl[4][l], b1 * dl[1][l]);
        let x2 = b2 * dl[2][l];
        out[l] = b2.mul_add(x2, b1.mul_add(x1, b0 * x0));
    }
    out
}

/// Σ_k ψ_k·(a_k·C_e·a_k) for the six edges e (`[edge][lane]`) of a batch, the
/// fibre part of 2·g_e, with ψ_k = 2·Vol·∂w/∂I4_k: the edge entries
/// ([`edge_entries`]) of the one symmetric matrix S = Σ_k ψ_k b_k b_kᵀ, both
/// families summed before the edge form is taken. b_k is read from the rest data
/// again here rather than c4_k being kept through the law (12 lane vectors that
/// did not fit in registers).
#[inline(always)]
pub(crate) fn fibre_gradient(
    b: &[[[f64; LANES]; 3]; 2],
    psi: &[[f64; LANES]; 2],
    families: usize,
) -> [[f64; LANES]; 6] {
    let mut g = [[0.0; LANES]; 6];
    for l in 0..LANES {
        // S's entries s00, s11, s22, s01, s12, s02
        let mut s = [0.0; 6];
        for k in 0..families {
            let (b0, b1, b2) = (b[k][0][l], b[k][1][l], b[k][2][l]);
            let (u0, u1, u2) = (psi[k][l] * b0, psi[k][l] * b1, psi[k][l] * b2);
            s[0] = u0.mul_add(b0, s[0]);
            s[1] = u1.mul_add(b1, s[1]);
            s[2] = u2.mul_add(b2, s[2]);
            s[3] = u0.mul_add(b1, s[3]);
            s[4] = u1.mul_add(b2, s[4]);
            s[5] = u0.mul_add(b2, s[5]);
        }
        let e = edge_entries([s[0], s[1], s[2]], s[3], s[4], s[5]);
        for i in 0..6 {
            g[i][l] = e[i];
        }
    }
    g
}

/// Rest data of one tet of a fibre law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FibreTet {
    /// Rest volume.
    pub vol: f64,
    /// tr(C_e), as for invariant laws.
    pub vtr: [f64; 6],
    /// a_k·C_e·a_k per family: I4_k = `c4[k]`·l.
    pub c4: [[f64; 6]; 2],
    /// b_k = V⁻¹a_k per family (for I5).
    pub b: [[f64; 3]; 2],
}

impl FibreTet {
    /// The rest data of a tet with rest corners `p` and unit fibre directions `a`.
    pub fn new(p: &[Vec3; 4], a: [Vec3; 2]) -> Self {
        let r = RestTet::new(p);
        let vinv = rest_edge_matrix(p).try_inverse().unwrap_or_else(Matrix3::zeros);
        let b = a.map(|a| {
            let v = vinv * a;
            [v.x, v.y, v.z]
        });
        FibreTet {
            vol: r.vol,
            vtr: r.vtr,
            c4: b.map(|b| edge_form_sq(&b)),
            b,
        }
    }
}

/// What a fibre tet's energy depends on, at the current edge vectors: the variables
/// q, their l-gradients (row 2, J, is zero: J enters through the volume term), the
/// law's derivatives on the force kernel's branch, J's cross products.
pub(crate) struct FibreState {
    pub q: [f64; FIBRE_VARS],
    pub grads: [[f64; 6]; FIBRE_VARS],
    pub d: FibreDerivs,
    pub crosses: [Vec3; 3],
    pub extended: bool,
}

impl FibreState {
    /// The state of tet `r` (law `M`) at edge vectors `v`.
    #[inline(always)]
    pub(crate) fn new<M: FibreLaw>(law: &M, opts: &ForceOptions, r: &FibreTet, v: &[Vec3; 6]) -> Self {
        let l = v.map(|e| e.norm_squared());
        let (i1, i2, ml) = invariant_terms(&r.vtr, &l, M::USES_I2);
        let (j, crosses) = if M::USES_J {
            volume_terms(v, r.vol)
        } else {
            (1.0, [Vec3::zeros(); 3])
        };
        let mut q = [i1, i2, j, 1.0, 1.0, 1.0, 1.0];
        let mut grads = [[0.0; 6]; FIBRE_VARS];
        grads[0] = r.vtr;
        if M::USES_I2 {
            grads[1] = std::array::from_fn(|e| i1 * r.vtr[e] - ml[e]);
        }
        let bm = b_from_vtr(&r.vtr);
        for k in 0..M::FAMILIES {
            let i = i4_index(k);
            q[i] = (0..6).map(|e| r.c4[k][e] * l[e]).sum();
            grads[i] = r.c4[k];
            if M::USES_I5 {
                let (i5, g5) = i5_terms(&r.b[k], &bm, &l);
                q[i + 1] = i5;
                grads[i + 1] = g5;
            }
        }
        let extended = opts.extend(M::INVERSION_FIX, j);
        let d = if extended { law.dw_ext(&q, opts.j0) } else { law.dw(&q) };
        FibreState {
            q,
            grads,
            d,
            crosses,
            extended,
        }
    }

    /// g_e = ∂W/∂l_e of a tet of rest volume `vol`.
    #[inline(always)]
    pub(crate) fn link_coefficients(&self, vol: f64) -> [f64; 6] {
        std::array::from_fn(|e| {
            let mut s = 0.0;
            for (a, g) in self.grads.iter().enumerate() {
                if a != 2 {
                    s += self.d.d[a] * g[e];
                }
            }
            vol * s
        })
    }
}

/// Internal forces of a fibre law `M` over (a region of) a mesh, the HEML way.
pub type FibreField<M> = TetField<FibreKernel<M>>;

/// The HEML formulation of a fibre law: law, options and the fibre directions of
/// every tet of the mesh.
#[derive(Debug, Clone)]
pub struct FibreKernel<M: FibreLaw> {
    law: M,
    /// The law's parametric values ([`FibreLaw::hoisted`]), once for all batches.
    hoisted: [f64; HOISTED],
    opts: ForceOptions,
    fibres: Arc<Fibres>,
}

impl<M: FibreLaw> Formulation for FibreKernel<M> {}

/// Rest data of `LANES` tets, structure of arrays: volume, `vtr` and b_k = V⁻¹a_k
/// (the plain kernel's c4_k of [`FibreTet`] are formed from b_k by [`FibreBatch::tet`]).
#[derive(Debug, Clone, Copy)]
pub struct FibreBatch {
    vol: [f64; LANES],
    vtr: [[f64; LANES]; 6],
    b: [[[f64; LANES]; 3]; 2],
}

impl FibreBatch {
    /// The rest data of lane `l` as one tet (c4 formed exactly as [`FibreTet::new`]
    /// does, so the plain kernel sees the same numbers).
    #[inline(always)]
    fn tet(&self, l: usize) -> FibreTet {
        let b: [[f64; 3]; 2] = std::array::from_fn(|k| std::array::from_fn(|i| self.b[k][i][l]));
        FibreTet {
            vol: self.vol[l],
            vtr: std::array::from_fn(|e| self.vtr[e][l]),
            c4: b.map(|b| edge_form_sq(&b)),
            b,
        }
    }
}

impl<M: FibreLaw> FibreField<M> {
    /// The field of `law` with fibres `fibres` (covering all of `mesh`) over the tets
    /// `tets` of `mesh` (all when `None`), in Morton order.
    pub fn on_tets(
        law: M,
        fibres: Arc<Fibres>,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: ForceOptions,
    ) -> Result<Self> {
        fibres.check(M::NAME, mesh.n_tets(), M::FAMILIES)?;
        let hoisted = law.hoisted();
        let kernel = FibreKernel {
            law,
            hoisted,
            opts,
            fibres,
        };
        TetField::build(kernel, mesh, tets, opts, true)
    }

    /// The law.
    pub fn law(&self) -> &M {
        &self.kernel().law
    }
}

impl<M: FibreLaw> FibreKernel<M> {
    /// Energy, J and nodal forces of a tet with rest data `r` at corners `p`.
    #[inline(always)]
    fn eval(&self, r: &FibreTet, p: &[Vec3; 4]) -> (f64, f64, [Vec3; 4]) {
        let v = edge_vectors(p);
        let s = FibreState::new(&self.law, &self.opts, r, &v);
        let g = s.link_coefficients(r.vol);
        let mut f = [Vec3::zeros(); 4];
        scatter_links(&mut f, &g, &v);
        if M::USES_J {
            let c = s.d.d[2] / 6.0;
            for a in 0..3 {
                f[a + 1] -= s.crosses[a] * c;
                f[0] += s.crosses[a] * c;
            }
        }
        (r.vol * s.d.w, s.q[2], f)
    }
}

impl<M: FibreLaw> FibreKernel<M> {
    /// w and ∂w/∂q (`[var][lane]`) of the law at the lanes' variables `q`: the
    /// fast kernel in a branch-free loop (vectorised) when no lane is below J0,
    /// else each lane picks its own, as the invariant kernels' `law_lanes!`.
    #[inline(always)]
    fn law_lanes(&self, q: &[[f64; LANES]; FIBRE_VARS]) -> ([f64; LANES], [[f64; LANES]; FIBRE_VARS]) {
        let (mut w, mut d) = ([0.0; LANES], [[0.0; LANES]; FIBRE_VARS]);
        let j0 = self.opts.j0;
        let fix = M::INVERSION_FIX && self.opts.inversion_fix;
        let mut any_ext = false;
        if fix {
            for l in 0..LANES {
                any_ext |= q[2][l] < j0;
            }
        }
        let lane = |l: usize| -> [f64; FIBRE_VARS] { std::array::from_fn(|a| q[a][l]) };
        if any_ext {
            for l in 0..LANES {
                let r = if q[2][l] < j0 {
                    self.law.dw_ext_fast(&lane(l), j0)
                } else {
                    self.law.dw_fast_hoisted(&self.hoisted, &lane(l))
                };
                w[l] = r.w;
                for a in 0..FIBRE_VARS {
                    d[a][l] = r.d[a];
                }
            }
        } else {
            for l in 0..LANES {
                let r = self.law.dw_fast_hoisted(&self.hoisted, &lane(l));
                w[l] = r.w;
                for a in 0..FIBRE_VARS {
                    d[a][l] = r.d[a];
                }
            }
        }
        (w, d)
    }
}

/// A batch kernel made of a plain one: `tet(lane, corners)` gives each lane's
/// energy and corner forces, stored in the batch's layout.
#[inline(always)]
fn per_lane(
    p: &LanePoints,
    f: &mut LaneForces,
    en: &mut [f64; LANES],
    mut tet: impl FnMut(usize, &[Vec3; 4]) -> (f64, [Vec3; 4]),
) {
    for l in 0..LANES {
        let pts: [Vec3; 4] = std::array::from_fn(|a| Vec3::new(p[a][0][l], p[a][1][l], p[a][2][l]));
        let (e, fl) = tet(l, &pts);
        for a in 0..4 {
            for c in 0..3 {
                f[a][c][l] = fl[a][c];
            }
        }
        en[l] = e;
    }
}

/// The directions of the families of tet `t` (the first repeated for one family).
fn tet_dirs(fibres: &Fibres, t: usize) -> [Vec3; 2] {
    [fibres.dir(t, 0), fibres.dir(t, 1)]
}

impl<M: FibreLaw> TetKernel for FibreKernel<M> {
    type Batch = FibreBatch;
    const SKIPS_ENERGY: bool = true;

    const PAD: FibreBatch = FibreBatch {
        vol: [1.0; LANES],
        vtr: [[0.0; LANES]; 6],
        b: [[[0.0; LANES]; 3]; 2],
    };

    fn store_rest(&mut self, mesh: &TetMesh, t: usize, _k: usize, batch: &mut FibreBatch, lane: usize) {
        let r = FibreTet::new(&mesh.tet_points(t), tet_dirs(&self.fibres, t));
        batch.vol[lane] = r.vol;
        for e in 0..6 {
            batch.vtr[e][lane] = r.vtr[e];
        }
        for k in 0..2 {
            for i in 0..3 {
                batch.b[k][i][lane] = r.b[k][i];
            }
        }
    }

    #[inline(always)]
    fn tet(&self, rest: &FibreBatch, lane: usize, p: &[Vec3; 4], mut add: impl FnMut(usize, Vec3)) -> f64 {
        let (e, _, f) = self.eval(&rest.tet(lane), p);
        for (a, fa) in f.into_iter().enumerate() {
            add(a, fa);
        }
        e
    }

    fn tet_state(&self, rest: &FibreBatch, lane: usize, _k: usize, p: &[Vec3; 4]) -> (f64, f64) {
        let r = rest.tet(lane);
        let (e, j, _) = self.eval(&r, p);
        let j = if M::USES_J { j } else { signed_j(p, r.vol) };
        (j, e / r.vol)
    }

    /// The plain kernel's steps over the lanes (see the module doc); equal to it to
    /// round-off (the fast `ln`/`exp`/`powf`, sums in another order).
    #[inline(always)]
    fn batch(&self, r: &FibreBatch, p: &LanePoints, f: &mut LaneForces, en: &mut [f64; LANES]) {
        const L: usize = LANES;
        // J first, as in the invariant kernel: the law's longest chain starts from it
        let (j, cr) = if M::USES_J {
            volume_lanes(p, &r.vol)
        } else {
            ([1.0; L], [[[0.0; L]; 3]; 3])
        };
        let len = squared_lengths(p);
        // q[var][lane]; the variables of absent families stay 1
        let mut q = [[1.0; L]; FIBRE_VARS];
        q[2] = j;
        let mut i1 = [0.0; L];
        for e in 0..6 {
            for l in 0..L {
                i1[l] = r.vtr[e][l].mul_add(len[e][l], i1[l]);
            }
        }
        q[0] = i1;
        let (i2, ml) = if M::USES_I2 {
            i2_lanes(&r.vtr, &len, &i1)
        } else {
            ([0.0; L], [[0.0; L]; 6])
        };
        q[1] = i2;
        // I4_k = b_kᵀ D(l) b_k with D(l) = Σ_e l_e D_e (`rest::d_of_lengths`), its
        // off-diagonal entries doubled, formed once for both families: no c4_k held
        // across the law (see `fibre_gradient`); I5_k and its l-gradient
        let dl = doubled_d_of_lengths(&len);
        let mut g5 = [[[0.0; L]; 6]; 2];
        for k in 0..M::FAMILIES {
            let i = i4_index(k);
            q[i] = quadratic_form(&r.b[k], &dl);
            if M::USES_I5 {
                for l in 0..L {
                    let b = [r.b[k][0][l], r.b[k][1][l], r.b[k][2][l]];
                    let vtr: [f64; 6] = std::array::from_fn(|e| r.vtr[e][l]);
                    let le: [f64; 6] = std::array::from_fn(|e| len[e][l]);
                    let (i5, g) = i5_terms(&b, &b_from_vtr(&vtr), &le);
                    q[i + 1][l] = i5;
                    for e in 0..6 {
                        g5[k][e][l] = g[e];
                    }
                }
            }
        }
        let (w, mut d) = self.law_lanes(&q);
        // 2·g_e = 2·Vol·Σ_v w_v ∂v/∂l_e, with the per-tet factors 2·Vol·w_v formed
        // once (as the invariant kernel does); w_J stays as it is (volume term)
        for l in 0..L {
            let s = 2.0 * r.vol[l];
            for a in [0, 1, 3, 4, 5, 6] {
                d[a][l] *= s;
            }
        }
        let psi: [[f64; L]; 2] = std::array::from_fn(|k| d[i4_index(k)]);
        let gf = fibre_gradient(&r.b, &psi, M::FAMILIES);
        let mut g2 = [[0.0; L]; 6];
        for e in 0..6 {
            for l in 0..L {
                let mut ge = d[0][l].mul_add(r.vtr[e][l], gf[e][l]);
                if M::USES_I2 {
                    ge = d[1][l].mul_add(i1[l].mul_add(r.vtr[e][l], -ml[e][l]), ge);
                }
                if M::USES_I5 {
                    for k in 0..M::FAMILIES {
                        ge = d[i4_index(k) + 1][l].mul_add(g5[k][e][l], ge);
                    }
                }
                g2[e][l] = ge;
            }
        }
        link_forces(p, &g2, f);
        if M::USES_J {
            add_volume_forces(&cr, &d[2], f);
        }
        for l in 0..L {
            en[l] = r.vol[l] * w[l];
        }
    }

    fn side_bytes(&self) -> usize {
        std::mem::size_of_val(&*self.fibres) + self.fibres.n_tets() * std::mem::size_of::<[Vec3; 2]>()
    }
}

/// The variables q = (I1, I2, J, I4_1, I5_1, I4_2, I5_2) of a fibre law at the
/// deformation gradient `f` with fibres `a` (families beyond `families` stay 1).
pub fn fibre_invariants(f: &Matrix3<f64>, a: &[Vec3; 2], families: usize) -> [f64; FIBRE_VARS] {
    let c = f.transpose() * f;
    let i1 = c.trace();
    let mut q = [
        i1,
        0.5 * (i1 * i1 - (c * c).trace()),
        f.determinant(),
        1.0,
        1.0,
        1.0,
        1.0,
    ];
    for k in 0..families {
        let ca = c * a[k];
        q[i4_index(k)] = a[k].dot(&ca);
        q[i4_index(k) + 1] = ca.norm_squared();
    }
    q
}

/// Energy density and first Piola–Kirchhoff stress of fibre law `law` at `f` with
/// fibres `a`: P = 2w1 F + 2w2 (I1 F − F C) + wJ cof F + Σ_k (2w4_k F a⊗a +
/// 2w5_k F (Ca⊗a + a⊗Ca)), with the J0 extension as in the HEML path.
pub fn fibre_energy_and_piola<M: FibreLaw>(
    law: &M,
    f: &Matrix3<f64>,
    a: &[Vec3; 2],
    opts: &ForceOptions,
) -> (f64, Matrix3<f64>) {
    let q = fibre_invariants(f, a, M::FAMILIES);
    let d = if opts.extend(M::INVERSION_FIX, q[2]) {
        law.dw_ext(&q, opts.j0)
    } else {
        law.dw(&q)
    };
    let c = f.transpose() * f;
    let mut p = f * (2.0 * d.d[0]) + (f * q[0] - f * c) * (2.0 * d.d[1]) + cofactor(f) * d.d[2];
    for k in 0..M::FAMILIES {
        let i = i4_index(k);
        let ca = c * a[k];
        p += f * (a[k] * a[k].transpose()) * (2.0 * d.d[i])
            + f * (ca * a[k].transpose() + a[k] * ca.transpose()) * (2.0 * d.d[i + 1]);
    }
    (d.w, p)
}

/// The standard P1 formulation of a fibre law (the oracle for [`FibreField`]).
#[derive(Debug, Clone)]
pub struct FibreP1Kernel<M: FibreLaw> {
    law: M,
    opts: ForceOptions,
    fibres: Arc<Fibres>,
}

impl<M: FibreLaw> Formulation for FibreP1Kernel<M> {}

/// Internal forces of a fibre law computed the standard P1 way.
pub type FibreP1Field<M> = TetField<FibreP1Kernel<M>>;

/// Rest data of `LANES` tets for the P1 oracle: volume, Dm⁻¹ and the fibres.
#[derive(Debug, Clone, Copy)]
pub struct FibreP1Batch {
    tets: [(f64, Matrix3<f64>, [Vec3; 2]); LANES],
}

impl<M: FibreLaw> FibreP1Field<M> {
    /// The P1 field of `law` with fibres `fibres` over the tets `tets` of `mesh`.
    pub fn on_tets(
        law: M,
        fibres: Arc<Fibres>,
        mesh: &TetMesh,
        tets: Option<&[usize]>,
        opts: ForceOptions,
    ) -> Result<Self> {
        fibres.check(M::NAME, mesh.n_tets(), M::FAMILIES)?;
        TetField::build(FibreP1Kernel { law, opts, fibres }, mesh, tets, opts, true)
    }
}

impl<M: FibreLaw> FibreP1Kernel<M> {
    fn eval(&self, r: &(f64, Matrix3<f64>, [Vec3; 2]), p: &[Vec3; 4]) -> (f64, Matrix3<f64>, f64) {
        let (vol, dm_inv, a) = r;
        let f = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]) * dm_inv;
        let (w, pk) = fibre_energy_and_piola(&self.law, &f, a, &self.opts);
        (vol * w, -*vol * pk * dm_inv.transpose(), f.determinant())
    }
}

impl<M: FibreLaw> TetKernel for FibreP1Kernel<M> {
    type Batch = FibreP1Batch;

    const PAD: FibreP1Batch = FibreP1Batch {
        tets: [(
            1.0,
            Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
            [Vec3::new(1.0, 0.0, 0.0); 2],
        ); LANES],
    };
    const PLAIN_ENERGY: bool = true;

    fn store_rest(&mut self, mesh: &TetMesh, t: usize, _k: usize, batch: &mut FibreP1Batch, lane: usize) {
        let dm = rest_edge_matrix(&mesh.tet_points(t));
        batch.tets[lane] = (
            dm.determinant() / 6.0,
            dm.try_inverse().unwrap_or_else(Matrix3::zeros),
            tet_dirs(&self.fibres, t),
        );
    }

    fn tet(&self, rest: &FibreP1Batch, lane: usize, p: &[Vec3; 4], mut add: impl FnMut(usize, Vec3)) -> f64 {
        let (e, h, _) = self.eval(&rest.tets[lane], p);
        for a in 0..3 {
            let fa: Vec3 = h.column(a).into();
            add(a + 1, fa);
            add(0, -fa);
        }
        e
    }

    fn tet_state(&self, rest: &FibreP1Batch, lane: usize, _k: usize, p: &[Vec3; 4]) -> (f64, f64) {
        let (e, _, j) = self.eval(&rest.tets[lane], p);
        (j, e / rest.tets[lane].0)
    }

    fn batch(&self, r: &FibreP1Batch, p: &LanePoints, f: &mut LaneForces, en: &mut [f64; LANES]) {
        per_lane(p, f, en, |l, pts| {
            let mut fl = [Vec3::zeros(); 4];
            let e = self.tet(r, l, pts, |a, fa| fl[a] += fa);
            (e, fl)
        });
    }
}
