//! Medit / INRIA `.mesh` files (ASCII; the binary `.meshb` is not supported).
//!
//! Keywords are free-format tokens. `Vertices` and `Tetrahedra` (whose reference
//! becomes the tag) are read; surface and annotation sections (`Edges`,
//! `Triangles`, `Quadrilaterals`, `Corners`, `Ridges`, `Required*`, `Normals`, …)
//! are skipped and counted; other volume elements (`Hexahedra`, `Prisms`,
//! `Pyramids`, P2 tets) are refused. A keyword whose layout is unknown cannot be
//! skipped safely in a token stream, so it is an error naming it.
//!
//! The references of boundary elements (the labels MMG and FreeFem++ give the
//! faces and edges of a boundary) become node sets, named as Gmsh's unnamed
//! groups: the nodes of the triangles and quadrilaterals with reference N are
//! `"surface N"`, those of the edges `"curve N"` (reference 0, the usual "none",
//! gives no set). A scene selects one with `node_set = "surface 3"`.

use std::io::Write;
use std::path::Path;

use super::atomic::write_atomic;
use super::cursor::{capacity, finite_point, shorten, Cursor};
use super::{read_bytes, MeshData};
use crate::error::Result;
use crate::mesh::TetMesh;

/// Boundary sections whose references become node sets: keyword, vertices per
/// item (a reference follows them) and the set's dimension word.
const LABELLED: &[(&str, usize, &str)] = &[
    ("edges", 2, "curve"),
    ("triangles", 3, "surface"),
    ("quadrilaterals", 4, "surface"),
];

/// Skippable sections: keyword (lowercase) and the number of tokens per item.
const SKIPPED: &[(&str, usize)] = &[
    ("corners", 1),
    ("ridges", 1),
    ("requiredvertices", 1),
    ("requirededges", 1),
    ("requiredtriangles", 1),
    ("requiredquadrilaterals", 1),
    ("normals", 3),
    ("tangents", 3),
    ("normalatvertices", 2),
    ("normalattrianglevertices", 3),
    ("normalatquadrilateralvertices", 3),
    ("tangentatedges", 3),
];

const VOLUMES: &[&str] = &["hexahedra", "prisms", "pyramids", "tetrahedrap2", "hexahedraq2"];

/// Reads a Medit mesh.
pub fn read(path: &Path) -> Result<MeshData> {
    let bytes = read_bytes(path)?;
    parse(path, &bytes)
}

/// Parses the bytes of a Medit file (`path` is used in error messages).
pub fn parse(path: &Path, bytes: &[u8]) -> Result<MeshData> {
    let mut c = Cursor::new(path, bytes, Some(b'#'));
    let mut data = MeshData::default();
    let mut raw_tets: Vec<([usize; 4], usize)> = Vec::new();
    // labelled boundary elements: set name, 1-based vertices, line
    let mut labelled: Vec<(String, Vec<usize>, usize)> = Vec::new();
    let mut have_vertices = false;
    let mut have_end = false;
    let mut have_version = false;
    // the last section read and the line of its count, to explain a wrong count
    let mut last_section: Option<(&str, usize)> = None;
    while let Some((kw, ln)) = c.token()? {
        let key = kw.to_ascii_lowercase();
        match key.as_str() {
            "meshversionformatted" => {
                c.parse::<u32>("the format version")?;
                have_version = true;
            }
            "dimension" => {
                let d: u32 = c.parse("the dimension")?;
                if d != 3 {
                    return Err(c.err_at(ln, format!("dimension {d}, expected 3")));
                }
            }
            "vertices" => {
                let n: usize = c.parse("the number of vertices")?;
                let header = c.line();
                // a vertex line holds 4 numbers and their separators: 8 bytes at least
                data.nodes.reserve(capacity(n, c.remaining(), 8));
                for k in 0..n {
                    // peek at the record's first token for a count that is too large
                    let before = c.clone();
                    c.record_number::<f64>(k, n, "vertices", header)?;
                    c = before;
                    let p = finite_point(&mut c, k + 1)?;
                    c.parse::<i64>("a vertex reference")?;
                    data.nodes.push(p);
                }
                last_section = Some(("Vertices", header));
                have_vertices = true;
            }
            "tetrahedra" => {
                let n: usize = c.parse("the number of tetrahedra")?;
                let header = c.line();
                // a tet line holds 5 numbers and their separators: 10 bytes at least
                raw_tets.reserve(capacity(n, c.remaining(), 10));
                data.tags.reserve(capacity(n, c.remaining(), 10));
                for k in 0..n {
                    let (first, line) = c.record_number::<usize>(k, n, "tetrahedra", header)?;
                    let mut t = [first, 0, 0, 0];
                    for v in &mut t[1..] {
                        *v = c.parse("a vertex number (1-based)")?;
                    }
                    data.tags.push(c.parse::<i32>("an integer tetrahedron reference")?);
                    raw_tets.push((t, line));
                }
                last_section = Some(("Tetrahedra", header));
            }
            "end" => {
                have_end = true;
                break;
            }
            k => {
                if let Some(&(name, nv, word)) = LABELLED.iter().find(|(n, _, _)| *n == k) {
                    let n: usize = c.parse(&format!("the number of {name}"))?;
                    let header = c.line();
                    for i in 0..n {
                        let (first, line) = c.record_number::<usize>(i, n, name, header)?;
                        let mut vs = vec![first];
                        for _ in 1..nv {
                            vs.push(c.parse("a vertex number (1-based)")?);
                        }
                        let r: i64 = c.parse(&format!("an integer reference of the {name}"))?;
                        if r != 0 {
                            labelled.push((format!("{word} {r}"), vs, line));
                        }
                    }
                    *data.skipped.entry(name.to_string()).or_insert(0) += n;
                    last_section = Some((name, header));
                } else if let Some(&(name, per)) = SKIPPED.iter().find(|(n, _)| *n == k) {
                    let n: usize = c.parse(&format!("the number of {name}"))?;
                    let total = n.checked_mul(per).ok_or_else(|| c.err_at(ln, "count overflows"))?;
                    let header = c.line();
                    for _ in 0..total {
                        c.expect_token(&format!("{name} entries"))?;
                    }
                    *data.skipped.entry(name.to_string()).or_insert(0) += n;
                    last_section = Some((name, header));
                } else if VOLUMES.contains(&k) {
                    return Err(c.err_at(
                        ln,
                        format!("section {kw}: only linear tetrahedra are supported as volume elements"),
                    ));
                } else if let (Ok(_), Some((section, header))) = (kw.parse::<f64>(), last_section) {
                    return Err(c.err_at(
                        ln,
                        format!(
                            "found the number '{}' where a keyword was expected: the {section} section \
                             (count at line {header}) has more records than its count",
                            shorten(kw)
                        ),
                    ));
                } else {
                    return Err(c.err_at(ln, format!("unknown Medit keyword '{}'", shorten(kw))));
                }
            }
        }
    }
    if !have_version {
        return Err(c.err_at(1, "missing MeshVersionFormatted (not a Medit .mesh file?)"));
    }
    if !have_end {
        return Err(c.err("missing End keyword (file truncated?)"));
    }
    if !have_vertices {
        return Err(c.err("missing Vertices section"));
    }
    if raw_tets.is_empty() {
        return Err(
            c.err("no tetrahedra in the file (no Tetrahedra section, or a count of 0): a mesh needs at least one")
        );
    }
    let n = data.nodes.len();
    let vertex = |v: usize, line: usize| {
        v.checked_sub(1)
            .filter(|&i| i < n)
            .ok_or_else(|| c.err_at(line, format!("vertex number {v} is outside 1..={n}")))
    };
    for (name, vs, line) in labelled {
        let set = data.node_sets.entry(name).or_default();
        for v in vs {
            set.push(vertex(v, line)?);
        }
    }
    for set in data.node_sets.values_mut() {
        set.sort_unstable();
        set.dedup();
    }
    for (t, line) in raw_tets {
        let mut tet = [0usize; 4];
        for (k, &v) in t.iter().enumerate() {
            tet[k] = vertex(v, line)?;
        }
        data.tets.push(tet);
    }
    Ok(data)
}

/// Writes `mesh` as a Medit file (double precision, tags as tet references).
pub fn write(path: &Path, mesh: &TetMesh) -> Result<()> {
    write_atomic(path, |w| {
        writeln!(w, "MeshVersionFormatted 2\nDimension 3\nVertices\n{}", mesh.n_nodes())?;
        for p in mesh.nodes() {
            writeln!(w, "{:e} {:e} {:e} 0", p.x, p.y, p.z)?;
        }
        writeln!(w, "Tetrahedra\n{}", mesh.n_tets())?;
        for (t, tag) in mesh.tets().iter().zip(mesh.tags()) {
            writeln!(w, "{} {} {} {} {tag}", t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1)?;
        }
        writeln!(w, "End")
    })
}
