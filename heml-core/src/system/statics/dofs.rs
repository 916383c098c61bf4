//! The unknowns of a Newton solve: the free coordinates of the nodes, numbered node
//! by node in reverse Cuthill–McKee order so that the tangent is banded.

use super::rcm::rcm_order;
use crate::Vec3;

/// Marks a coordinate that is held (no degree of freedom).
const HELD: usize = usize::MAX;

/// Numbering of the free coordinates and the half-bandwidth it gives the tangent.
pub(in crate::system) struct DofMap {
    /// Per node and axis, the degree of freedom, or [`HELD`].
    dof: Vec<[usize; 3]>,
    /// Number of degrees of freedom.
    n: usize,
    /// Half-bandwidth of any matrix coupling the nodes of one tet.
    band: usize,
}

impl DofMap {
    /// Numbers the coordinates not marked in `held` (one entry per node), nodes in
    /// reverse Cuthill–McKee order of the tets' graph.
    pub(in crate::system) fn new(held: &[[bool; 3]], tets: &[[u32; 4]]) -> Self {
        let order = rcm_order(held.len(), tets);
        let mut dof = vec![[HELD; 3]; held.len()];
        let mut n = 0;
        for &i in &order {
            for a in 0..3 {
                if !held[i][a] {
                    dof[i][a] = n;
                    n += 1;
                }
            }
        }
        let mut band = 0;
        for tet in tets {
            let ids: Vec<usize> = tet
                .iter()
                .flat_map(|&i| dof[i as usize])
                .filter(|&d| d != HELD)
                .collect();
            if let (Some(lo), Some(hi)) = (ids.iter().min(), ids.iter().max()) {
                band = band.max(hi - lo);
            }
        }
        DofMap { dof, n, band }
    }

    /// Number of degrees of freedom.
    pub(in crate::system) fn len(&self) -> usize {
        self.n
    }

    /// Half-bandwidth of the tangent.
    pub(in crate::system) fn band(&self) -> usize {
        self.band
    }

    /// Half-bandwidth of a matrix that couples every pair of nodes around a common
    /// node (e.g. the nodal volumetric term: the tets around a node and their nodes),
    /// about twice [`DofMap::band`].
    pub(in crate::system) fn ring_band(&self, tets: &[[u32; 4]]) -> usize {
        let n = self.dof.len();
        let (mut lo, mut hi) = (vec![usize::MAX; n], vec![0; n]);
        for tet in tets {
            let ids = tet.iter().flat_map(|&i| self.dof[i as usize]).filter(|&d| d != HELD);
            let (l, h) = ids.fold((usize::MAX, 0), |(l, h), d| (l.min(d), h.max(d)));
            for &b in tet {
                lo[b as usize] = lo[b as usize].min(l);
                hi[b as usize] = hi[b as usize].max(h);
            }
        }
        (0..n)
            .filter(|&b| lo[b] <= hi[b])
            .map(|b| hi[b] - lo[b])
            .max()
            .unwrap_or(0)
    }

    /// Half-bandwidth of a matrix that couples the nodes of each of `groups` (the
    /// patch volumetric term's patches).
    pub(in crate::system) fn group_band(&self, groups: &[Vec<u32>]) -> usize {
        groups
            .iter()
            .map(|g| {
                let ids = g.iter().flat_map(|&i| self.dof[i as usize]).filter(|&d| d != HELD);
                let (l, h) = ids.fold((usize::MAX, 0), |(l, h), d| (l.min(d), h.max(d)));
                h.saturating_sub(l)
            })
            .max()
            .unwrap_or(0)
    }

    /// The degree of freedom of coordinate `axis` of `node`, if free.
    pub(in crate::system) fn get(&self, node: usize, axis: usize) -> Option<usize> {
        let d = self.dof[node][axis];
        (d != HELD).then_some(d)
    }

    /// The free components of a nodal vector field, by degree of freedom.
    pub(in crate::system) fn gather(&self, field: &[Vec3]) -> Vec<f64> {
        let mut out = vec![0.0; self.n];
        for (i, d) in self.dof.iter().enumerate() {
            for a in 0..3 {
                if d[a] != HELD {
                    out[d[a]] = field[i][a];
                }
            }
        }
        out
    }

    /// The nodal vector field, flat (3 numbers per node), with the free components
    /// taken from `v` (by degree of freedom) and zeros on the held ones.
    pub(in crate::system) fn scatter(&self, v: &[f64], out: &mut [f64]) {
        for (o, d) in out.chunks_exact_mut(3).zip(&self.dof) {
            for a in 0..3 {
                o[a] = if d[a] != HELD { v[d[a]] } else { 0.0 };
            }
        }
    }

    /// The free components of a flat nodal field (3 numbers per node) into `out`, by
    /// degree of freedom: the inverse of [`DofMap::scatter`].
    pub(in crate::system) fn gather_flat(&self, field: &[f64], out: &mut [f64]) {
        for (i, d) in self.dof.iter().enumerate() {
            for a in 0..3 {
                if d[a] != HELD {
                    out[d[a]] = field[3 * i + a];
                }
            }
        }
    }

    /// x = x0 + step·dx on the free coordinates (held ones are left as they are).
    pub(in crate::system) fn step(&self, x: &mut [Vec3], x0: &[Vec3], dx: &[f64], step: f64) {
        for (i, d) in self.dof.iter().enumerate() {
            for a in 0..3 {
                if d[a] != HELD {
                    x[i][a] = x0[i][a] + step * dx[d[a]];
                }
            }
        }
    }
}
