//! Medit / INRIA `.mesh` files (ASCII; the binary `.meshb` is not supported).
//!
//! Keywords are free-format tokens. `Vertices` and `Tetrahedra` (whose reference
//! becomes the tag) are read; surface and annotation sections (`Edges`,
//! `Triangles`, `Quadrilaterals`, `Corners`, `Ridges`, `Required*`, `Normals`, …)
//! are skipped and counted; other volume elements (`Hexahedra`, `Prisms`,
//! `Pyramids`, P2 tets) are refused. A keyword whose layout is unknown cannot be
//! skipped safely in a token stream, so it is an error naming it.

use std::io::Write;
use std::path::Path;

use super::atomic::write_atomic;
use super::cursor::{capacity, shorten, Cursor};
use super::{read_bytes, MeshData};
use crate::error::Result;
use crate::mesh::TetMesh;
use crate::Vec3;

/// Skippable sections: keyword (lowercase) and the number of tokens per item.
const SKIPPED: &[(&str, usize)] = &[
    ("edges", 3),
    ("triangles", 4),
    ("quadrilaterals", 5),
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
    let mut have_vertices = false;
    let mut have_end = false;
    let mut have_version = false;
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
                data.nodes.reserve(capacity(n, c.remaining() / 8));
                for _ in 0..n {
                    let x: f64 = c.parse("x coordinate")?;
                    let y: f64 = c.parse("y coordinate")?;
                    let z: f64 = c.parse("z coordinate")?;
                    c.parse::<i64>("a vertex reference")?;
                    data.nodes.push(Vec3::new(x, y, z));
                }
                have_vertices = true;
            }
            "tetrahedra" => {
                let n: usize = c.parse("the number of tetrahedra")?;
                raw_tets.reserve(capacity(n, c.remaining() / 10));
                data.tags.reserve(capacity(n, c.remaining() / 10));
                for _ in 0..n {
                    let line = c.line_of_next_token();
                    let mut t = [0usize; 4];
                    for v in &mut t {
                        *v = c.parse("a vertex number (1-based)")?;
                    }
                    data.tags.push(c.parse::<i32>("an integer tetrahedron reference")?);
                    raw_tets.push((t, line));
                }
            }
            "end" => {
                have_end = true;
                break;
            }
            k => {
                if let Some(&(name, per)) = SKIPPED.iter().find(|(n, _)| *n == k) {
                    let n: usize = c.parse(&format!("the number of {name}"))?;
                    let total = n.checked_mul(per).ok_or_else(|| c.err_at(ln, "count overflows"))?;
                    for _ in 0..total {
                        c.expect_token(&format!("{name} entries"))?;
                    }
                    *data.skipped.entry(name.to_string()).or_insert(0) += n;
                } else if VOLUMES.contains(&k) {
                    return Err(c.err_at(
                        ln,
                        format!("section {kw}: only linear tetrahedra are supported as volume elements"),
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
    let n = data.nodes.len();
    for (t, line) in raw_tets {
        let mut tet = [0usize; 4];
        for (k, &v) in t.iter().enumerate() {
            tet[k] = v
                .checked_sub(1)
                .filter(|&i| i < n)
                .ok_or_else(|| c.err_at(line, format!("vertex number {v} is outside 1..={n}")))?;
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
