//! The per-frame data of the live view: surface positions in f32 and the colour
//! field at the surface vertices, plus the smallest volume ratio over all the tets.
//!
//! J and the energy density are evaluated on the tets that own a boundary triangle
//! only (one tet per surface triangle, a few per vertex) and averaged to the
//! vertices: the cost of a frame grows with the surface, not with the volume.

use heml::nalgebra::Matrix3;
use heml::system::System;
use heml::Vec3;

use super::protocol::FieldKind;

/// Precomputed rest data for the surface fields of one system.
pub struct SurfaceFields {
    /// Surface vertices (mesh node ids, sorted).
    nodes: Vec<u32>,
    /// Boundary tets (distinct owners of the surface triangles).
    owners: Vec<u32>,
    /// Inverse rest edge matrix Dm⁻¹ of each owner.
    dm_inv: Vec<Matrix3<f64>>,
    /// Region index of each owner (for the energy density's law).
    region_of: Vec<usize>,
    /// For vertex k, its owners are `adj[adj_start[k]..adj_start[k + 1]]` (indices into `owners`).
    adj_start: Vec<usize>,
    adj: Vec<u32>,
    /// 1 / (6 V) at rest of every tet (min J).
    inv_six_vol: Vec<f64>,
}

fn edges(x: &[Vec3], t: &[u32; 4]) -> Matrix3<f64> {
    let p0 = x[t[0] as usize];
    Matrix3::from_columns(&[x[t[1] as usize] - p0, x[t[2] as usize] - p0, x[t[3] as usize] - p0])
}

impl SurfaceFields {
    /// Rest data of `sys`'s current surface.
    pub fn new(sys: &System) -> Self {
        let mesh = sys.mesh();
        let rest = sys.rest_positions();
        let surface = sys.surface();
        let nodes = surface.nodes().to_vec();
        let mut owners: Vec<u32> = surface.owners().to_vec();
        owners.sort_unstable();
        owners.dedup();
        let dm_inv = owners
            .iter()
            .map(|&t| {
                edges(rest, &mesh.tets()[t as usize])
                    .try_inverse()
                    .unwrap_or_else(Matrix3::zeros)
            })
            .collect();
        // which region's law covers each owner tet: tagged regions first, then the untagged one
        let tags = mesh.tags();
        let region_of = owners
            .iter()
            .map(|&t| {
                let tag = tags.get(t as usize).copied();
                let regions = sys.regions();
                regions
                    .iter()
                    .position(|r| r.tag().is_some() && r.tag() == tag)
                    .or_else(|| regions.iter().position(|r| r.tag().is_none()))
                    .unwrap_or(0)
            })
            .collect();
        // vertex → owners adjacency (CSR), through the triangles
        let local = |n: u32| nodes.binary_search(&n).ok();
        let mut pairs: Vec<(usize, u32)> = Vec::new();
        for (tri, &owner) in surface.triangles().iter().zip(surface.owners()) {
            let o = owners.binary_search(&owner).unwrap_or(0) as u32;
            for &n in tri {
                if let Some(k) = local(n) {
                    pairs.push((k, o));
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut adj_start = vec![0; nodes.len() + 1];
        for &(k, _) in &pairs {
            adj_start[k + 1] += 1;
        }
        for k in 0..nodes.len() {
            adj_start[k + 1] += adj_start[k];
        }
        let adj = pairs.iter().map(|&(_, o)| o).collect();
        let inv_six_vol = mesh
            .tets()
            .iter()
            .map(|t| {
                let d = edges(rest, t).determinant();
                if d != 0.0 {
                    1.0 / d
                } else {
                    0.0
                }
            })
            .collect();
        SurfaceFields {
            nodes,
            owners,
            dm_inv,
            region_of,
            adj_start,
            adj,
            inv_six_vol,
        }
    }

    /// Surface vertices (mesh node ids) in frame order.
    pub fn nodes(&self) -> &[u32] {
        &self.nodes
    }

    /// Current positions of the surface vertices, f32 xyz.
    pub fn positions(&self, sys: &System) -> Vec<f32> {
        let x = sys.positions();
        self.nodes
            .iter()
            .flat_map(|&n| {
                let p = x[n as usize];
                [p.x as f32, p.y as f32, p.z as f32]
            })
            .collect()
    }

    /// `field` at every surface vertex.
    pub fn values(&self, sys: &System, field: FieldKind) -> Vec<f32> {
        let x = sys.positions();
        let rest = sys.rest_positions();
        match field {
            FieldKind::Displacement => self
                .nodes
                .iter()
                .map(|&n| (x[n as usize] - rest[n as usize]).norm() as f32)
                .collect(),
            FieldKind::J | FieldKind::Energy => {
                let tets = sys.mesh().tets();
                let opts = sys.force_options();
                let per_owner: Vec<f64> = self
                    .owners
                    .iter()
                    .zip(&self.dm_inv)
                    .zip(&self.region_of)
                    .map(|((&t, dm_inv), &r)| {
                        let f = edges(x, &tets[t as usize]) * dm_inv;
                        match field {
                            FieldKind::J => f.determinant(),
                            _ => sys.regions()[r]
                                .material()
                                .stress(&f, &opts)
                                .map_or(f64::NAN, |(w, _)| w),
                        }
                    })
                    .collect();
                (0..self.nodes.len())
                    .map(|k| {
                        let around = &self.adj[self.adj_start[k]..self.adj_start[k + 1]];
                        if around.is_empty() {
                            return 0.0;
                        }
                        (around.iter().map(|&o| per_owner[o as usize]).sum::<f64>() / around.len() as f64) as f32
                    })
                    .collect()
            }
        }
    }

    /// The smallest volume ratio J = det(Ds) / det(Dm) over the tets a cut left.
    pub fn min_j(&self, sys: &System) -> f64 {
        let x = sys.positions();
        sys.mesh()
            .tets()
            .iter()
            .zip(&self.inv_six_vol)
            .enumerate()
            .filter(|(k, _)| sys.tet_alive(*k))
            .map(|(_, (t, inv))| edges(x, t).determinant() * inv)
            .fold(f64::INFINITY, f64::min)
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use heml::prelude::*;

    /// A neo-Hookean cube of `size` m in 2 × 2 × 2 cells, clamped at x = 0 when `clamp`.
    pub(in crate::cli::view) fn block(size: f64, clamp: bool) -> System {
        let mesh = heml::mesh::generate::box_mesh([size; 3], [2, 2, 2], heml::mesh::generate::HexSplit::Six).unwrap();
        let b = heml::system(mesh)
            .material("neo_hookean", Params::from([("E", 1e4), ("nu", 0.3)]))
            .unwrap();
        let b = if clamp { b.fix_where(|p| p.x < 1e-9) } else { b };
        b.build().unwrap()
    }

    #[test]
    fn a_uniform_stretch_gives_its_j_and_displacement_everywhere() {
        let mut sys = block(1.0, false);
        let f = SurfaceFields::new(&sys);
        // rest: J = 1, no displacement, no energy
        assert!(f.values(&sys, FieldKind::J).iter().all(|&j| (j - 1.0).abs() < 1e-6));
        assert!(f.values(&sys, FieldKind::Energy).iter().all(|&w| w.abs() < 1e-6));
        // x → 1.1 x: J = 1.1 in every tet (f32 round-off: 1e-6), |u| = 0.1 |X|
        for p in sys.positions_mut() {
            p.x *= 1.1;
        }
        assert!(f.values(&sys, FieldKind::J).iter().all(|&j| (j - 1.1).abs() < 1e-6));
        assert!((f.min_j(&sys) - 1.1).abs() < 1e-12);
        let u = f.values(&sys, FieldKind::Displacement);
        for (k, &n) in f.nodes().iter().enumerate() {
            let expect = 0.1 * sys.rest_positions()[n as usize].x;
            assert!((u[k] as f64 - expect).abs() < 1e-6);
        }
        assert!(f.values(&sys, FieldKind::Energy).iter().all(|&w| w > 0.0));
        assert_eq!(f.positions(&sys).len(), 3 * f.nodes().len());
    }
}
