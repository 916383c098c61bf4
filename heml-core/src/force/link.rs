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

use super::assembly::{LaneForces, LanePoints, LANES};
use super::field::{Formulation, TetField};
use super::heml::{scatter_links, signed_j};
use super::kernel::TetKernel;
use super::lanes::{link_forces, squared_lengths};
use super::ForceOptions;
use crate::error::Result;
use crate::law::LinkLaw;
use crate::mesh::TetMesh;
use crate::rest::edge_vectors;
use crate::Vec3;

/// Rest squared edge lengths of `LANES` consecutive tets, `[edge][lane]`.
#[derive(Debug, Clone, Copy)]
pub struct LinkBatch {
    rest_l: [[f64; LANES]; 6],
}

/// Internal forces of a link law `M` over (a region of) a mesh.
///
/// The tets are kept in Morton order (`tet_ids()` gives the global id of each), with
/// the rest lengths in batches of [`LANES`] tets.
pub type LinkField<M> = TetField<LinkKernel<M>>;

/// The link formulation of a link law `M`: the kernel of a [`LinkField`].
#[derive(Debug, Clone)]
pub struct LinkKernel<M: LinkLaw> {
    law: M,
    /// Rest volume per field tet, for [`super::ElasticForces::tet_states`] only
    /// (kept out of the batches, which the force kernels stream).
    vol: Vec<f64>,
}

impl<M: LinkLaw> Formulation for LinkKernel<M> {}

impl<M: LinkLaw> LinkField<M> {
    /// The field of `law` over the tets `tets` of `mesh` (all when `None`), stored in
    /// Morton order. `opts` is accepted for symmetry with [`super::HemlField`]; link
    /// laws have no J.
    pub fn on_tets(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        let kernel = LinkKernel {
            law,
            vol: Vec::with_capacity(tets.map_or(mesh.n_tets(), <[usize]>::len)),
        };
        TetField::build(kernel, mesh, tets, opts, true)
    }

    /// The law.
    pub fn law(&self) -> &M {
        &self.kernel().law
    }
}

impl<M: LinkLaw> TetKernel for LinkKernel<M> {
    type Batch = LinkBatch;

    // padding lanes: any finite rest length (their results are never used)
    const PAD: LinkBatch = LinkBatch {
        rest_l: [[1.0; LANES]; 6],
    };

    fn store_rest(&mut self, mesh: &TetMesh, t: usize, k: usize, batch: &mut LinkBatch, lane: usize) {
        let l = edge_vectors(&mesh.tet_points(t)).map(|v| v.norm_squared());
        for e in 0..6 {
            batch.rest_l[e][lane] = l[e];
        }
        debug_assert_eq!(self.vol.len(), k, "rest data stored out of field order");
        self.vol.push(mesh.tet_volume(t));
    }

    /// Energy summed edge by edge; forces added corner by corner.
    #[inline(always)]
    fn tet(&self, rest: &LinkBatch, lane: usize, p: &[Vec3; 4], mut add: impl FnMut(usize, Vec3)) -> f64 {
        let v = edge_vectors(p);
        let mut energy = 0.0;
        let g: [f64; 6] = std::array::from_fn(|e| {
            let (w, dw) = self.law.dw(v[e].norm_squared(), rest.rest_l[e][lane]);
            energy += w;
            dw
        });
        let mut f = [Vec3::zeros(); 4];
        scatter_links(&mut f, &g, &v);
        for (a, fa) in f.into_iter().enumerate() {
            add(a, fa);
        }
        energy
    }

    /// J from the positions and the tet's energy divided by its rest volume.
    fn tet_state(&self, rest: &LinkBatch, lane: usize, k: usize, p: &[Vec3; 4]) -> (f64, f64) {
        (signed_j(p, self.vol[k]), self.tet_energy(rest, lane, p) / self.vol[k])
    }

    #[inline(always)]
    fn batch(&self, r: &LinkBatch, p: &LanePoints, f: &mut LaneForces, en: &mut [f64; LANES]) {
        const L: usize = LANES;
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

    fn side_bytes(&self) -> usize {
        std::mem::size_of_val(self.vol.as_slice())
    }
}
