//! What a cut needs to stay local: which tets are alive, each tet's neighbours across
//! its faces, its region, the alive tets per node, and where each boundary face sits
//! in the system's [`BoundarySurface`]. Built once, on the first cut (or by
//! [`crate::system::System::prepare_cutting`]), in O(n log n); every cut then costs
//! O(removed tets) here.

use crate::mesh::surface::{BoundarySurface, OUTWARD_FACES};
use rayon::slice::ParallelSliceMut;

/// No neighbour (a boundary face of the mesh).
pub(crate) const NONE: u32 = u32::MAX;

/// The cut state of a system: empty until the first cut.
#[derive(Debug, Default)]
pub(crate) struct CutState {
    pub(crate) topo: Option<Box<Topology>>,
    /// Bumped by every cut; lets caches built on the tet set notice
    /// ([`crate::system::System::topology_version`]).
    pub(crate) version: u64,
}

/// See the module docs.
#[derive(Debug)]
pub(crate) struct Topology {
    pub(crate) alive: Vec<bool>,
    pub(crate) n_alive: usize,
    /// Neighbour across the face opposite local vertex k, or [`NONE`].
    pub(crate) neighbors: Vec<[u32; 4]>,
    /// Region index per tet.
    pub(crate) region_of: Vec<u32>,
    /// Alive tets per node.
    pub(crate) tet_count: Vec<u32>,
    /// Boundary face `4 t + k` → its index in the surface, or [`NONE`].
    slot: Vec<u32>,
    /// Surface triangles per node.
    surf_count: Vec<u32>,
    /// Tets whose faces never join the surface (covers other than 0 of a mesh whose
    /// tets overlap, see [`crate::mesh::overlap`]); empty when there are none.
    pub(crate) off_surface: Vec<bool>,
}

impl Topology {
    /// The topology of `tets` (all alive), whose tet `t` belongs to region
    /// `region_of[t]`, with its boundary `surface`.
    pub(crate) fn new(tets: &[[u32; 4]], n_nodes: usize, region_of: Vec<u32>, surface: &BoundarySurface) -> Topology {
        let mut faces: Vec<([u32; 3], u32, u8)> = Vec::with_capacity(4 * tets.len());
        let mut tet_count = vec![0u32; n_nodes];
        for (t, tet) in tets.iter().enumerate() {
            for &i in tet {
                tet_count[i as usize] += 1;
            }
            for (k, f) in OUTWARD_FACES.iter().enumerate() {
                let mut key = f.map(|i| tet[i]);
                key.sort_unstable();
                faces.push((key, t as u32, k as u8));
            }
        }
        faces.par_sort_unstable();
        let mut neighbors = vec![[NONE; 4]; tets.len()];
        for w in faces.windows(2) {
            if w[0].0 == w[1].0 {
                neighbors[w[0].1 as usize][w[0].2 as usize] = w[1].1;
                neighbors[w[1].1 as usize][w[1].2 as usize] = w[0].1;
            }
        }
        let mut slot = vec![NONE; 4 * tets.len()];
        let mut surf_count = vec![0u32; n_nodes];
        for (i, (tri, &owner)) in surface.triangles().iter().zip(surface.owners()).enumerate() {
            slot[face_key(owner, local_face(&tets[owner as usize], tri))] = i as u32;
            for &n in tri {
                surf_count[n as usize] += 1;
            }
        }
        Topology {
            alive: vec![true; tets.len()],
            n_alive: tets.len(),
            neighbors,
            region_of,
            tet_count,
            slot,
            surf_count,
            off_surface: Vec::new(),
        }
    }

    /// Updates `surface` for the tets `removed`, already marked dead: their boundary
    /// faces leave it, and their faces shared with alive tets join it, oriented
    /// outward from those tets. O(removed); the triangles' order is no longer sorted
    /// by owner (a removed face's slot is filled by the last triangle).
    pub(crate) fn update_surface(&mut self, tets: &[[u32; 4]], removed: &[usize], surface: &mut BoundarySurface) {
        let mut touched: Vec<u32> = Vec::new();
        for &t in removed {
            for k in 0..4 {
                let i = std::mem::replace(&mut self.slot[face_key(t as u32, k)], NONE);
                if i != NONE {
                    let (tris, owners, _) = surface.parts_mut();
                    let gone = tris.swap_remove(i as usize);
                    owners.swap_remove(i as usize);
                    if let (Some(tri), Some(&owner)) = (tris.get(i as usize), owners.get(i as usize)) {
                        let moved = face_key(owner, local_face(&tets[owner as usize], tri));
                        self.slot[moved] = i;
                    }
                    for n in gone {
                        self.surf_count[n as usize] -= 1;
                        touched.push(n);
                    }
                }
                let u = self.neighbors[t][k];
                if u != NONE && self.alive[u as usize] && !self.off_surface.get(u as usize).copied().unwrap_or(false) {
                    let ku = self.neighbors[u as usize]
                        .iter()
                        .position(|&v| v == t as u32)
                        .unwrap_or(0);
                    let tri = OUTWARD_FACES[ku].map(|a| tets[u as usize][a]);
                    let (tris, owners, _) = surface.parts_mut();
                    self.slot[face_key(u, ku)] = tris.len() as u32;
                    tris.push(tri);
                    owners.push(u);
                    for n in tri {
                        self.surf_count[n as usize] += 1;
                        touched.push(n);
                    }
                }
            }
        }
        touched.sort_unstable();
        touched.dedup();
        let (_, _, nodes) = surface.parts_mut();
        for n in touched {
            let on = self.surf_count[n as usize] > 0;
            match (nodes.binary_search(&n), on) {
                (Err(p), true) => nodes.insert(p, n),
                (Ok(p), false) => {
                    nodes.remove(p);
                }
                _ => {}
            }
        }
    }

    /// Connected components of the alive tets (through shared faces): the component
    /// of each tet (`usize::MAX` for removed ones) and their number.
    pub(crate) fn components(&self) -> (Vec<usize>, usize) {
        let mut comp = vec![usize::MAX; self.alive.len()];
        let mut n = 0;
        let mut stack = Vec::new();
        for s in 0..self.alive.len() {
            if !self.alive[s] || comp[s] != usize::MAX {
                continue;
            }
            comp[s] = n;
            stack.push(s);
            while let Some(t) = stack.pop() {
                for &u in &self.neighbors[t] {
                    if u != NONE && self.alive[u as usize] && comp[u as usize] == usize::MAX {
                        comp[u as usize] = n;
                        stack.push(u as usize);
                    }
                }
            }
            n += 1;
        }
        (comp, n)
    }
}

fn face_key(t: u32, k: usize) -> usize {
    4 * t as usize + k
}

/// The local vertex of `tet` that triangle `tri` (one of its faces) is opposite.
fn local_face(tet: &[u32; 4], tri: &[u32; 3]) -> usize {
    (0..4).find(|&k| !tri.contains(&tet[k])).unwrap_or(0)
}
