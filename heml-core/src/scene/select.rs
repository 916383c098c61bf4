//! Boundary selections: which nodes a `[[fix]]`, `[[prescribe]]` or
//! `[[loads.nodal]]` entry acts on.

use super::schema::{BoxSpec, FixSpec, NodalLoadSpec, PlaneSpec, PrescribeSpec};
use crate::error::{HemlError, Result};
use crate::mesh::TetMesh;
use crate::Vec3;

/// One way of selecting nodes (positions in metres, on the scaled mesh).
#[derive(Debug, Clone, PartialEq)]
pub enum Selection {
    /// Explicit node ids.
    Nodes(Vec<usize>),
    /// Nodes inside an axis-aligned box.
    Box(BoxSpec),
    /// Nodes within a distance of a plane.
    Plane(PlaneSpec),
    /// Nodes of the tets carrying a mesh tag.
    Tag(i32),
    /// A named node set of the mesh file ([`TetMesh::node_set`]).
    NodeSet(String),
}

impl Selection {
    /// Short name of the selector (`nodes`, `box`, `plane`, `tag`, `node_set`).
    pub fn kind(&self) -> &'static str {
        match self {
            Selection::Nodes(_) => "nodes",
            Selection::Box(_) => "box",
            Selection::Plane(_) => "plane",
            Selection::Tag(_) => "tag",
            Selection::NodeSet(_) => "node_set",
        }
    }

    /// Builds a selection from the optional selector keys of an entry: exactly one
    /// must be given. `what` names the entry in errors (e.g. `[[fix]] #2`).
    pub fn from_keys(
        what: &str,
        nodes: &Option<Vec<usize>>,
        bbox: &Option<BoxSpec>,
        plane: &Option<PlaneSpec>,
        tag: &Option<i32>,
        node_set: &Option<String>,
    ) -> Result<Selection> {
        let mut found = Vec::new();
        if let Some(n) = nodes {
            found.push(Selection::Nodes(n.clone()));
        }
        if let Some(b) = bbox {
            found.push(Selection::Box(*b));
        }
        if let Some(p) = plane {
            found.push(Selection::Plane(*p));
        }
        if let Some(t) = tag {
            found.push(Selection::Tag(*t));
        }
        if let Some(name) = node_set {
            found.push(Selection::NodeSet(name.clone()));
        }
        match found.len() {
            1 => Ok(found.remove(0)),
            0 => Err(HemlError::Invalid(format!(
                "{what}: no selector; give exactly one of nodes = [ids], box = {{ min, max }}, \
                 plane = {{ point, normal, tolerance }}, tag = N, node_set = \"name\""
            ))),
            _ => Err(HemlError::Invalid(format!(
                "{what}: several selectors ({}); give exactly one",
                found.iter().map(Selection::kind).collect::<Vec<_>>().join(", ")
            ))),
        }
    }

    /// The selected node ids, sorted and without duplicates. Selecting no node is
    /// an error naming `what`, the selector and the mesh's extent.
    pub fn resolve(&self, what: &str, mesh: &TetMesh) -> Result<Vec<usize>> {
        let n = mesh.n_nodes();
        let (lo, hi) = mesh.bounding_box();
        let diag = (hi - lo).norm();
        let nodes = mesh.nodes();
        let err = |detail: String| HemlError::Invalid(format!("{what} ({}) {detail}", self.kind()));
        let finite = |v: &[f64]| v.iter().all(|c| c.is_finite());
        let mut ids: Vec<usize> = match self {
            Selection::Nodes(ids) => {
                if let Some(&bad) = ids.iter().find(|&&i| i >= n) {
                    return Err(err(format!(
                        "names node {bad}, but the mesh has {n} nodes (ids 0..{})",
                        n.saturating_sub(1)
                    )));
                }
                ids.clone()
            }
            Selection::Box(b) => {
                if !finite(&b.min) || !finite(&b.max) {
                    return Err(err("has non-finite corners".into()));
                }
                let eps = 1e-9 * diag;
                (0..n)
                    .filter(|&i| (0..3).all(|k| nodes[i][k] >= b.min[k] - eps && nodes[i][k] <= b.max[k] + eps))
                    .collect()
            }
            Selection::Plane(p) => {
                let normal = Vec3::from(p.normal);
                let len = normal.norm();
                if !(finite(&p.point) && len.is_finite() && len > 0.0) {
                    return Err(err("needs a finite point and a non-zero finite normal".into()));
                }
                let tol = p.tolerance.unwrap_or(1e-6 * diag);
                if !(tol.is_finite() && tol >= 0.0) {
                    return Err(err(format!("tolerance {tol} must be a finite number >= 0")));
                }
                let unit = normal / len;
                let point = Vec3::from(p.point);
                (0..n).filter(|&i| (nodes[i] - point).dot(&unit).abs() <= tol).collect()
            }
            Selection::Tag(tag) => {
                let tets = mesh.tets_with_tag(*tag);
                if tets.is_empty() {
                    return Err(err(format!(
                        "selects no node: no tet has tag {tag} (the mesh's tags are {:?})",
                        mesh.distinct_tags()
                    )));
                }
                tets.iter()
                    .flat_map(|&t| mesh.tets()[t].iter().map(|&i| i as usize))
                    .collect()
            }
            Selection::NodeSet(name) => match mesh.node_set(name) {
                Some(ids) => ids.to_vec(),
                None if mesh.node_sets().is_empty() => {
                    return Err(err(format!(
                        "names the node set '{name}', but the mesh file has no node sets (Gmsh files give \
                         their physical points, curves and surfaces by name, Medit files their boundary \
                         references as \"surface N\", an OpenSurgSim .ply its \"boundary_condition\" nodes)"
                    )))
                }
                None => {
                    return Err(err(format!(
                        "names the node set '{name}'; the mesh file's node sets are {:?}",
                        mesh.node_sets().keys().collect::<Vec<_>>()
                    )))
                }
            },
        };
        ids.sort_unstable();
        ids.dedup();
        if ids.is_empty() {
            return Err(err(format!(
                "selects no node; the mesh spans [{:.6e}, {:.6e}, {:.6e}] to [{:.6e}, {:.6e}, {:.6e}] (metres)",
                lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
            )));
        }
        Ok(ids)
    }
}

impl FixSpec {
    /// The selection of this entry.
    pub fn selection(&self, what: &str) -> Result<Selection> {
        Selection::from_keys(what, &self.nodes, &self.bbox, &self.plane, &self.tag, &self.node_set)
    }
}

impl PrescribeSpec {
    /// The selection of this entry.
    pub fn selection(&self, what: &str) -> Result<Selection> {
        Selection::from_keys(what, &self.nodes, &self.bbox, &self.plane, &self.tag, &self.node_set)
    }
}

impl NodalLoadSpec {
    /// The selection of this entry.
    pub fn selection(&self, what: &str) -> Result<Selection> {
        Selection::from_keys(what, &self.nodes, &self.bbox, &self.plane, &self.tag, &self.node_set)
    }
}
