//! The partition of a field's tets into small compact patches for the patch
//! volumetric term ([`super::patch_volume`]): disjoint, face-connected groups of
//! about k tets, each inside one block of the field's layout (so a block can sum
//! its patches' volumes from the positions it has gathered), made from the mesh
//! and the layout only (deterministic, independent of the thread count).
//!
//! Greedy clustering, block by block: the first unassigned tet in field (Morton)
//! order seeds a patch, which then takes, one at a time, the unassigned
//! face-neighbour in the block that adds the fewest new nodes (ties: the first in
//! field order) until it has k tets or no neighbour is left. Fewest new nodes keeps
//! the patch compact (on a hex split it prefers the tets around the hex's shared
//! diagonal). A patch left with fewer than k/2 tets joins its smallest face-adjacent
//! patch of the block, so no patch carries a near-element constraint.

use super::assembly::Layout;
use crate::error::{HemlError, Result};
use crate::mesh::TetMesh;
use std::collections::HashMap;

/// No patch yet.
const NONE: u32 = u32::MAX;

/// The patch of each field tet (`layout` order) for patches of about `k` tets, and
/// the number of patches.
pub(crate) fn partition(mesh: &TetMesh, layout: &Layout, k: usize) -> Result<(Vec<u32>, usize)> {
    if !(1..=64).contains(&k) {
        return Err(HemlError::Invalid(format!("patch size {k} must lie in 1..=64 tets")));
    }
    let n = layout.n_tets();
    let mut patch = vec![NONE; n];
    let mut sizes: Vec<usize> = Vec::new();
    for (s, e) in layout.block_ranges() {
        let tets: Vec<[u32; 4]> = (s..e).map(|p| mesh.tets()[layout.ids[p]]).collect();
        let adj = face_neighbours(&tets);
        let first = sizes.len();
        for seed in 0..tets.len() {
            if patch[s + seed] != NONE {
                continue;
            }
            let id = sizes.len() as u32;
            patch[s + seed] = id;
            let mut members = vec![seed];
            let mut nodes: Vec<u32> = tets[seed].to_vec();
            while members.len() < k {
                // the unassigned neighbour adding the fewest new nodes, first in order
                let mut best: Option<(usize, usize)> = None;
                for &m in &members {
                    for &q in &adj[m] {
                        if patch[s + q] != NONE {
                            continue;
                        }
                        let new = tets[q].iter().filter(|g| !nodes.contains(g)).count();
                        if best.is_none_or(|(bn, bq)| (new, q) < (bn, bq)) {
                            best = Some((new, q));
                        }
                    }
                }
                let Some((_, q)) = best else { break };
                patch[s + q] = id;
                members.push(q);
                nodes.extend(
                    tets[q]
                        .iter()
                        .filter(|g| !nodes.contains(g))
                        .copied()
                        .collect::<Vec<_>>(),
                );
            }
            sizes.push(members.len());
            if 2 * members.len() < k {
                // join the smallest face-adjacent patch of this block (first id on ties)
                let mut target: Option<(usize, u32)> = None;
                for &m in &members {
                    for &q in &adj[m] {
                        let o = patch[s + q];
                        if o != id && o != NONE && (o as usize) >= first {
                            let c = (sizes[o as usize], o);
                            if target.is_none_or(|t| c < t) {
                                target = Some(c);
                            }
                        }
                    }
                }
                if let Some((_, o)) = target {
                    for &m in &members {
                        patch[s + m] = o;
                    }
                    sizes[o as usize] += members.len();
                    sizes.pop();
                }
            }
        }
    }
    Ok((patch, sizes.len()))
}

/// Face neighbours of each tet of `tets` (indices into it), in increasing order.
fn face_neighbours(tets: &[[u32; 4]]) -> Vec<Vec<usize>> {
    let mut faces: HashMap<[u32; 3], usize> = HashMap::with_capacity(2 * tets.len());
    let mut adj = vec![Vec::new(); tets.len()];
    for (t, tet) in tets.iter().enumerate() {
        for skip in 0..4 {
            let mut f = [0u32; 3];
            let mut i = 0;
            for (a, &g) in tet.iter().enumerate() {
                if a != skip {
                    f[i] = g;
                    i += 1;
                }
            }
            f.sort_unstable();
            match faces.remove(&f) {
                Some(o) => {
                    adj[t].push(o);
                    adj[o].push(t);
                }
                None => {
                    faces.insert(f, t);
                }
            }
        }
    }
    for a in &mut adj {
        a.sort_unstable();
    }
    adj
}
