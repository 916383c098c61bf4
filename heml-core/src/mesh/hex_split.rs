//! Hexahedra of an unstructured mesh (read from a file) cut into tetrahedra, so
//! that hex meshes load instead of being refused.
//!
//! A structured grid ([`super::generate`]) can cut every cell the same way; an
//! unstructured hex mesh has no global axes, and two hexes sharing a face must cut
//! it along the same diagonal or the tets do not conform (a crack or an overlap
//! along the face). Each split therefore decides from data both hexes see alike:
//!
//! * [`HexSplit::Six`] — every quadrilateral face is cut along the diagonal through
//!   its corner of smallest node id, and the hex is the cone from its own
//!   smallest-id corner over the six triangles of the three faces away from it
//!   (the faces through that corner are cut through it, as the rule says). Six
//!   tets per hex, always conforming (Dompierre et al. 1999, "How to subdivide
//!   pyramids, prisms and hexahedra into tetrahedra", use the same rule).
//! * [`HexSplit::Five`] — the corners are 2-coloured along the hex edges over the
//!   whole mesh; the central tet joins the four corners of colour 1 and each
//!   colour-0 corner gets a corner tet, so every face is cut along its colour-1
//!   diagonal, from both sides. A structured grid is always 2-colourable; a mesh
//!   whose edge graph has an odd cycle is not, and is refused with the hex where
//!   the colouring fails (use `six`).
//! * [`HexSplit::Ten`] — the same colouring, and both five-tet cuttings of each
//!   hex: the first five tets (cover 0) as `five`, the last five (cover 1) its
//!   mirror with the central tet on the colour-0 corners; each cover conforms on
//!   its own. The tets overlap and weigh ½ each ([`HexSplit::overlap`]).
//! * [`HexSplit::TwentyFour`] — a node at each face centre (shared by the two hexes
//!   of the face) and one at the hex centre; each face is cut into four triangles
//!   around its centre, each joined to the hex centre. Conforming without any
//!   choice, no preferred direction; adds nodes after the file's.
//!
//! In a file that mixes tets and hexes, a tet glued to a hex face conforms only
//! if its face is one of the two triangles the split makes (for `six`: the
//! diagonal through the face's smallest node id); meshers put pyramids there.
//!
//! Hex corners are given in the VTK / Gmsh order (bottom face 0-1-2-3 counter-
//! clockwise seen from above, top face 4-5-6-7 above them).

use std::collections::HashMap;

use super::generate::HexSplit;
use crate::Vec3;

/// Hex corner (VTK / Gmsh order) of each cube corner `b`, where the bits of `b`
/// are the corner's (x, y, z) in the hex's own frame: corners differing by one
/// bit share an edge.
const HEX_OF_BIT: [usize; 8] = [0, 1, 3, 2, 4, 5, 7, 6];

/// The faces of a cube as (axis bit, the two other bits).
const AXES: [(usize, usize, usize); 3] = [(1, 2, 4), (2, 4, 1), (4, 1, 2)];

/// The four corners (cube bits) of the face normal to `axis` on `side`, in cyclic order.
fn ring(axis: usize, side: bool, u: usize, v: usize) -> [usize; 4] {
    let o = if side { axis } else { 0 };
    [o, o | u, o | u | v, o | v]
}

/// Cuts `hexes` (8 node ids each, VTK / Gmsh order) into tets with `split`.
/// Returns the tets, `split.tets_per_cell()` per hex in hex order, each oriented
/// to a positive volume when its corners allow; [`HexSplit::TwentyFour`] appends
/// its face and cell centres to `nodes`. An `Err` says which hex cannot be split
/// and why (a repeated corner, ids out of range, or a mesh that [`HexSplit::Five`]
/// cannot colour).
///
/// ```
/// use heml_core::mesh::generate::HexSplit;
/// use heml_core::mesh::hex_split::split_hexes;
/// use heml_core::Vec3;
///
/// // two unit cubes side by side along x, VTK corner order
/// let mut nodes: Vec<Vec3> = (0..12)
///     .map(|i| Vec3::new((i % 3) as f64, ((i / 3) % 2) as f64, (i / 6) as f64))
///     .collect();
/// let hexes = [[0, 1, 4, 3, 6, 7, 10, 9], [1, 2, 5, 4, 7, 8, 11, 10]];
/// let tets = split_hexes(&mut nodes, &hexes, HexSplit::Six).unwrap();
/// assert_eq!(tets.len(), 12);
/// ```
pub fn split_hexes(nodes: &mut Vec<Vec3>, hexes: &[[usize; 8]], split: HexSplit) -> Result<Vec<[usize; 4]>, String> {
    let n = nodes.len();
    for (h, hex) in hexes.iter().enumerate() {
        if let Some(&i) = hex.iter().find(|&&i| i >= n) {
            return Err(format!("hexahedron {h} refers to node {i}, but there are {n} nodes"));
        }
        for k in 0..8 {
            if hex[k + 1..].contains(&hex[k]) {
                return Err(format!(
                    "hexahedron {h} repeats node {} (a hex collapsed into a prism or pyramid cannot be \
                     split into sound tets)",
                    hex[k]
                ));
            }
        }
    }
    let corners = |hex: &[usize; 8]| -> [usize; 8] { std::array::from_fn(|b| hex[HEX_OF_BIT[b]]) };
    let mut tets = Vec::with_capacity(hexes.len().saturating_mul(split.tets_per_cell()));
    match split {
        HexSplit::Six => {
            for hex in hexes {
                let c = corners(hex);
                let m = (0..8).min_by_key(|&b| c[b]).unwrap_or(0);
                for (axis, u, v) in AXES {
                    // the face on the other side of `axis` from the smallest corner
                    let r = ring(axis, m & axis == 0, u, v);
                    let k = (0..4).min_by_key(|&k| c[r[k]]).unwrap_or(0);
                    let at = |e: usize| c[r[(k + e) % 4]];
                    tets.push([c[m], at(0), at(1), at(2)]);
                    tets.push([c[m], at(0), at(2), at(3)]);
                }
            }
        }
        HexSplit::Five | HexSplit::Ten => {
            let colour = two_colouring(n, hexes, split)?;
            // `ten`: cover 1 is the mirror cutting, central tet on the colour-0 corners
            let covers: &[bool] = if split == HexSplit::Ten {
                &[true, false]
            } else {
                &[true]
            };
            for hex in hexes {
                let c = corners(hex);
                for &centre_colour in covers {
                    let central: Vec<usize> = (0..8)
                        .filter(|&b| colour[c[b]] == centre_colour)
                        .map(|b| c[b])
                        .collect();
                    tets.push([central[0], central[1], central[2], central[3]]);
                    for b in (0..8).filter(|&b| colour[c[b]] != centre_colour) {
                        tets.push([c[b], c[b ^ 1], c[b ^ 2], c[b ^ 4]]);
                    }
                }
            }
        }
        HexSplit::TwentyFour => {
            let mut face_centre: HashMap<[usize; 4], usize> = HashMap::new();
            for hex in hexes {
                let c = corners(hex);
                let centre = nodes.len();
                nodes.push(c.iter().map(|&i| nodes[i]).sum::<Vec3>() / 8.0);
                for (axis, u, v) in AXES {
                    for side in [false, true] {
                        let r = ring(axis, side, u, v).map(|b| c[b]);
                        let mut key = r;
                        key.sort_unstable();
                        let f = *face_centre.entry(key).or_insert_with(|| {
                            nodes.push(r.iter().map(|&i| nodes[i]).sum::<Vec3>() / 4.0);
                            nodes.len() - 1
                        });
                        for e in 0..4 {
                            tets.push([r[e], r[(e + 1) % 4], f, centre]);
                        }
                    }
                }
            }
        }
    }
    for t in &mut tets {
        let p = t.map(|i| nodes[i]);
        if (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) < 0.0 {
            t.swap(2, 3);
        }
    }
    Ok(tets)
}

/// A 2-colouring of the nodes along the hex edges (`true` = colour 1), by a
/// union-find that keeps each node's parity relative to its root; an edge whose
/// ends already have the same parity is an odd cycle, reported with its hex.
fn two_colouring(n: usize, hexes: &[[usize; 8]], split: HexSplit) -> Result<Vec<bool>, String> {
    let mut parent: Vec<usize> = (0..n).collect();
    let mut parity = vec![false; n];
    // root of x and the parity of x relative to it, compressing the path
    fn find(parent: &mut [usize], parity: &mut [bool], x: usize) -> (usize, bool) {
        let mut path = Vec::new();
        let mut r = x;
        while parent[r] != r {
            path.push(r);
            r = parent[r];
        }
        // walk back from the node nearest the root, accumulating parities
        let mut acc = false;
        for &p in path.iter().rev() {
            acc ^= parity[p];
            parity[p] = acc;
            parent[p] = r;
        }
        (r, if path.is_empty() { false } else { parity[x] })
    }
    for (h, hex) in hexes.iter().enumerate() {
        for b in 0..8usize {
            for axis in [1, 2, 4] {
                if b & axis != 0 {
                    continue;
                }
                let (x, y) = (hex[HEX_OF_BIT[b]], hex[HEX_OF_BIT[b | axis]]);
                let (rx, px) = find(&mut parent, &mut parity, x);
                let (ry, py) = find(&mut parent, &mut parity, y);
                if rx == ry {
                    if px == py {
                        return Err(format!(
                            "hex_split = \"{}\" needs the hex corners 2-coloured along the edges (as in a \
                             structured grid), but the edge {x}-{y} of hexahedron {h} closes an odd cycle; \
                             use \"six\" or \"twentyfour\"",
                            if split == HexSplit::Ten { "ten" } else { "five" }
                        ));
                    }
                } else {
                    parent[ry] = rx;
                    parity[ry] = !(px ^ py);
                }
            }
        }
    }
    Ok((0..n).map(|x| find(&mut parent, &mut parity, x).1).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A structured grid of `nx × ny × nz` unit hexes with shuffled node ids, so
    /// that no split can lean on a global numbering.
    fn grid(nx: usize, ny: usize, nz: usize) -> (Vec<Vec3>, Vec<[usize; 8]>) {
        let id0 = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
        let n = (nx + 1) * (ny + 1) * (nz + 1);
        // a fixed permutation: multiply by a number coprime with n
        let step = (1..).map(|s: usize| 7 + 2 * s).find(|s| gcd(*s, n) == 1).unwrap();
        let perm = |i: usize| (i * step + 3) % n;
        let mut nodes = vec![Vec3::zeros(); n];
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    nodes[perm(id0(i, j, k))] = Vec3::new(i as f64, j as f64, k as f64);
                }
            }
        }
        let mut hexes = Vec::new();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let c = |b: usize| perm(id0(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1)));
                    hexes.push(HEX_OF_BIT.map(c));
                }
            }
        }
        (nodes, hexes)
    }

    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }

    fn volume(nodes: &[Vec3], t: &[usize; 4]) -> f64 {
        let p = t.map(|i| nodes[i]);
        (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) / 6.0
    }

    #[test]
    fn every_split_fills_each_hex_with_positive_tets() {
        for split in HexSplit::ALL {
            let (mut nodes, hexes) = grid(3, 2, 2);
            let tets = split_hexes(&mut nodes, &hexes, split).unwrap();
            assert_eq!(tets.len(), hexes.len() * split.tets_per_cell(), "{split:?}");
            for (h, chunk) in tets.chunks(split.tets_per_cell()).enumerate() {
                // unit cubes: the tets of a hex sum to 1 (exact dyadic arithmetic for
                // corners and centres at multiples of 1/2; 1e-14 for the sum's rounding)
                let w = split.overlap(1).map_or(1.0, |o| o.weights[0]);
                let v: f64 = chunk.iter().map(|t| w * volume(&nodes, t)).sum();
                assert!((v - 1.0).abs() < 1e-14, "{split:?}: hex {h} volume {v}");
                assert!(chunk.iter().all(|t| volume(&nodes, t) > 0.0), "{split:?}: hex {h}");
            }
        }
    }

    #[test]
    fn an_odd_cycle_refuses_five_and_six_still_splits() {
        // The colouring sees the topology only: swapping two edge-adjacent corners
        // of the second hex (VTK corners 0 and 1) joins corner 1 to corner 3 by an
        // edge, two neighbours of corner 0 that a colouring must give one colour.
        let (mut nodes, mut hexes) = grid(2, 1, 1);
        hexes[1].swap(0, 1);
        let e = split_hexes(&mut nodes.clone(), &hexes, HexSplit::Five).unwrap_err();
        assert!(e.contains("odd cycle") && e.contains("hexahedron 1"), "{e}");
        assert_eq!(split_hexes(&mut nodes, &hexes, HexSplit::Six).unwrap().len(), 12);
    }

    #[test]
    fn degenerate_hexes_are_refused_with_their_index() {
        let (mut nodes, mut hexes) = grid(1, 1, 2);
        hexes[1][3] = hexes[1][2];
        let e = split_hexes(&mut nodes, &hexes, HexSplit::Six).unwrap_err();
        assert!(e.starts_with("hexahedron 1 repeats node"), "{e}");
        hexes[1][3] = 999;
        let e = split_hexes(&mut nodes, &hexes, HexSplit::Six).unwrap_err();
        assert!(e.contains("hexahedron 1 refers to node 999"), "{e}");
    }
}
