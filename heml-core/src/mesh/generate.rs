//! Structured meshes of boxes and beams, for tests, benchmarks and the demo.
//!
//! Each hexahedral cell is cut into tetrahedra by a [`HexSplit`]. The splits differ
//! in element count and in *anisotropy*: a split along a preferred diagonal makes
//! the discrete body stiffer in some directions than others (visible e.g. as a
//! slight twist of a cantilever under pure bending), so convergence studies should
//! compare splits.

use crate::error::{HemlError, Result};
use crate::mesh::TetMesh;
use crate::Vec3;

/// How each hexahedral cell is cut into tetrahedra.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HexSplit {
    /// Five tets: four corner tets and a central regular-shaped one. The two mirror
    /// images of the pattern alternate with the parity of `i + j + k`, which makes
    /// neighbouring cells cut their shared face along the same diagonal (conforming).
    /// Fewest elements, but the pattern's face diagonals are not symmetric in a cell.
    Five,
    /// Six tets around the cell's main diagonal (Kuhn/Freudenthal); conforming,
    /// with a preferred direction along (1, 1, 1).
    #[default]
    Six,
    /// Twenty-four tets with no preferred direction: a node is added at the centre
    /// of each cell and of each face; every face is cut into 4 triangles around
    /// its centre, and each triangle is joined to the cell centre. The result is
    /// invariant under all symmetries of the cube (reflections included) and
    /// conforming, because face centres are shared by the two cells of a face.
    /// The smallest symmetric split that needs no weights (compare [`HexSplit::Ten`]).
    TwentyFour,
    /// The method's symmetric ten-tet split: both [`HexSplit::Five`] cuttings of every
    /// cell, the two mirror images (the central tet on one or the other set of
    /// alternating corners), all ten tets kept and each weighted ½ in stiffness and
    /// mass (see [`super::overlap`]). Each cutting alone is a conforming tiling
    /// (cover 0: the `five` split's, cover 1: its mirror), so the half-sum integrates
    /// a homogeneous deformation exactly and has no preferred face diagonal; the
    /// boundary surface is cover 0's. No added nodes, twice the tets of `five`.
    Ten,
}

impl HexSplit {
    /// Every split, for tests and parameter sweeps.
    pub const ALL: [HexSplit; 4] = [HexSplit::Five, HexSplit::Six, HexSplit::TwentyFour, HexSplit::Ten];

    /// Number of tets per hexahedral cell.
    pub fn tets_per_cell(self) -> usize {
        match self {
            HexSplit::Five => 5,
            HexSplit::Six => 6,
            HexSplit::Ten => 10,
            HexSplit::TwentyFour => 24,
        }
    }

    /// The weights and covers of `n_cells` cells cut by this split, the tets of
    /// each cell in the order the split makes them: `None` unless the split's tets
    /// overlap ([`HexSplit::Ten`]: the first five tets of a cell are cover 0, the
    /// last five cover 1, all of weight ½).
    pub fn overlap(self, n_cells: usize) -> Option<super::overlap::Overlap> {
        (self == HexSplit::Ten).then(|| super::overlap::Overlap {
            weights: vec![0.5; n_cells * 10],
            covers: (0..n_cells).flat_map(|_| [0, 0, 0, 0, 0, 1, 1, 1, 1, 1]).collect(),
        })
    }
}

/// The largest mesh [`box_mesh`] and [`beam`] build: 50 million tets, about 2.9 GB
/// while generating (see [`MeshSize::bytes`]) and several times that once a system
/// is built on it. Asking for more is far more often a typo (`cells = [2000, 2000,
/// 2000]` is 48 billion tets and 2.6 TB) than a plan, and it used to abort the
/// process in the allocator; [`box_mesh_limited`] (or the scene key
/// `[mesh] generate.max_tets`) sets another limit deliberately.
pub const DEFAULT_MAX_GENERATED_TETS: usize = 50_000_000;

/// The size of a generated mesh, computed from its cell counts before anything
/// is allocated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshSize {
    /// Number of nodes.
    pub nodes: usize,
    /// Number of tets.
    pub tets: usize,
    /// Peak memory of the generation in bytes: the nodes (24 B each), the tets as
    /// generated (32 B) and as stored by [`TetMesh`] (16 B), and their tags (4 B).
    pub bytes: usize,
}

/// Node and tet counts (and bytes) of [`box_mesh`] with these cells and split,
/// with overflow-checked arithmetic: `None` when a count does not fit a `usize`.
pub fn box_mesh_size(cells: [usize; 3], split: HexSplit) -> Option<MeshSize> {
    let [nx, ny, nz] = cells;
    let mul = |a: usize, b: usize, c: usize| a.checked_mul(b)?.checked_mul(c);
    let corners = mul(nx.checked_add(1)?, ny.checked_add(1)?, nz.checked_add(1)?)?;
    let n_cells = mul(nx, ny, nz)?;
    let nodes = if split == HexSplit::TwentyFour {
        // face centres of the x-, y- and z-normal faces, then cell centres
        let faces = [mul(nx + 1, ny, nz)?, mul(nx, ny + 1, nz)?, mul(nx, ny, nz + 1)?];
        faces
            .iter()
            .try_fold(corners.checked_add(n_cells)?, |a, &f| a.checked_add(f))?
    } else {
        corners
    };
    let tets = n_cells.checked_mul(split.tets_per_cell())?;
    let bytes = nodes.checked_mul(24)?.checked_add(tets.checked_mul(32 + 16 + 4)?)?;
    Some(MeshSize { nodes, tets, bytes })
}

/// A box `[0, size.x] × [0, size.y] × [0, size.z]` with `cells` hexahedra per axis.
/// Meshes above [`DEFAULT_MAX_GENERATED_TETS`] are refused before anything is
/// allocated; see [`box_mesh_limited`].
///
/// ```
/// use heml_core::mesh::generate::{box_mesh, HexSplit};
/// let m = box_mesh([2.0, 1.0, 1.0], [4, 2, 2], HexSplit::Six).unwrap();
/// assert_eq!(m.n_tets(), 6 * 16);
/// assert!((m.total_volume() - 2.0).abs() < 1e-12);
/// let m = box_mesh([2.0, 1.0, 1.0], [4, 2, 2], HexSplit::Five).unwrap();
/// assert_eq!(m.n_tets(), 5 * 16);
/// ```
pub fn box_mesh(size: [f64; 3], cells: [usize; 3], split: HexSplit) -> Result<TetMesh> {
    box_mesh_limited(size, cells, split, DEFAULT_MAX_GENERATED_TETS)
}

/// [`box_mesh`] with an explicit limit on the number of tets: the counts and the
/// memory are computed first ([`box_mesh_size`]) and a mesh above `max_tets` (or
/// whose node ids would not fit the `u32` of [`TetMesh`]) is refused with them.
pub fn box_mesh_limited(size: [f64; 3], cells: [usize; 3], split: HexSplit, max_tets: usize) -> Result<TetMesh> {
    if cells.contains(&0) || size.iter().any(|&s| !(s.is_finite() && s > 0.0)) {
        return Err(HemlError::Invalid(format!(
            "box mesh needs positive finite sizes and at least one cell per axis, got size {size:?}, cells {cells:?}"
        )));
    }
    let split_name = format!("{split:?}").to_lowercase();
    let sized = box_mesh_size(cells, split).ok_or_else(|| {
        HemlError::Invalid(format!(
            "box mesh with cells {cells:?} (split {split_name}): the node or tet count overflows; \
             the limit is {max_tets} tets"
        ))
    })?;
    if sized.tets > max_tets || sized.nodes > u32::MAX as usize {
        return Err(HemlError::Invalid(format!(
            "box mesh with cells {cells:?} (split {split_name}) would have {} nodes and {} tets \
             (~{:.1} GB to generate); the limit is {max_tets} tets{} (DEFAULT_MAX_GENERATED_TETS = {}; \
             in a scene, raise it with `max_tets` in [mesh] generate)",
            sized.nodes,
            sized.tets,
            sized.bytes as f64 / 1e9,
            if sized.nodes > u32::MAX as usize {
                " and 2^32 - 1 nodes"
            } else {
                ""
            },
            DEFAULT_MAX_GENERATED_TETS
        )));
    }
    let [nx, ny, nz] = cells;
    let id = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
    let h = [size[0] / nx as f64, size[1] / ny as f64, size[2] / nz as f64];
    // exact end coordinates: i * size / n (not i * h) so that the far face is at `size`
    let coord = |a: usize, i: usize, n: usize| size[a] * i as f64 / n as f64;
    let mut nodes = Vec::with_capacity(sized.nodes);
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                nodes.push(Vec3::new(coord(0, i, nx), coord(1, j, ny), coord(2, k, nz)));
            }
        }
    }
    // Extra nodes of the 24-tet split: face centres (x-, y-, z-normal) then cell centres.
    let base_x = nodes.len();
    let base_y = base_x + (nx + 1) * ny * nz;
    let base_z = base_y + nx * (ny + 1) * nz;
    let base_c = base_z + nx * ny * (nz + 1);
    if split == HexSplit::TwentyFour {
        let mid = |a: usize, i: usize| (i as f64 + 0.5) * h[a];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..=nx {
                    nodes.push(Vec3::new(coord(0, i, nx), mid(1, j), mid(2, k)));
                }
            }
        }
        for k in 0..nz {
            for j in 0..=ny {
                for i in 0..nx {
                    nodes.push(Vec3::new(mid(0, i), coord(1, j, ny), mid(2, k)));
                }
            }
        }
        for k in 0..=nz {
            for j in 0..ny {
                for i in 0..nx {
                    nodes.push(Vec3::new(mid(0, i), mid(1, j), coord(2, k, nz)));
                }
            }
        }
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    nodes.push(Vec3::new(mid(0, i), mid(1, j), mid(2, k)));
                }
            }
        }
    }
    let mut tets = Vec::with_capacity(sized.tets);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                // corner(b) for b = bits (x, y, z) of the cell's corners
                let corner = |b: usize| id(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1));
                match split {
                    HexSplit::Six => {
                        // paths 000 → axis a → axes a+b → 111 for the six axis orders
                        for (a, b) in [(1, 2), (2, 1), (2, 4), (4, 2), (4, 1), (1, 4)] {
                            tets.push([corner(0), corner(a), corner(a | b), corner(7)]);
                        }
                    }
                    HexSplit::Five | HexSplit::Ten => {
                        // Global parity of corner b is (i+j+k + popcount(b)) % 2. The central
                        // tet joins the 4 odd corners; each even corner gets a corner tet with
                        // its 3 neighbours. Every face diagonal thus joins the two globally
                        // odd corners of the face, the same from both cells sharing it. `ten`
                        // adds the mirror cutting (central tet on the even corners), itself
                        // conforming by the same argument.
                        let covers = if split == HexSplit::Ten { 2 } else { 1 };
                        for cover in 0..covers {
                            let parity = (i + j + k + cover) % 2;
                            let odd = |b: usize| (parity + (b as u32).count_ones() as usize) % 2 == 1;
                            let central: Vec<usize> = (0..8).filter(|&b| odd(b)).map(corner).collect();
                            tets.push([central[0], central[1], central[2], central[3]]);
                            for b in (0..8).filter(|&b| !odd(b)) {
                                tets.push([corner(b), corner(b ^ 1), corner(b ^ 2), corner(b ^ 4)]);
                            }
                        }
                    }
                    HexSplit::TwentyFour => {
                        let centre = base_c + i + nx * (j + ny * k);
                        // (axis bit, other bits u, v, face-centre index for side 0 / 1)
                        let faces = [
                            (
                                1,
                                2,
                                4,
                                [
                                    base_x + i + (nx + 1) * (j + ny * k),
                                    base_x + i + 1 + (nx + 1) * (j + ny * k),
                                ],
                            ),
                            (
                                2,
                                1,
                                4,
                                [
                                    base_y + i + nx * (j + (ny + 1) * k),
                                    base_y + i + nx * (j + 1 + (ny + 1) * k),
                                ],
                            ),
                            (
                                4,
                                1,
                                2,
                                [base_z + i + nx * (j + ny * k), base_z + i + nx * (j + ny * (k + 1))],
                            ),
                        ];
                        for (axis, u, v, fc) in faces {
                            for (side, &f) in fc.iter().enumerate() {
                                let off = if side == 1 { axis } else { 0 };
                                let ring = [off, off | u, off | u | v, off | v];
                                for e in 0..4 {
                                    tets.push([corner(ring[e]), corner(ring[(e + 1) % 4]), f, centre]);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    // Orient every tet positively here, so that the mesh reports no reorientation.
    for t in &mut tets {
        let p = t.map(|i| nodes[i]);
        if (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) < 0.0 {
            t.swap(2, 3);
        }
    }
    let mesh = TetMesh::new(nodes, tets)?;
    match split.overlap(nx * ny * nz) {
        Some(o) => mesh.with_overlap(o),
        None => Ok(mesh),
    }
}

/// A beam `[0, length] × [0, width] × [0, height]` along x with
/// `cells_along_length` cells along its axis and as many across as keep the cells
/// close to cubes (at least one). Clamp it at `x = 0` for a cantilever.
///
/// ```
/// use heml_core::mesh::generate::{beam, HexSplit};
/// let m = beam(40.0, 4.0, 2.0, 20, HexSplit::Six).unwrap();
/// assert_eq!(m.n_tets(), 20 * 2 * 1 * 6);
/// ```
pub fn beam(length: f64, width: f64, height: f64, cells_along_length: usize, split: HexSplit) -> Result<TetMesh> {
    if cells_along_length == 0 || !(length.is_finite() && length > 0.0) {
        return Err(HemlError::Invalid(format!(
            "beam needs a positive finite length and at least one cell along it, got length {length}, {cells_along_length} cells"
        )));
    }
    let h = length / cells_along_length as f64;
    let across = |d: f64| {
        if d.is_finite() && d > 0.0 {
            ((d / h).round() as usize).max(1)
        } else {
            1
        }
    };
    box_mesh(
        [length, width, height],
        [cells_along_length, across(width), across(height)],
        split,
    )
}

/// A box of about `n_tets` tets, for benchmarks: [`HexSplit::Six`] cells, about cubic
/// (`a × a × c` cells with `c ≈ a`), 0.1 m across in x and y. The tet count is within a
/// few percent of `n_tets` for `n_tets` ≥ 1000 (at least one cell, 6 tets, always).
///
/// ```
/// use heml_core::mesh::generate::box_of_about;
/// let m = box_of_about(10_000).unwrap();
/// assert!((m.n_tets() as f64 / 10_000.0 - 1.0).abs() < 0.1);
/// ```
pub fn box_of_about(n_tets: usize) -> Result<TetMesh> {
    let cells = (n_tets as f64 / 6.0).max(1.0);
    let a = cells.cbrt().round().max(1.0) as usize;
    let c = ((cells / (a * a) as f64).round() as usize).max(1);
    box_mesh([0.1, 0.1, 0.1 * c as f64 / a as f64], [a, a, c], HexSplit::Six)
}

/// Per-face incidence counts of a mesh (sorted node triples), for conformity checks.
#[cfg(test)]
fn face_counts(m: &TetMesh) -> std::collections::HashMap<[u32; 3], usize> {
    let mut faces = std::collections::HashMap::new();
    for t in m.tets() {
        for skip in 0..4 {
            let mut f = [0u32; 3];
            let mut n = 0;
            for (k, &v) in t.iter().enumerate() {
                if k != skip {
                    f[n] = v;
                    n += 1;
                }
            }
            f.sort_unstable();
            *faces.entry(f).or_insert(0) += 1;
        }
    }
    faces
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_generated_meshes_are_sized_and_refused_before_allocating() {
        // used to abort: "memory allocation of 192288144024 bytes failed"
        let e = box_mesh([1.0; 3], [2000, 2000, 2000], HexSplit::Six)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("8012006001 nodes") && e.contains("48000000000 tets") && e.contains("limit is 50000000 tets"),
            "{e}"
        );
        let e = beam(1.0, 1.0, 1.0, 2000, HexSplit::Six).unwrap_err().to_string();
        assert!(e.contains("48000000000 tets"), "{e}");
        // counts that overflow usize are an error too, not a wrap-around
        let e = box_mesh([1.0; 3], [usize::MAX, 2, 2], HexSplit::Five)
            .unwrap_err()
            .to_string();
        assert!(e.contains("overflows"), "{e}");
        // the limit is the caller's to set, and the sizing matches what is built
        assert!(box_mesh_limited([1.0; 3], [2, 2, 2], HexSplit::Six, 47).is_err());
        for split in HexSplit::ALL {
            let m = box_mesh_limited([1.0; 3], [3, 2, 2], split, 12 * split.tets_per_cell()).unwrap();
            let s = box_mesh_size([3, 2, 2], split).unwrap();
            assert_eq!((s.nodes, s.tets), (m.n_nodes(), m.n_tets()), "{split:?}");
        }
    }

    #[test]
    fn box_of_about_hits_the_requested_tet_count() {
        for n in [1_000, 10_000, 100_000] {
            let m = box_of_about(n).unwrap();
            let r = m.n_tets() as f64 / n as f64;
            assert!((r - 1.0).abs() < 0.1, "{n} tets asked, {} made", m.n_tets());
        }
    }

    #[test]
    fn every_split_fills_the_box_conformingly() {
        let size = [2.0, 1.5, 1.0];
        for split in HexSplit::ALL {
            let m = box_mesh(size, [3, 2, 2], split).unwrap();
            assert_eq!(m.n_tets(), 12 * split.tets_per_cell(), "{split:?}");
            assert!(
                (m.total_volume() - 3.0).abs() < 1e-12,
                "{split:?}: {}",
                m.total_volume()
            );
            assert_eq!(m.reoriented_count(), 0, "{split:?}");
            assert!(m.unreferenced_nodes().is_empty(), "{split:?}");
            // conforming: a face used once must lie on the box boundary, none more than twice
            for (f, n) in face_counts(&m) {
                assert!(n <= 2, "{split:?}: face {f:?} shared by {n} tets");
                if n == 1 {
                    let p = f.map(|i| m.nodes()[i as usize]);
                    let on_boundary = (0..3).any(|a| {
                        p.iter().all(|q| q[a].abs() < 1e-12) || p.iter().all(|q| (q[a] - size[a]).abs() < 1e-12)
                    });
                    assert!(
                        on_boundary,
                        "{split:?}: interior face {p:?} belongs to one tet (non-conforming)"
                    );
                }
            }
        }
    }

    #[test]
    fn twenty_four_split_has_the_symmetry_of_the_cube() {
        // the set of tets (as sets of points) is invariant under each axis reflection
        // and under swapping x and y; the six-tet split is not (it has a preferred diagonal)
        let key = |m: &TetMesh, map: &dyn Fn(Vec3) -> Vec3| {
            let mut tets: Vec<Vec<[i64; 3]>> = (0..m.n_tets())
                .map(|t| {
                    let mut pts: Vec<[i64; 3]> = m
                        .tet_points(t)
                        .iter()
                        .map(|&p| {
                            let q = map(p) * 4.0;
                            [q.x.round() as i64, q.y.round() as i64, q.z.round() as i64]
                        })
                        .collect();
                    pts.sort_unstable();
                    pts
                })
                .collect();
            tets.sort_unstable();
            tets
        };
        let maps: [&dyn Fn(Vec3) -> Vec3; 4] = [
            &|p: Vec3| Vec3::new(1.0 - p.x, p.y, p.z),
            &|p: Vec3| Vec3::new(p.x, 1.0 - p.y, p.z),
            &|p: Vec3| Vec3::new(p.x, p.y, 1.0 - p.z),
            &|p: Vec3| Vec3::new(p.y, p.x, p.z),
        ];
        let sym = box_mesh([1.0; 3], [1, 1, 1], HexSplit::TwentyFour).unwrap();
        let six = box_mesh([1.0; 3], [1, 1, 1], HexSplit::Six).unwrap();
        for map in maps {
            assert_eq!(key(&sym, &|p| p), key(&sym, map));
        }
        assert_ne!(key(&six, &|p| p), key(&six, maps[0]));
    }

    #[test]
    fn beam_picks_near_cubic_cells_and_split_names_are_lowercase() {
        let m = beam(40.0, 4.0, 2.0, 10, HexSplit::Five).unwrap();
        assert_eq!(m.n_tets(), 10 * 5); // 10 × 1 × 1 cells
        let (lo, hi) = m.bounding_box();
        assert_eq!((lo, hi), (Vec3::zeros(), Vec3::new(40.0, 4.0, 2.0)));
        assert!(beam(0.0, 1.0, 1.0, 3, HexSplit::Six).is_err());
        assert!(box_mesh([1.0, f64::NAN, 1.0], [1, 1, 1], HexSplit::Six).is_err());
        assert_eq!(serde_json_like(HexSplit::TwentyFour), "twentyfour");
        assert_eq!(serde_json_like(HexSplit::Ten), "ten");
    }

    /// The serde name of a variant, found by deserializing candidate names with
    /// `serde::de::value` (no format crate needed).
    fn serde_json_like(split: HexSplit) -> &'static str {
        use serde::de::{value::StrDeserializer, Deserialize};
        for name in ["five", "six", "ten", "twentyfour"] {
            let d: StrDeserializer<'_, serde::de::value::Error> = StrDeserializer::new(name);
            if HexSplit::deserialize(d).ok() == Some(split) {
                return name;
            }
        }
        "?"
    }
}
