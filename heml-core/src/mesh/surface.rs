//! The boundary surface of a tet mesh: the faces that belong to exactly one tet,
//! oriented outward.
//!
//! Tools contact this surface, pressure acts on it, the viewer draws it, and cuts
//! change it. Because every rest tet is positively oriented (the mesh reorders them at
//! load), the outward orientation of a face follows from which vertex of its tet it is
//! opposite: no geometric test is needed, so the orientation is exact even for slivers.

use crate::Vec3;

/// The three vertices (local indices) of the face opposite local vertex `k`, ordered
/// so that their normal (right-hand rule) points away from vertex `k` in a
/// positively oriented tet.
pub const OUTWARD_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// Outward boundary triangles of a tet mesh, with the tet each belongs to.
///
/// ```
/// use heml_core::mesh::generate::{box_mesh, HexSplit};
/// use heml_core::mesh::surface::BoundarySurface;
/// let mesh = box_mesh([1.0, 1.0, 1.0], [2, 2, 2], HexSplit::Six)?;
/// let s = BoundarySurface::of_mesh(mesh.tets());
/// // 6 sides × 4 quads × 2 triangles
/// assert_eq!(s.n_triangles(), 48);
/// assert!(s.is_closed());
/// // outward: the enclosed volume from the divergence theorem is the box's
/// assert!((s.enclosed_volume(mesh.nodes()) - 1.0).abs() < 1e-12);
/// # Ok::<(), heml_core::HemlError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct BoundarySurface {
    triangles: Vec<[u32; 3]>,
    owners: Vec<u32>,
    nodes: Vec<u32>,
}

impl BoundarySurface {
    /// Extracts the boundary of all the tets.
    pub fn of_mesh(tets: &[[u32; 4]]) -> Self {
        Self::of_tets(tets, |_| true)
    }

    /// Extracts the boundary of a mesh: of all its tets, or, when its tets overlap
    /// (several covers of the body, e.g. [`super::generate::HexSplit::Ten`]), of the
    /// tets of cover 0 alone, a conforming tiling whose boundary is a closed,
    /// consistently oriented manifold (see [`super::overlap`]).
    ///
    /// ```
    /// use heml_core::mesh::generate::{box_mesh, HexSplit};
    /// use heml_core::mesh::surface::BoundarySurface;
    /// let mesh = box_mesh([1.0, 1.0, 1.0], [2, 2, 2], HexSplit::Ten)?;
    /// let s = BoundarySurface::of_tet_mesh(&mesh);
    /// assert_eq!(s.n_triangles(), 48);
    /// assert!(s.is_closed());
    /// # Ok::<(), heml_core::HemlError>(())
    /// ```
    pub fn of_tet_mesh(mesh: &super::TetMesh) -> Self {
        Self::of_tets(mesh.tets(), |t| mesh.tet_cover(t) == 0)
    }

    /// Extracts the boundary of the tets for which `alive(t)` holds (e.g. the ones a
    /// cut left). Deterministic: triangles come sorted by owning tet, then by the
    /// local vertex they are opposite. Cost O(m log m) in the number of tets.
    pub fn of_tets(tets: &[[u32; 4]], alive: impl Fn(usize) -> bool) -> Self {
        // (sorted key, tet, local face): a face shared by two alive tets appears twice
        let mut faces: Vec<([u32; 3], u32, u8)> = Vec::with_capacity(4 * tets.len());
        for (t, tet) in tets.iter().enumerate() {
            if !alive(t) {
                continue;
            }
            for (k, f) in OUTWARD_FACES.iter().enumerate() {
                let mut key = f.map(|i| tet[i]);
                key.sort_unstable();
                faces.push((key, t as u32, k as u8));
            }
        }
        faces.sort_unstable();
        let mut once: Vec<(u32, u8)> = Vec::new();
        let mut i = 0;
        while i < faces.len() {
            let mut j = i + 1;
            while j < faces.len() && faces[j].0 == faces[i].0 {
                j += 1;
            }
            if j - i == 1 {
                once.push((faces[i].1, faces[i].2));
            }
            i = j;
        }
        once.sort_unstable();
        let triangles: Vec<[u32; 3]> = once
            .iter()
            .map(|&(t, k)| OUTWARD_FACES[k as usize].map(|i| tets[t as usize][i]))
            .collect();
        let owners = once.iter().map(|&(t, _)| t).collect();
        let mut nodes: Vec<u32> = triangles.iter().flatten().copied().collect();
        nodes.sort_unstable();
        nodes.dedup();
        Self {
            triangles,
            owners,
            nodes,
        }
    }

    /// The triangles, outward by the right-hand rule (node ids of the mesh).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The tet each triangle is a face of (parallel to [`Self::triangles`]).
    pub fn owners(&self) -> &[u32] {
        &self.owners
    }

    /// The distinct nodes on the surface, ascending.
    pub fn nodes(&self) -> &[u32] {
        &self.nodes
    }

    /// Number of triangles.
    pub fn n_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// Area-weighted outward normal (½ (b−a)×(c−a)) of triangle `i` at positions `x`.
    pub fn area_normal(&self, i: usize, x: &[Vec3]) -> Vec3 {
        let [a, b, c] = self.triangles[i].map(|n| x[n as usize]);
        0.5 * (b - a).cross(&(c - a))
    }

    /// Volume enclosed by the surface at positions `x` (divergence theorem); equals
    /// the total signed tet volume when the surface is closed and outward.
    pub fn enclosed_volume(&self, x: &[Vec3]) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|n| x[n as usize]);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Whether every directed edge is matched by its reverse exactly once: the
    /// surface is closed (watertight) and consistently oriented.
    pub fn is_closed(&self) -> bool {
        let mut edges: Vec<(u32, u32)> = Vec::with_capacity(3 * self.triangles.len());
        for t in &self.triangles {
            for k in 0..3 {
                edges.push((t[k], t[(k + 1) % 3]));
            }
        }
        edges.sort_unstable();
        if edges.windows(2).any(|w| w[0] == w[1]) {
            return false;
        }
        edges.iter().all(|&(a, b)| edges.binary_search(&(b, a)).is_ok())
    }
}

impl BoundarySurface {
    /// Triangles, owners and nodes, for a cut to update in place
    /// (`system::cut`): the caller keeps them parallel, the nodes sorted and
    /// distinct, and the triangles outward.
    pub(crate) fn parts_mut(&mut self) -> (&mut Vec<[u32; 3]>, &mut Vec<u32>, &mut Vec<u32>) {
        (&mut self.triangles, &mut self.owners, &mut self.nodes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::{box_mesh, HexSplit};

    #[test]
    fn single_tet_faces_point_outward() {
        let x = [Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()];
        let s = BoundarySurface::of_mesh(&[[0, 1, 2, 3]]);
        assert_eq!(s.n_triangles(), 4);
        assert!(s.is_closed());
        let centroid = (x[0] + x[1] + x[2] + x[3]) / 4.0;
        for i in 0..4 {
            let [a, ..] = s.triangles()[i].map(|n| x[n as usize]);
            assert!(
                s.area_normal(i, &x).dot(&(a - centroid)) > 0.0,
                "face {i} points inward"
            );
        }
        // the normals of a closed surface sum to zero
        let sum: Vec3 = (0..4).map(|i| s.area_normal(i, &x)).sum();
        assert!(sum.norm() < 1e-15);
    }

    #[test]
    fn removing_tets_opens_no_holes_and_keeps_volume() {
        let mesh = box_mesh([1.0, 2.0, 1.0], [3, 4, 2], HexSplit::Five).unwrap();
        for split in [HexSplit::Five, HexSplit::Six] {
            let mesh = box_mesh([1.0, 2.0, 1.0], [3, 4, 2], split).unwrap();
            let s = BoundarySurface::of_mesh(mesh.tets());
            assert!(s.is_closed());
            // outward and closed: enclosed volume = mesh volume (round-off of ~100 terms)
            assert!((s.enclosed_volume(mesh.nodes()) - mesh.total_volume()).abs() < 1e-12);
        }
        // drop every tet touching the plane y = 1: two closed pieces remain
        let cut = |t: usize| {
            let p = mesh.tet_points(t);
            let (lo, hi) = p
                .iter()
                .fold((f64::MAX, f64::MIN), |(l, h), q| (l.min(q.y), h.max(q.y)));
            !(lo < 1.0 && hi > 1.0)
        };
        let s = BoundarySurface::of_tets(mesh.tets(), cut);
        assert!(s.is_closed());
        let kept: f64 = (0..mesh.n_tets()).filter(|&t| cut(t)).map(|t| mesh.tet_volume(t)).sum();
        assert!((s.enclosed_volume(mesh.nodes()) - kept).abs() < 1e-12);
        assert!(s.owners().iter().all(|&t| cut(t as usize)));
    }
}
