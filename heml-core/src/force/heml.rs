//! The HEML force field: per tet, invariants from the six squared edge lengths,
//! forces along the links plus (for laws using J) the volume term (DESIGN §1).
//!
//! Three evaluation paths compute the same forces (see [`Assembly`]):
//! the plain serial kernel [`HemlField::add_forces_reference`] (one tet at a time,
//! the law's `dw`, the definition the others are tested against), a serial batched
//! kernel, and the default parallel blocked kernel (`ElasticForces::add_forces`).

// The kernels index fixed-size lane arrays in lock-step on purpose (it is what
// vectorises); iterator chains over several arrays would obscure that.
#![allow(clippy::needless_range_loop)]

use super::assembly::{BatchKernel, LaneForces, LanePoints, LawBatches, Layout, LANES};
use super::{check_sizes, scatter_links, selection, Assembly, ElasticForces, ForceOptions};
use crate::error::Result;
use crate::law::InvariantLaw;
use crate::mesh::TetMesh;
use crate::rest::{edge_vectors, i2_terms, RestTet};
use crate::Vec3;

/// Rest data of `LANES` consecutive tets, structure of arrays.
#[derive(Debug, Clone, Copy)]
struct RestBatch {
    vol: [f64; LANES],
    vtr: [[f64; LANES]; 6],
}

/// Internal forces of an invariant law `M` over (a region of) a mesh.
///
/// Monomorphised per law: `USES_I2`/`USES_J` are constants, so the dead parts of the
/// kernel (the I2 terms, the cross products) vanish at compile time. `Mtr` is never
/// stored: the I2 terms are factorised through `vtr` (see [`crate::rest::i2_terms`]),
/// so laws using I2 take no more memory than the others. The tets are kept in Morton
/// order (`tet_ids()` gives the global id of each), with rest data in batches of
/// [`LANES`] tets; see [`super::assembly`] for the parallel, deterministic assembly.
#[derive(Debug, Clone)]
pub struct HemlField<M: InvariantLaw> {
    law: M,
    opts: ForceOptions,
    n_nodes: usize,
    assembly: Assembly,
    layout: Layout,
    rest: Vec<RestBatch>,
}

/// What one tet contributes.
pub(crate) struct TetResult {
    pub energy: f64,
    pub j: f64,
    pub f: [Vec3; 4],
}

impl<M: InvariantLaw> HemlField<M> {
    /// The field of `law` over every tet of `mesh`.
    pub fn new(law: M, mesh: &TetMesh, opts: ForceOptions) -> Result<Self> {
        Self::on_tets(law, mesh, None, opts)
    }

    /// The field of `law` over the tets `tets` of `mesh` (all when `None`), stored in
    /// Morton order.
    pub fn on_tets(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        Self::build(law, mesh, tets, opts, true)
    }

    /// As [`Self::on_tets`], keeping the tets in the given order (no Morton
    /// reordering); for tests and benchmarks of the reordering itself.
    pub fn on_tets_unordered(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        Self::build(law, mesh, tets, opts, false)
    }

    fn build(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions, reorder: bool) -> Result<Self> {
        opts.validate()?;
        let sel = selection(mesh.n_tets(), tets)?;
        let layout = Layout::new(mesh, &sel, reorder);
        let nb = layout.n_batches();
        let pad = RestBatch {
            vol: [1.0; LANES],
            vtr: [[0.0; LANES]; 6],
        };
        let mut rest = vec![pad; nb];
        for (k, &t) in layout.ids.iter().enumerate() {
            let r = RestTet::new(&mesh.tet_points(t));
            let (b, l) = (k / LANES, k % LANES);
            rest[b].vol[l] = r.vol;
            for e in 0..6 {
                rest[b].vtr[e][l] = r.vtr[e];
            }
        }
        Ok(HemlField {
            law,
            opts,
            n_nodes: mesh.n_nodes(),
            assembly: Assembly::default(),
            layout,
            rest,
        })
    }

    /// The law.
    pub fn law(&self) -> &M {
        &self.law
    }

    /// The evaluation path `add_forces` uses.
    pub fn assembly(&self) -> Assembly {
        self.assembly
    }

    /// Chooses the evaluation path `add_forces` uses (default [`Assembly::Parallel`]).
    pub fn set_assembly(&mut self, assembly: Assembly) {
        self.assembly = assembly;
    }

    /// Bytes of memory per tet this field holds: rest data, indices, blocks, merge
    /// lists and the scratch buffers of the parallel path.
    pub fn bytes_per_tet(&self) -> f64 {
        self.layout.bytes_per_tet(&self.rest)
    }

    fn vol(&self, k: usize) -> f64 {
        self.rest[k / LANES].vol[k % LANES]
    }

    /// Energy, J and the four nodal forces of the field's `k`-th tet: the plain kernel.
    #[inline(always)]
    pub(crate) fn tet(&self, k: usize, idx: &[u32; 4], x: &[Vec3]) -> TetResult {
        let (b, lane) = (k / LANES, k % LANES);
        let p = idx.map(|i| x[i as usize]);
        let v = edge_vectors(&p);
        let l = v.map(|e| e.norm_squared());
        let vtr: [f64; 6] = std::array::from_fn(|e| self.rest[b].vtr[e][lane]);
        let vol = self.rest[b].vol[lane];
        let i1: f64 = (0..6).map(|e| vtr[e] * l[e]).sum();
        let (i2, ml) = if M::USES_I2 {
            // tr C² = lᵀ Mtr l and Mtr l through B (`rest::i2_terms`, tested against
            // the definition); the P1 oracle checks the result independently
            let (tr_c2, ml) = i2_terms(&vtr, &l);
            (0.5 * (i1 * i1 - tr_c2), ml)
        } else {
            (0.0, [0.0; 6])
        };
        let (j, crosses) = if M::USES_J {
            let c = [v[1].cross(&v[2]), v[2].cross(&v[0]), v[0].cross(&v[1])];
            (v[0].dot(&c[0]) / (6.0 * vol), c)
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

    /// The plain serial kernel: one tet at a time in field order, the law's `dw`,
    /// forces added node by node. The reference every optimised path is tested
    /// against.
    pub fn add_forces_reference(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        self.layout.add_plain(x, f, |k, idx| {
            let r = self.tet(k, idx, x);
            (r.energy, r.f)
        })
    }

    fn kernel(&self) -> LawBatches<'_, M, RestBatch> {
        LawBatches {
            law: &self.law,
            opts: self.opts,
            rest: &self.rest,
        }
    }
}

impl<M: InvariantLaw> BatchKernel for LawBatches<'_, M, RestBatch> {
    #[inline(always)]
    fn batch(&self, b: usize, p: &LanePoints, f: &mut LaneForces, en: &mut [f64; LANES]) {
        const L: usize = LANES;
        let r = &self.rest[b];
        let mut j = [1.0; L];
        let mut cr = [[[0.0; L]; 3]; 3];
        if M::USES_J {
            // J first: the law's longest chain (ln J, J^(−2/3)…) starts from it, and
            // the lengths and invariants below overlap with it (measured: 7–12 %
            // faster for neo-Hookean, 20–36 % for Mooney–Rivlin, than J after them).
            // J = det/(6·vol) as a product: the division depends on rest data only
            // and runs early, off the chain positions → J → law → forces
            let mut inv_6vol = [0.0; L];
            for l in 0..L {
                inv_6vol[l] = 1.0 / (6.0 * r.vol[l]);
            }
            // crosses v2×v3, v3×v1, v1×v2
            // v_a = p_{a+1} − p_0 (EDGES 0..3)
            for (a, (s, t)) in [(2, 3), (3, 1), (1, 2)].into_iter().enumerate() {
                for l in 0..L {
                    let (ux, uy, uz) = (
                        p[s][0][l] - p[0][0][l],
                        p[s][1][l] - p[0][1][l],
                        p[s][2][l] - p[0][2][l],
                    );
                    let (wx, wy, wz) = (
                        p[t][0][l] - p[0][0][l],
                        p[t][1][l] - p[0][1][l],
                        p[t][2][l] - p[0][2][l],
                    );
                    cr[a][0][l] = uy * wz - uz * wy;
                    cr[a][1][l] = uz * wx - ux * wz;
                    cr[a][2][l] = ux * wy - uy * wx;
                }
            }
            for l in 0..L {
                let det = (p[1][0][l] - p[0][0][l]) * cr[0][0][l]
                    + (p[1][1][l] - p[0][1][l]) * cr[0][1][l]
                    + (p[1][2][l] - p[0][2][l]) * cr[0][2][l];
                j[l] = det * inv_6vol[l];
            }
        }
        // Edge vectors are not kept: recomputing them from `p` where needed is cheaper
        // than a 1 kB array (its zeroing alone measured 10 instructions per tet).
        let len = super::lanes::squared_lengths(p);
        let mut i1 = [0.0; L];
        for e in 0..6 {
            for l in 0..L {
                i1[l] += r.vtr[e][l] * len[e][l];
            }
        }
        let mut i2 = [0.0; L];
        let mut ml = [[0.0; L]; 6];
        if M::USES_I2 {
            // factorised through B = V⁻¹V⁻ᵀ (see `rest::i2_terms`): no Mtr to load
            for l in 0..L {
                let vtr: [f64; 6] = std::array::from_fn(|e| r.vtr[e][l]);
                let le: [f64; 6] = std::array::from_fn(|e| len[e][l]);
                let (tr_c2, m) = i2_terms(&vtr, &le);
                for e in 0..6 {
                    ml[e][l] = m[e];
                }
                i2[l] = 0.5 * (i1[l] * i1[l] - tr_c2);
            }
        }
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
        let mut s = [0.0; L];
        for l in 0..L {
            s[l] = wj[l] * (1.0 / 6.0);
        }
        super::lanes::link_forces(p, &g2, f);
        if M::USES_J {
            for c in 0..3 {
                for l in 0..L {
                    let (c0, c1, c2) = (cr[0][c][l] * s[l], cr[1][c][l] * s[l], cr[2][c][l] * s[l]);
                    f[1][c][l] -= c0;
                    f[0][c][l] += c0;
                    f[2][c][l] -= c1;
                    f[0][c][l] += c1;
                    f[3][c][l] -= c2;
                    f[0][c][l] += c2;
                }
            }
        }
        for l in 0..L {
            en[l] = r.vol[l] * w[l];
        }
    }
}

impl<M: InvariantLaw> ElasticForces for HemlField<M> {
    fn n_nodes(&self) -> usize {
        self.n_nodes
    }
    fn n_tets(&self) -> usize {
        self.layout.n_tets()
    }
    fn tet_ids(&self) -> &[usize] {
        &self.layout.ids
    }

    fn energy(&self, x: &[Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, None)?;
        match self.assembly {
            Assembly::Reference => Ok((0..self.layout.n_tets())
                .map(|k| self.tet(k, &self.layout.global_tet(k), x).energy)
                .sum()),
            _ => self.add_forces(x, &mut vec![Vec3::zeros(); self.n_nodes]),
        }
    }

    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        match self.assembly {
            Assembly::Reference => self.add_forces_reference(x, f),
            a => self.layout.add_batched(&self.kernel(), a == Assembly::Parallel, x, f),
        }
    }

    fn set_assembly(&mut self, assembly: Assembly) {
        self.assembly = assembly;
    }
    fn bytes_per_tet(&self) -> Option<f64> {
        Some(HemlField::bytes_per_tet(self))
    }

    fn tet_states(&self, x: &[Vec3]) -> Result<Vec<(f64, f64)>> {
        check_sizes(self.n_nodes, x, None)?;
        Ok((0..self.layout.n_tets())
            .map(|k| {
                let idx = self.layout.global_tet(k);
                let r = self.tet(k, &idx, x);
                let j = if M::USES_J { r.j } else { signed_j(&idx, x, self.vol(k)) };
                (j, r.energy / self.vol(k))
            })
            .collect())
    }
}

/// J of a tet from its current positions, for fields whose law does not need it.
pub(crate) fn signed_j(idx: &[u32; 4], x: &[Vec3], vol: f64) -> f64 {
    let p = idx.map(|i| x[i as usize]);
    (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) / (6.0 * vol)
}
