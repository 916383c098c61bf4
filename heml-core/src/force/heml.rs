//! The HEML force field: per tet, invariants from the six squared edge lengths,
//! forces along the links plus (for laws using J) the volume term (DESIGN §1).
//!
//! Three evaluation paths compute the same forces (see [`super::Assembly`]):
//! the plain serial kernel [`HemlField::add_forces_reference`] (one tet at a time,
//! the law's `dw`, the definition the others are tested against), a serial batched
//! kernel, and the default parallel blocked kernel (`ElasticForces::add_forces`).

// The kernels index fixed-size lane arrays in lock-step on purpose (it is what
// vectorises); iterator chains over several arrays would obscure that.
#![allow(clippy::needless_range_loop)]

use super::assembly::{LaneForces, LanePoints, LANES};
use super::field::{Formulation, TetField};
use super::kernel::TetKernel;
use super::ForceOptions;
use crate::error::Result;
use crate::law::InvariantLaw;
use crate::mesh::TetMesh;
use crate::rest::{edge_vectors, i2_terms, RestTet};
use crate::Vec3;

/// Rest data of `LANES` consecutive tets, structure of arrays.
#[derive(Debug, Clone, Copy)]
pub struct HemlBatch {
    vol: [f64; LANES],
    vtr: [[f64; LANES]; 6],
}

/// Internal forces of an invariant law `M` over (a region of) a mesh, the HEML way.
///
/// Monomorphised per law: `USES_I2`/`USES_J` are constants, so the dead parts of the
/// kernel (the I2 terms, the cross products) vanish at compile time. `Mtr` is never
/// stored: the I2 terms are factorised through `vtr` (see [`crate::rest::i2_terms`]),
/// so laws using I2 take no more memory than the others. The tets are kept in Morton
/// order (`tet_ids()` gives the global id of each), with rest data in batches of
/// [`LANES`] tets; see [`super::assembly`] for the parallel, deterministic assembly.
pub type HemlField<M> = TetField<HemlKernel<M>>;

/// The HEML formulation of an invariant law `M` (its law and force options): the
/// kernel of a [`HemlField`].
#[derive(Debug, Clone)]
pub struct HemlKernel<M: InvariantLaw> {
    law: M,
    opts: ForceOptions,
}

impl<M: InvariantLaw> Formulation for HemlKernel<M> {}

/// What one tet contributes.
struct TetResult {
    energy: f64,
    j: f64,
    f: [Vec3; 4],
}

impl<M: InvariantLaw> HemlField<M> {
    /// The field of `law` over every tet of `mesh`.
    pub fn new(law: M, mesh: &TetMesh, opts: ForceOptions) -> Result<Self> {
        Self::on_tets(law, mesh, None, opts)
    }

    /// The field of `law` over the tets `tets` of `mesh` (all when `None`), stored in
    /// Morton order.
    pub fn on_tets(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        TetField::build(HemlKernel { law, opts }, mesh, tets, opts, true)
    }

    /// As [`Self::on_tets`], keeping the tets in the given order (no Morton
    /// reordering); for tests and benchmarks of the reordering itself.
    pub fn on_tets_unordered(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        TetField::build(HemlKernel { law, opts }, mesh, tets, opts, false)
    }

    /// The law.
    pub fn law(&self) -> &M {
        &self.kernel().law
    }
}

impl<M: InvariantLaw> HemlKernel<M> {
    /// Energy, J and the four nodal forces of the tet in lane `lane` of `r`, whose
    /// corners are at `p`: the plain kernel.
    #[inline(always)]
    fn eval(&self, r: &HemlBatch, lane: usize, p: &[Vec3; 4]) -> TetResult {
        let v = edge_vectors(p);
        let l = v.map(|e| e.norm_squared());
        let vtr: [f64; 6] = std::array::from_fn(|e| r.vtr[e][lane]);
        let vol = r.vol[lane];
        let (i1, i2, ml) = invariant_terms(&vtr, &l, M::USES_I2);
        let (j, crosses) = if M::USES_J {
            volume_terms(&v, vol)
        } else {
            (1.0, [Vec3::zeros(); 3])
        };
        let d = if self.opts.extend(M::INVERSION_FIX, j) {
            self.law.dw_ext(i1, i2, j, self.opts.j0)
        } else {
            self.law.dw(i1, i2, j)
        };
        let [w1, w2, wj] = d.d;
        let g: [f64; 6] = std::array::from_fn(|e| {
            let mut ge = w1 * vtr[e];
            if M::USES_I2 {
                ge += w2 * (i1 * vtr[e] - ml[e]);
            }
            vol * ge
        });
        let mut f = [Vec3::zeros(); 4];
        scatter_links(&mut f, &g, &v);
        if M::USES_J {
            // ∂vol/∂x_a = crosses[a-1]/6 for a = 1..3, minus their sum for node 0
            let s = wj / 6.0;
            for a in 0..3 {
                f[a + 1] -= crosses[a] * s;
                f[0] += crosses[a] * s;
            }
        }
        TetResult {
            energy: vol * d.w,
            j,
            f,
        }
    }
}

impl<M: InvariantLaw> TetKernel for HemlKernel<M> {
    type Batch = HemlBatch;

    const PAD: HemlBatch = HemlBatch {
        vol: [1.0; LANES],
        vtr: [[0.0; LANES]; 6],
    };

    fn store_rest(&mut self, mesh: &TetMesh, t: usize, _k: usize, batch: &mut HemlBatch, lane: usize) {
        let r = RestTet::new(&mesh.tet_points(t));
        batch.vol[lane] = r.vol;
        for e in 0..6 {
            batch.vtr[e][lane] = r.vtr[e];
        }
    }

    /// The law's `dw`, forces added corner by corner.
    #[inline(always)]
    fn tet(&self, rest: &HemlBatch, lane: usize, p: &[Vec3; 4], mut add: impl FnMut(usize, Vec3)) -> f64 {
        let r = self.eval(rest, lane, p);
        for (a, fa) in r.f.into_iter().enumerate() {
            add(a, fa);
        }
        r.energy
    }

    /// J (from the positions when the law does not use it) and w = energy / vol.
    fn tet_state(&self, rest: &HemlBatch, lane: usize, _k: usize, p: &[Vec3; 4]) -> (f64, f64) {
        let r = self.eval(rest, lane, p);
        let vol = rest.vol[lane];
        let j = if M::USES_J { r.j } else { signed_j(p, vol) };
        (j, r.energy / vol)
    }

    #[inline(always)]
    fn batch(&self, r: &HemlBatch, p: &LanePoints, f: &mut LaneForces, en: &mut [f64; LANES]) {
        self.batch_with(r, p, None, f, en)
    }

    /// The pressure p̄ rides on the ∂w/∂J lane: −(w_J + p̄)·∇vol in one loop (a law
    /// without J has no cross products to share, so it takes the default).
    #[inline(always)]
    fn batch_pressure(
        &self,
        r: &HemlBatch,
        p: &LanePoints,
        pbar: &[f64; LANES],
        f: &mut LaneForces,
        en: &mut [f64; LANES],
    ) {
        if M::USES_J {
            self.batch_with(r, p, Some(pbar), f, en)
        } else {
            self.batch(r, p, f, en);
            let (cr, _) = super::lanes::lane_crosses(p);
            super::lanes::add_volume_forces(&cr, pbar, f);
        }
    }
}

impl<M: InvariantLaw> HemlKernel<M> {
    /// The batch kernel, with `pbar` (when given, and the law uses J) added to the
    /// ∂w/∂J lane: the volume term's factor on ∇vol (see [`TetKernel::batch_pressure`]).
    #[inline(always)]
    fn batch_with(
        &self,
        r: &HemlBatch,
        p: &LanePoints,
        pbar: Option<&[f64; LANES]>,
        f: &mut LaneForces,
        en: &mut [f64; LANES],
    ) {
        const L: usize = LANES;
        // J first: the law's longest chain (ln J, J^(−2/3)…) starts from it, and
        // the lengths and invariants below overlap with it (measured: 7–12 %
        // faster for neo-Hookean, 20–36 % for Mooney–Rivlin, than J after them)
        let (j, cr) = if M::USES_J {
            super::lanes::volume_lanes(p, &r.vol)
        } else {
            ([1.0; L], [[[0.0; L]; 3]; 3])
        };
        // Edge vectors are not kept: recomputing them from `p` where needed is cheaper
        // than a 1 kB array (its zeroing alone measured 10 instructions per tet).
        let len = super::lanes::squared_lengths(p);
        let mut i1 = [0.0; L];
        for e in 0..6 {
            for l in 0..L {
                i1[l] += r.vtr[e][l] * len[e][l];
            }
        }
        let (i2, ml) = if M::USES_I2 {
            super::lanes::i2_lanes(&r.vtr, &len, &i1)
        } else {
            ([0.0; L], [[0.0; L]; 6])
        };
        super::lanes::law_lanes!(self.law, self.opts, i1, i2, j => w, w1, w2, wj);
        // 2·g_e = 2·Vol·(w1·vtr_e + w2·(I1·vtr_e − (Mtr l)_e)), with the per-tet
        // factors 2·Vol·w1 and 2·Vol·w2 formed once
        let (mut a1, mut a2) = ([0.0; L], [0.0; L]);
        for l in 0..L {
            a1[l] = 2.0 * r.vol[l] * w1[l];
            a2[l] = 2.0 * r.vol[l] * w2[l];
        }
        let mut g2 = [[0.0; L]; 6];
        for e in 0..6 {
            for l in 0..L {
                let mut ge = a1[l] * r.vtr[e][l];
                if M::USES_I2 {
                    ge += a2[l] * (i1[l] * r.vtr[e][l] - ml[e][l]);
                }
                g2[e][l] = ge;
            }
        }
        // node forces, summed in the plain kernel's order (links, then volume term)
        super::lanes::link_forces(p, &g2, f);
        if M::USES_J {
            // the volume term's factor: Vol·∂w/∂J·∇J = w_J·∇vol, so a pressure adds to it
            let mut s = wj;
            if let Some(pb) = pbar {
                for l in 0..L {
                    s[l] += pb[l];
                }
            }
            super::lanes::add_volume_forces(&cr, &s, f);
        }
        for l in 0..L {
            en[l] = r.vol[l] * w[l];
        }
    }
}

/// I1, I2 (0 when `uses_i2` is false) and Mtr·l from the rest traces `vtr` and the
/// squared lengths `l`: shared by the force kernel and the tangent, so both evaluate
/// the law at the same invariants to the bit. tr C² = lᵀ Mtr l and Mtr·l go through
/// B (`rest::i2_terms`, tested against the definition); the P1 oracle checks the
/// result independently.
#[inline(always)]
pub(crate) fn invariant_terms(vtr: &[f64; 6], l: &[f64; 6], uses_i2: bool) -> (f64, f64, [f64; 6]) {
    let i1: f64 = (0..6).map(|e| vtr[e] * l[e]).sum();
    if uses_i2 {
        let (tr_c2, ml) = i2_terms(vtr, l);
        (i1, 0.5 * (i1 * i1 - tr_c2), ml)
    } else {
        (i1, 0.0, [0.0; 6])
    }
}

/// J and the cross products v2×v3, v3×v1, v1×v2 of the edge vectors `v` of a tet of
/// rest volume `vol` (∂vol/∂x_a = crosses[a−1]/6 for a = 1..3): shared by the force
/// kernel and the tangent, so both see the same J to the bit.
#[inline(always)]
pub(crate) fn volume_terms(v: &[Vec3; 6], vol: f64) -> (f64, [Vec3; 3]) {
    let c = [v[1].cross(&v[2]), v[2].cross(&v[0]), v[0].cross(&v[1])];
    (v[0].dot(&c[0]) / (6.0 * vol), c)
}

/// J of a tet from its current positions, for fields whose law does not need it.
pub(super) fn signed_j(p: &[Vec3; 4], vol: f64) -> f64 {
    (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) / (6.0 * vol)
}

/// Adds the six link forces of a tet: head −= 2 g_e v_e, tail += 2 g_e v_e.
#[inline(always)]
pub(super) fn scatter_links(f: &mut [Vec3; 4], g: &[f64; 6], v: &[Vec3; 6]) {
    for (e, &(tail, head)) in crate::rest::EDGES.iter().enumerate() {
        let fe = v[e] * (2.0 * g[e]);
        f[tail] += fe;
        f[head] -= fe;
    }
}
