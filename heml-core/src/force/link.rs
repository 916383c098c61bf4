//! Link laws (mass–spring and kin): an energy per tetrahedron edge w(l, L), summed
//! over the six edges of every tet.
//!
//! An edge shared by n tets therefore carries n springs; a classical mass–spring
//! network with stiffness k per unique edge is the link law with k/n on each.
//!
//! Evaluated like [`super::HemlField`]: a plain serial kernel (the reference), and
//! batched and parallel paths on the shared block driver ([`super::assembly`]).

// The kernels index fixed-size lane arrays in lock-step on purpose (it is what
// vectorises); iterator chains over several arrays would obscure that.
#![allow(clippy::needless_range_loop)]

use super::assembly::{BatchKernel, LaneForces, LanePoints, LawBatches, Layout, LANES};
use super::heml::signed_j;
use super::lanes::{link_forces, squared_lengths};
use super::{check_sizes, scatter_links, selection, Assembly, ElasticForces, ForceOptions};
use crate::error::Result;
use crate::law::LinkLaw;
use crate::mesh::TetMesh;
use crate::rest::edge_vectors;
use crate::Vec3;

/// Rest squared edge lengths of `LANES` consecutive tets, `[edge][lane]`.
#[derive(Debug, Clone, Copy)]
struct LinkBatch {
    rest_l: [[f64; LANES]; 6],
}

/// Internal forces of a link law `M` over (a region of) a mesh.
///
/// The tets are kept in Morton order (`tet_ids()` gives the global id of each), with
/// the rest lengths in batches of [`LANES`] tets.
#[derive(Debug, Clone)]
pub struct LinkField<M: LinkLaw> {
    law: M,
    n_nodes: usize,
    assembly: Assembly,
    layout: Layout,
    rest: Vec<LinkBatch>,
    /// Rest volume per field tet, for [`ElasticForces::tet_states`] only.
    vol: Vec<f64>,
}

impl<M: LinkLaw> LinkField<M> {
    /// The field of `law` over the tets `tets` of `mesh` (all when `None`), stored in
    /// Morton order. `opts` is accepted for symmetry with [`super::HemlField`]; link
    /// laws have no J.
    pub fn on_tets(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        opts.validate()?;
        let sel = selection(mesh.n_tets(), tets)?;
        let layout = Layout::new(mesh, &sel, true);
        // padding lanes: any finite rest length (their results are never used)
        let pad = LinkBatch {
            rest_l: [[1.0; LANES]; 6],
        };
        let mut rest = vec![pad; layout.n_batches()];
        let mut vol = Vec::with_capacity(layout.n_tets());
        for (k, &t) in layout.ids.iter().enumerate() {
            let l = edge_vectors(&mesh.tet_points(t)).map(|v| v.norm_squared());
            for e in 0..6 {
                rest[k / LANES].rest_l[e][k % LANES] = l[e];
            }
            vol.push(mesh.tet_volume(t));
        }
        Ok(LinkField {
            law,
            n_nodes: mesh.n_nodes(),
            assembly: Assembly::default(),
            layout,
            rest,
            vol,
        })
    }

    /// The law.
    pub fn law(&self) -> &M {
        &self.law
    }

    /// Energy and the four nodal forces of the field's `k`-th tet, whose nodes are
    /// `idx`: the plain kernel.
    #[inline(always)]
    fn tet(&self, k: usize, idx: &[u32; 4], x: &[Vec3]) -> (f64, [Vec3; 4]) {
        let p = idx.map(|i| x[i as usize]);
        let v = edge_vectors(&p);
        let rest = &self.rest[k / LANES];
        let mut energy = 0.0;
        let g: [f64; 6] = std::array::from_fn(|e| {
            let (w, dw) = self.law.dw(v[e].norm_squared(), rest.rest_l[e][k % LANES]);
            energy += w;
            dw
        });
        let mut f = [Vec3::zeros(); 4];
        scatter_links(&mut f, &g, &v);
        (energy, f)
    }

    /// The plain serial kernel: one tet at a time in field order, forces added node by
    /// node. The reference the optimised paths are tested against.
    pub fn add_forces_reference(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        self.layout.add_plain(x, f, |k, idx| self.tet(k, idx, x))
    }
}

impl<M: LinkLaw> BatchKernel for LawBatches<'_, M, LinkBatch> {
    #[inline(always)]
    fn batch(&self, b: usize, p: &LanePoints, f: &mut LaneForces, en: &mut [f64; LANES]) {
        const L: usize = LANES;
        let r = &self.rest[b];
        let mut w = [0.0; L];
        let mut g2 = [[0.0; L]; 6];
        let len = squared_lengths(p);
        for e in 0..6 {
            for l in 0..L {
                let (we, ge) = self.law.dw(len[e][l], r.rest_l[e][l]);
                // summed edge by edge from 0, as the plain kernel does
                w[l] += we;
                g2[e][l] = 2.0 * ge;
            }
        }
        link_forces(p, &g2, f);
        *en = w;
    }
}

impl<M: LinkLaw> ElasticForces for LinkField<M> {
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
                .map(|k| self.tet(k, &self.layout.global_tet(k), x).0)
                .sum()),
            _ => self.add_forces(x, &mut vec![Vec3::zeros(); self.n_nodes]),
        }
    }
    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        match self.assembly {
            Assembly::Reference => self.add_forces_reference(x, f),
            a => {
                let kernel = LawBatches {
                    law: &self.law,
                    opts: ForceOptions::default(),
                    rest: &self.rest,
                };
                self.layout.add_batched(&kernel, a == Assembly::Parallel, x, f)
            }
        }
    }
    fn set_assembly(&mut self, assembly: Assembly) {
        self.assembly = assembly;
    }
    fn bytes_per_tet(&self) -> Option<f64> {
        let vol = std::mem::size_of_val(self.vol.as_slice()) as f64 / self.layout.n_tets().max(1) as f64;
        Some(self.layout.bytes_per_tet(&self.rest) + vol)
    }
    fn tet_states(&self, x: &[Vec3]) -> Result<Vec<(f64, f64)>> {
        check_sizes(self.n_nodes, x, None)?;
        Ok((0..self.layout.n_tets())
            .map(|k| {
                let idx = self.layout.global_tet(k);
                (signed_j(&idx, x, self.vol[k]), self.tet(k, &idx, x).0 / self.vol[k])
            })
            .collect())
    }
}
