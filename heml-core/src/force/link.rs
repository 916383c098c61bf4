//! Link laws (mass–spring and kin): an energy per tetrahedron edge w(l, L), summed
//! over the six edges of every tet.
//!
//! An edge shared by n tets therefore carries n springs; a classical mass–spring
//! network with stiffness k per unique edge is the link law with k/n on each.

use super::heml::signed_j;
use super::{check_sizes, scatter_links, selection, ElasticForces, ForceOptions};
use crate::error::Result;
use crate::law::LinkLaw;
use crate::mesh::TetMesh;
use crate::rest::edge_vectors;
use crate::Vec3;

/// Internal forces of a link law `M` over (a region of) a mesh.
#[derive(Debug, Clone)]
pub struct LinkField<M: LinkLaw> {
    law: M,
    n_nodes: usize,
    ids: Vec<usize>,
    tets: Vec<[u32; 4]>,
    rest_l: Vec<[f64; 6]>,
    vol: Vec<f64>,
}

impl<M: LinkLaw> LinkField<M> {
    /// The field of `law` over the tets `tets` of `mesh` (all when `None`).
    /// `opts` is accepted for symmetry with [`super::HemlField`]; link laws have no J.
    pub fn on_tets(law: M, mesh: &TetMesh, tets: Option<&[usize]>, opts: ForceOptions) -> Result<Self> {
        opts.validate()?;
        let ids = selection(mesh.n_tets(), tets)?;
        let tet_idx: Vec<[u32; 4]> = ids.iter().map(|&t| mesh.tets()[t]).collect();
        let rest_l = ids
            .iter()
            .map(|&t| edge_vectors(&mesh.tet_points(t)).map(|v| v.norm_squared()))
            .collect();
        let vol = ids.iter().map(|&t| mesh.tet_volume(t)).collect();
        Ok(LinkField {
            law,
            n_nodes: mesh.n_nodes(),
            ids,
            tets: tet_idx,
            rest_l,
            vol,
        })
    }

    #[inline(always)]
    fn tet(&self, k: usize, x: &[Vec3]) -> (f64, [Vec3; 4]) {
        let p = self.tets[k].map(|i| x[i as usize]);
        let v = edge_vectors(&p);
        let mut energy = 0.0;
        let g: [f64; 6] = std::array::from_fn(|e| {
            let (w, dw) = self.law.dw(v[e].norm_squared(), self.rest_l[k][e]);
            energy += w;
            dw
        });
        let mut f = [Vec3::zeros(); 4];
        scatter_links(&mut f, &g, &v);
        (energy, f)
    }
}

impl<M: LinkLaw> ElasticForces for LinkField<M> {
    fn n_nodes(&self) -> usize {
        self.n_nodes
    }
    fn n_tets(&self) -> usize {
        self.tets.len()
    }
    fn tet_ids(&self) -> &[usize] {
        &self.ids
    }
    fn energy(&self, x: &[Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, None)?;
        Ok((0..self.tets.len()).map(|k| self.tet(k, x).0).sum())
    }
    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<f64> {
        check_sizes(self.n_nodes, x, Some(f))?;
        let mut energy = 0.0;
        for k in 0..self.tets.len() {
            let (e, fk) = self.tet(k, x);
            energy += e;
            for (a, &i) in self.tets[k].iter().enumerate() {
                f[i as usize] += fk[a];
            }
        }
        Ok(energy)
    }
    fn tet_states(&self, x: &[Vec3]) -> Result<Vec<(f64, f64)>> {
        check_sizes(self.n_nodes, x, None)?;
        Ok((0..self.tets.len())
            .map(|k| (signed_j(&self.tets[k], x, self.vol[k]), self.tet(k, x).0 / self.vol[k]))
            .collect())
    }
}
