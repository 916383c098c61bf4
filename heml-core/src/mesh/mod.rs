//! Tetrahedral meshes: validated at construction, every rest tetrahedron positively
//! oriented (reordered at load) and non-degenerate.

pub mod generate;
pub mod hex_split;
pub mod overlap;
pub mod quality;
pub mod reorder;
pub mod surface;

use crate::error::{HemlError, Result};
use crate::Vec3;

/// How far below `l_max³` six times a tet's volume may fall before the tet counts
/// as degenerate. Real organ meshes have slivers with radius ratio ~0.01, whose
/// 6·vol/l_max³ is ~1e-3; 1e-12 only catches flat or collapsed elements, whose
/// rest-state inverse would be meaningless.
pub const DEGENERACY_TOLERANCE: f64 = 1e-12;

/// A linear tetrahedral mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct TetMesh {
    nodes: Vec<Vec3>,
    tets: Vec<[u32; 4]>,
    tags: Vec<i32>,
    reoriented: usize,
    /// Named 3-vector fields per tet read from the file's cell data (fibre
    /// directions, say), in tet order.
    cell_vectors: std::collections::BTreeMap<String, Vec<Vec3>>,
    /// Per-tet weights and covers when tets overlap (see [`overlap`]).
    overlap: Option<overlap::Overlap>,
    /// Named node sets of the mesh file (sorted ids, no repeats): a scene's
    /// `node_set = "name"` selects one.
    node_sets: std::collections::BTreeMap<String, Vec<usize>>,
}

impl TetMesh {
    /// Builds a mesh, every tet tagged 0. See [`TetMesh::with_tags`].
    pub fn new(nodes: Vec<Vec3>, tets: Vec<[usize; 4]>) -> Result<Self> {
        let n = tets.len();
        Self::with_tags(nodes, tets, vec![0; n])
    }

    /// Builds a mesh from plain arrays.
    ///
    /// ```
    /// use heml_core::TetMesh;
    /// let mesh = TetMesh::from_arrays(
    ///     &[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]],
    ///     &[[0, 1, 2, 3]],
    /// ).unwrap();
    /// assert!((mesh.total_volume() - 1.0 / 6.0).abs() < 1e-15);
    /// ```
    pub fn from_arrays(nodes: &[[f64; 3]], tets: &[[usize; 4]]) -> Result<Self> {
        Self::new(nodes.iter().map(|p| Vec3::from(*p)).collect(), tets.to_vec())
    }

    /// Builds a mesh with a region tag per tet (e.g. Gmsh physical groups).
    ///
    /// Checks that coordinates are finite, that indices are in range and distinct
    /// within a tet, and that no rest tet is degenerate (all offending ids are
    /// reported). Negatively oriented tets are reordered (nodes 2 and 3 swapped) so
    /// that every rest volume is positive; [`TetMesh::reoriented_count`] tells how many.
    pub fn with_tags(nodes: Vec<Vec3>, tets: Vec<[usize; 4]>, tags: Vec<i32>) -> Result<Self> {
        if tags.len() != tets.len() {
            return Err(HemlError::SizeMismatch {
                what: "tet tags",
                got: tags.len(),
                expected: tets.len(),
            });
        }
        if nodes.len() > u32::MAX as usize {
            return Err(HemlError::Mesh(format!(
                "{} nodes exceed the supported 2^32 - 1",
                nodes.len()
            )));
        }
        if let Some(i) = nodes.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(HemlError::Mesh(format!(
                "node {i} has a non-finite coordinate {:?}",
                nodes[i].as_slice()
            )));
        }
        if tets.is_empty() {
            return Err(HemlError::Mesh(format!(
                "no tetrahedra ({} nodes, 0 tets): a mesh needs at least one tetrahedron",
                nodes.len()
            )));
        }
        let mut out = Vec::with_capacity(tets.len());
        let mut degenerate = Vec::new();
        let mut overflow = Vec::new();
        let mut reoriented = 0;
        for (t, tet) in tets.iter().enumerate() {
            if let Some(&bad) = tet.iter().find(|&&i| i >= nodes.len()) {
                return Err(HemlError::Mesh(format!(
                    "tet {t} refers to node {bad}, but the mesh has {} nodes (ids 0..{})",
                    nodes.len(),
                    nodes.len().saturating_sub(1)
                )));
            }
            let mut idx = tet.map(|i| i as u32);
            let six_vol = signed_six_volume(&nodes, &idx);
            let lmax = max_edge_length(&nodes, &idx);
            let scale = lmax.powi(3);
            // Finite coordinates can still overflow: at ~1e103 m the cubed edge length
            // is infinite, and inf − inf in the triple product gives NaN. Such a tet is
            // not degenerate, it is out of range; say so.
            if !(six_vol.is_finite() && scale.is_finite()) {
                overflow.push(t);
                continue;
            }
            // written so that NaN fails it (a NaN comparison is false)
            let sound = six_vol.abs() > DEGENERACY_TOLERANCE * scale && lmax > 0.0;
            if !sound {
                degenerate.push(t);
                continue;
            }
            if six_vol < 0.0 {
                idx.swap(2, 3);
                reoriented += 1;
            }
            out.push(idx);
        }
        if !overflow.is_empty() {
            return Err(HemlError::Mesh(format!(
                "{} rest tet(s) whose volume is not finite (overflow: coordinates too large, \
                 e.g. a wrong unit scale; |x| must stay well below 1e100): ids {}",
                overflow.len(),
                list_ids(&overflow)
            )));
        }
        if !degenerate.is_empty() {
            return Err(HemlError::Mesh(format!(
                "{} degenerate rest tet(s) (zero volume or repeated nodes): ids {}",
                degenerate.len(),
                list_ids(&degenerate)
            )));
        }
        Ok(TetMesh {
            nodes,
            tets: out,
            tags,
            reoriented,
            cell_vectors: Default::default(),
            overlap: None,
            node_sets: Default::default(),
        })
    }

    /// Rest positions of the nodes.
    pub fn nodes(&self) -> &[Vec3] {
        &self.nodes
    }
    /// Node indices of each tet, positively oriented.
    pub fn tets(&self) -> &[[u32; 4]] {
        &self.tets
    }
    /// Region tag of each tet.
    pub fn tags(&self) -> &[i32] {
        &self.tags
    }
    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }
    /// Number of tets.
    pub fn n_tets(&self) -> usize {
        self.tets.len()
    }
    /// How many tets were reordered at construction because their input orientation
    /// was negative.
    pub fn reoriented_count(&self) -> usize {
        self.reoriented
    }

    /// The four rest positions of tet `t`.
    pub fn tet_points(&self, t: usize) -> [Vec3; 4] {
        corners(&self.nodes, &self.tets[t])
    }

    /// Rest volume of tet `t` (positive): its geometric volume, whatever its
    /// weight (see [`TetMesh::weighted_volume`]).
    pub fn tet_volume(&self, t: usize) -> f64 {
        signed_six_volume(&self.nodes, &self.tets[t]) / 6.0
    }

    /// Total rest volume of the body, Σ ω_k·Vol_k (overlapping tets count with
    /// their weight ω, see [`overlap`]).
    pub fn total_volume(&self) -> f64 {
        (0..self.n_tets()).map(|t| self.weighted_volume(t)).sum()
    }

    /// Lumped masses m_i = Σ ρ·ω_k·Vol_k / 4 over the tets k around node i
    /// (ω_k = 1 unless tets overlap, see [`overlap`]).
    pub fn lumped_masses(&self, density: f64) -> Vec<f64> {
        let mut m = vec![0.0; self.n_nodes()];
        for t in 0..self.n_tets() {
            let share = density * self.weighted_volume(t) / 4.0;
            for &i in &self.tets[t] {
                m[i as usize] += share;
            }
        }
        m
    }

    /// Nodes that belong to no tet (they get no mass and no elastic force).
    pub fn unreferenced_nodes(&self) -> Vec<usize> {
        let mut used = vec![false; self.n_nodes()];
        for tet in &self.tets {
            for &i in tet {
                used[i as usize] = true;
            }
        }
        used.iter().enumerate().filter(|(_, u)| !**u).map(|(i, _)| i).collect()
    }

    /// Axis-aligned bounding box (min, max) of the rest nodes.
    pub fn bounding_box(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::repeat(f64::INFINITY);
        let mut hi = Vec3::repeat(f64::NEG_INFINITY);
        for p in &self.nodes {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (lo, hi)
    }

    /// The same mesh with every coordinate multiplied by `factor` (unit conversion,
    /// e.g. 0.001 for millimetres → metres). The result is validated again: a
    /// factor such as 1e300 overflows coordinates or volumes, and 1e-300 collapses
    /// them, which must be an error rather than a mesh with NaN volumes.
    pub fn scaled(&self, factor: f64) -> Result<TetMesh> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(HemlError::Invalid(format!(
                "scale factor {factor} must be positive and finite"
            )));
        }
        let nodes = self.nodes.iter().map(|p| p * factor).collect();
        let tets = self.tets.iter().map(|t| t.map(|i| i as usize)).collect();
        let mut out = Self::with_tags(nodes, tets, self.tags.clone())
            .map_err(|e| HemlError::Invalid(format!("scaling the mesh by {factor:e}: {e}")))?;
        out.reoriented = self.reoriented;
        out.cell_vectors = self.cell_vectors.clone();
        out.overlap = self.overlap.clone();
        out.node_sets = self.node_sets.clone();
        Ok(out)
    }

    /// The 3-vector cell fields of the mesh file (e.g. fibre directions), by name,
    /// one vector per tet in tet order.
    pub fn cell_vectors(&self) -> &std::collections::BTreeMap<String, Vec<Vec3>> {
        &self.cell_vectors
    }

    /// The mesh with the 3-vector cell field `name` (one vector per tet).
    pub fn with_cell_vectors(mut self, name: impl Into<String>, values: Vec<Vec3>) -> Result<Self> {
        if values.len() != self.n_tets() {
            return Err(HemlError::SizeMismatch {
                what: "cell vectors",
                got: values.len(),
                expected: self.n_tets(),
            });
        }
        self.cell_vectors.insert(name.into(), values);
        Ok(self)
    }

    /// The named node sets of the mesh file (e.g. the `boundary_condition` nodes of
    /// an OpenSurgSim `.ply`), each sorted without repeats.
    pub fn node_sets(&self) -> &std::collections::BTreeMap<String, Vec<usize>> {
        &self.node_sets
    }

    /// The node set `name`, if the mesh has it.
    pub fn node_set(&self, name: &str) -> Option<&[usize]> {
        self.node_sets.get(name).map(Vec::as_slice)
    }

    /// The mesh with the node set `name` (node ids; sorted and deduplicated here).
    /// An id outside the mesh is an error naming it.
    ///
    /// ```
    /// use heml_core::mesh::generate::{box_mesh, HexSplit};
    /// let mesh = box_mesh([1.0; 3], [1, 1, 1], HexSplit::Six).unwrap();
    /// let mesh = mesh.with_node_set("base", vec![3, 0, 1, 2, 0]).unwrap();
    /// assert_eq!(mesh.node_set("base"), Some(&[0, 1, 2, 3][..]));
    /// assert!(mesh.clone().with_node_set("far", vec![8]).is_err()); // 8 nodes: ids 0..7
    /// ```
    pub fn with_node_set(mut self, name: impl Into<String>, mut ids: Vec<usize>) -> Result<Self> {
        let name = name.into();
        if let Some(&bad) = ids.iter().find(|&&i| i >= self.n_nodes()) {
            return Err(HemlError::Mesh(format!(
                "node set '{name}' names node {bad}, but the mesh has {} nodes",
                self.n_nodes()
            )));
        }
        ids.sort_unstable();
        ids.dedup();
        self.node_sets.insert(name, ids);
        Ok(self)
    }

    /// Indices of the tets whose tag is `tag`.
    pub fn tets_with_tag(&self, tag: i32) -> Vec<usize> {
        (0..self.n_tets()).filter(|&t| self.tags[t] == tag).collect()
    }

    /// The distinct tags, sorted.
    pub fn distinct_tags(&self) -> Vec<i32> {
        let mut t = self.tags.clone();
        t.sort_unstable();
        t.dedup();
        t
    }
}

/// The first 20 ids, comma-separated, then "…" if there are more.
fn list_ids(ids: &[usize]) -> String {
    let shown: Vec<String> = ids.iter().take(20).map(|t| t.to_string()).collect();
    format!("{}{}", shown.join(", "), if ids.len() > 20 { ", …" } else { "" })
}

/// The positions in `x` of the corners `t` of a tet. Plain indexing, always
/// inlined: an array `map` with a capturing closure was not inlined in hot loops
/// (~30 ns a tet in the implicit step's inverted-tet count, session 19).
#[inline(always)]
pub(crate) fn corners(x: &[Vec3], t: &[u32; 4]) -> [Vec3; 4] {
    [x[t[0] as usize], x[t[1] as usize], x[t[2] as usize], x[t[3] as usize]]
}

fn signed_six_volume(nodes: &[Vec3], idx: &[u32; 4]) -> f64 {
    let p = corners(nodes, idx);
    (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0])))
}

fn max_edge_length(nodes: &[Vec3], idx: &[u32; 4]) -> f64 {
    let p = corners(nodes, idx);
    crate::rest::EDGES
        .iter()
        .map(|&(a, b)| (p[b] - p[a]).norm())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reorients_negative_tets() {
        let m = TetMesh::from_arrays(
            &[[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]],
            &[[0, 2, 1, 3]],
        )
        .unwrap();
        assert_eq!(m.reoriented_count(), 1);
        assert!(m.tet_volume(0) > 0.0);
    }

    #[test]
    fn rejects_bad_indices_and_degenerate_tets_with_ids() {
        let nodes = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.], [1., 1., 0.]];
        let e = TetMesh::from_arrays(&nodes, &[[0, 1, 2, 7]]).unwrap_err().to_string();
        assert!(e.contains("tet 0") && e.contains("node 7"), "{e}");
        let e = TetMesh::from_arrays(&nodes, &[[0, 1, 2, 3], [0, 1, 2, 4], [0, 0, 2, 3]])
            .unwrap_err()
            .to_string();
        assert!(e.contains("2 degenerate") && e.contains("ids 1, 2"), "{e}");
        let e = TetMesh::from_arrays(&[[0., f64::NAN, 0.]], &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("node 0"), "{e}");
    }

    #[test]
    fn a_mesh_without_tets_is_refused() {
        // accepted before (an empty body: inverted bounding box, empty frames)
        let e = TetMesh::from_arrays(&[[0., 0., 0.], [1., 0., 0.]], &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("no tetrahedra") && e.contains("2 nodes"), "{e}");
        assert!(TetMesh::from_arrays(&[], &[]).is_err());
    }

    #[test]
    fn overflowing_rest_volumes_are_refused_as_overflow_not_degenerate() {
        let unit = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]];
        // ×1e200: finite coordinates, but l_max³ and the triple product overflow to
        // inf/NaN; the NaN volume used to pass the degeneracy test (a NaN comparison
        // is false). ×1e150 used to be called "degenerate".
        for factor in [1e200, 1e150] {
            let big: Vec<[f64; 3]> = unit.iter().map(|p| p.map(|c| c * factor)).collect();
            let mut nodes = unit.to_vec();
            nodes.extend(big);
            let e = TetMesh::from_arrays(&nodes, &[[0, 1, 2, 3], [4, 5, 6, 7]])
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("not finite") && e.contains("overflow") && e.contains("ids 1") && !e.contains("degenerate"),
                "×{factor:e}: {e}"
            );
        }
        // scaling a valid mesh into overflow is caught the same way
        let m = TetMesh::from_arrays(&unit, &[[0, 1, 2, 3]]).unwrap();
        for factor in [1e300, 1e120] {
            let e = m.scaled(factor).unwrap_err().to_string();
            assert!(
                e.contains("scaling the mesh") && e.contains("overflow") && e.contains("ids 0"),
                "{e}"
            );
        }
        // a normal unit conversion still works (volume to a few ulps: 1e-3 is inexact)
        let v = m.scaled(1e-3).unwrap().tet_volume(0);
        assert!((v - 1e-9 / 6.0).abs() <= 1e-24, "{v}");
        // the largest scale that still works is accepted with a finite volume
        let ok: Vec<[f64; 3]> = unit.iter().map(|p| p.map(|c| c * 1e100)).collect();
        let m = TetMesh::from_arrays(&ok, &[[0, 1, 2, 3]]).unwrap();
        assert!(m.tet_volume(0).is_finite() && m.tet_volume(0) > 0.0);
    }
}
