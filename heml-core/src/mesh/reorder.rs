//! Reordering for memory locality: Morton (Z-order) keys of tet centroids and node
//! positions.
//!
//! Real meshes arrive with nodes and tets in whatever order the mesher wrote them; a
//! force loop that walks the tets then jumps around the node arrays. Sorting along a
//! space-filling curve makes consecutive tets share nodes and neighbouring nodes sit
//! close in memory.
//!
//! The force fields apply [`morton_tet_order`] to their tets when built (their
//! `tet_ids()` report the resulting order, so callers map results back by id), and
//! number the nodes of each block locally, so node ids seen by users never change.
//! [`morton_node_order`] and [`TetMesh::renumbered`] renumber the nodes of a whole
//! mesh, keeping the [`Permutation`] to translate ids back.

use super::TetMesh;
use crate::error::Result;
use crate::Vec3;

/// A permutation and its inverse: `new_to_old[new] = old`, `old_to_new[old] = new`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Permutation {
    /// Old index of each new position.
    pub new_to_old: Vec<usize>,
    /// New position of each old index.
    pub old_to_new: Vec<usize>,
}

impl Permutation {
    /// From the list of old indices in their new order (must be a permutation).
    pub fn from_new_to_old(new_to_old: Vec<usize>) -> Permutation {
        let mut old_to_new = vec![usize::MAX; new_to_old.len()];
        for (new, &old) in new_to_old.iter().enumerate() {
            old_to_new[old] = new;
        }
        debug_assert!(old_to_new.iter().all(|&i| i != usize::MAX), "not a permutation");
        Permutation { new_to_old, old_to_new }
    }

    /// The identity on `n` elements.
    pub fn identity(n: usize) -> Permutation {
        Permutation {
            new_to_old: (0..n).collect(),
            old_to_new: (0..n).collect(),
        }
    }

    /// A pseudo-random permutation of `n` elements, the same for the same `seed` on
    /// every platform (xorshift64 + Fisher–Yates): meshes "as a mesher might number
    /// them", for tests and benchmarks of the renumbering and of the block driver.
    ///
    /// ```
    /// use heml_core::mesh::reorder::Permutation;
    /// let p = Permutation::pseudo_random(1000, 7);
    /// let mut seen = p.apply(&(0..1000).collect::<Vec<usize>>());
    /// assert_ne!(seen, (0..1000).collect::<Vec<_>>()); // shuffled
    /// seen.sort();
    /// assert_eq!(seen, (0..1000).collect::<Vec<_>>()); // a permutation
    /// assert_eq!(p, Permutation::pseudo_random(1000, 7)); // deterministic
    /// ```
    pub fn pseudo_random(n: usize, seed: u64) -> Permutation {
        // xorshift64 has no zero state: any seed maps to a non-zero one
        let mut state = seed ^ 0x9E37_79B9_7F4A_7C15;
        if state == 0 {
            state = 0x2545_F491_4F6C_DD1D;
        }
        let mut v: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            v.swap(i, (state % (i as u64 + 1)) as usize);
        }
        Permutation::from_new_to_old(v)
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.new_to_old.len()
    }

    /// Whether it permutes nothing.
    pub fn is_empty(&self) -> bool {
        self.new_to_old.is_empty()
    }

    /// `data` rearranged into the new order (`out[new] = data[new_to_old[new]]`).
    pub fn apply<T: Clone>(&self, data: &[T]) -> Vec<T> {
        self.new_to_old.iter().map(|&o| data[o].clone()).collect()
    }

    /// `data` in the new order brought back to the old order.
    pub fn unapply<T: Clone>(&self, data: &[T]) -> Vec<T> {
        self.old_to_new.iter().map(|&n| data[n].clone()).collect()
    }
}

/// Spreads the low 21 bits of `v` to every third bit.
fn spread3(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | x << 32) & 0x1f_0000_0000_ffff;
    x = (x | x << 16) & 0x1f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// Morton key of `p` inside the box [lo, lo + size].
fn morton_key(p: &Vec3, lo: &Vec3, inv: &Vec3) -> u64 {
    let q = |a: usize| {
        let t = ((p[a] - lo[a]) * inv[a]).clamp(0.0, 1.0);
        (t * 2_097_151.0) as u64
    };
    spread3(q(0)) | spread3(q(1)) << 1 | spread3(q(2)) << 2
}

/// Positions of `points` sorted by Morton key (ties by index: deterministic).
fn morton_sort(points: &[Vec3]) -> Vec<usize> {
    if points.is_empty() {
        return Vec::new();
    }
    let mut lo = Vec3::repeat(f64::INFINITY);
    let mut hi = Vec3::repeat(f64::NEG_INFINITY);
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let inv = (hi - lo).map(|s| if s > 0.0 { 1.0 / s } else { 0.0 });
    let mut keyed: Vec<(u64, usize)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| (morton_key(p, &lo, &inv), i))
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// Positions into `sel` (tet ids of `mesh`) in Morton order of the tet centroids.
pub fn morton_tet_order(mesh: &TetMesh, sel: &[usize]) -> Vec<usize> {
    let centroids: Vec<Vec3> = sel
        .iter()
        .map(|&t| mesh.tet_points(t).iter().sum::<Vec3>() / 4.0)
        .collect();
    morton_sort(&centroids)
}

/// The Morton order of all tets of `mesh` (by centroid).
pub fn morton_order(mesh: &TetMesh) -> Permutation {
    let all: Vec<usize> = (0..mesh.n_tets()).collect();
    Permutation::from_new_to_old(morton_tet_order(mesh, &all))
}

/// The Morton order of the nodes of `mesh` (by rest position).
pub fn morton_node_order(mesh: &TetMesh) -> Permutation {
    Permutation::from_new_to_old(morton_sort(mesh.nodes()))
}

impl TetMesh {
    /// The same mesh with nodes renumbered by `nodes` and tets reordered by `tets`
    /// (e.g. [`morton_node_order`], [`morton_order`]); tags, cell vectors and
    /// weights follow their tets, node sets their nodes.
    /// Node `i` of `self` is node `nodes.old_to_new[i]` of the result.
    pub fn renumbered(&self, nodes: &Permutation, tets: &Permutation) -> Result<TetMesh> {
        if nodes.len() != self.n_nodes() || tets.len() != self.n_tets() {
            return Err(crate::error::HemlError::SizeMismatch {
                what: "permutation",
                got: nodes.len(),
                expected: self.n_nodes(),
            });
        }
        let new_nodes = nodes.apply(self.nodes());
        let new_tets = tets
            .new_to_old
            .iter()
            .map(|&t| self.tets()[t].map(|i| nodes.old_to_new[i as usize]))
            .collect();
        let mut out = TetMesh::with_tags(new_nodes, new_tets, tets.apply(self.tags()))?;
        for (name, v) in self.cell_vectors() {
            out = out.with_cell_vectors(name.clone(), tets.apply(v))?;
        }
        for (name, ids) in self.node_sets() {
            out = out.with_node_set(name.clone(), ids.iter().map(|&i| nodes.old_to_new[i]).collect())?;
        }
        if let Some(o) = self.overlap() {
            out = out.with_overlap(super::overlap::Overlap {
                weights: tets.apply(&o.weights),
                covers: tets.apply(&o.covers),
            })?;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::{box_mesh, HexSplit};

    #[test]
    fn spread_interleaves() {
        assert_eq!(spread3(0b11), 0b1001);
        assert_eq!(spread3(0x1f_ffff).count_ones(), 21);
    }

    #[test]
    fn renumbering_keeps_geometry_and_inverts() {
        let m = box_mesh([1.0, 2.0, 1.0], [3, 4, 2], HexSplit::Five).unwrap();
        let (pn, pt) = (morton_node_order(&m), morton_order(&m));
        let r = m.renumbered(&pn, &pt).unwrap();
        assert_eq!(r.n_tets(), m.n_tets());
        for new in 0..r.n_tets() {
            let old = pt.new_to_old[new];
            assert!((r.tet_volume(new) - m.tet_volume(old)).abs() < 1e-15);
            for a in 0..4 {
                let i = m.tets()[old][a] as usize;
                assert_eq!(r.tets()[new][a] as usize, pn.old_to_new[i]);
            }
        }
        let back = pn.unapply(r.nodes());
        assert_eq!(back, m.nodes());
        let mut seen = pt.new_to_old.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..m.n_tets()).collect::<Vec<_>>());
    }
}
