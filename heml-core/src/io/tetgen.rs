//! TetGen `.node` + `.ele` pairs.
//!
//! Either file may be given; the sibling with the other extension is read too.
//! Numbering starts at 0 or 1 (TetGen's `-z` switch): the first point's number
//! decides, and point numbers must then be consecutive, as TetGen requires. The
//! first element attribute (TetGen's region attribute, `-A`) becomes the tag.
//! Point attributes and boundary markers are read and ignored. 10-node (quadratic)
//! tets (`-o2`) are refused: their mid-edge nodes would be unreferenced and the
//! curved geometry lost.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::atomic::write_atomic;
use super::cursor::{capacity, finite_point, Cursor};
use super::{float_to_tag, read_bytes, MeshData};
use crate::error::Result;
use crate::mesh::TetMesh;
use crate::Vec3;

/// The `.node` and `.ele` paths for a path with either extension.
pub fn sibling_paths(path: &Path) -> (PathBuf, PathBuf) {
    (path.with_extension("node"), path.with_extension("ele"))
}

/// Reads a `.node`/`.ele` pair.
pub fn read(path: &Path) -> Result<MeshData> {
    let (node_path, ele_path) = sibling_paths(path);
    let node_bytes = read_bytes(&node_path)?;
    let ele_bytes = read_bytes(&ele_path)?;
    let (nodes, first) = parse_node(&node_path, &node_bytes)?;
    let (tets, tags) = parse_ele(&ele_path, &ele_bytes, first, nodes.len())?;
    Ok(MeshData {
        nodes,
        tets,
        tags,
        ..MeshData::default()
    })
}

/// Parses a `.node` file: the points and the first point number (0 or 1).
pub fn parse_node(path: &Path, bytes: &[u8]) -> Result<(Vec<Vec3>, usize)> {
    let mut c = Cursor::new(path, bytes, Some(b'#'));
    let n: usize = c.parse("the number of points")?;
    let header = c.line();
    let dim: usize = c.parse("the dimension")?;
    let nattr: usize = c.parse("the number of point attributes")?;
    let nmark: usize = c.parse("the boundary-marker flag (0 or 1)")?;
    if dim != 3 {
        return Err(c.err_at(header, format!("dimension {dim}, expected 3")));
    }
    if nmark > 1 {
        return Err(c.err_at(header, format!("boundary-marker flag {nmark}, expected 0 or 1")));
    }
    // a point line holds at least 4 numbers and their separators: 8 bytes
    let mut nodes = Vec::with_capacity(capacity(n, c.remaining(), 8));
    let mut first = 0;
    for k in 0..n {
        let (tok, ln) = c.record_start(k, n, "points", header)?;
        let id: usize = super::cursor::parse_at(path, ln, tok, "a point number")?;
        if k == 0 {
            if id > 1 {
                return Err(c.err_at(
                    ln,
                    format!("first point is numbered {id}; TetGen numbering starts at 0 or 1"),
                ));
            }
            first = id;
        } else if id != first + k {
            return Err(c.err_at(
                ln,
                format!(
                    "point numbered {id}, expected {} (points must be consecutive)",
                    first + k
                ),
            ));
        }
        let p = finite_point(&mut c, id)?;
        for _ in 0..nattr {
            c.parse::<f64>("a point attribute")?;
        }
        for _ in 0..nmark {
            c.parse::<i64>("a boundary marker")?;
        }
        nodes.push(p);
    }
    c.expect_no_more_records(n, "points", header)?;
    Ok((nodes, first))
}

/// Parses an `.ele` file with point numbers starting at `first`.
pub fn parse_ele(path: &Path, bytes: &[u8], first: usize, n_nodes: usize) -> Result<(Vec<[usize; 4]>, Vec<i32>)> {
    let mut c = Cursor::new(path, bytes, Some(b'#'));
    let n: usize = c.parse("the number of tetrahedra")?;
    let header = c.line();
    let per: usize = c.parse("the number of nodes per tetrahedron")?;
    let nattr: usize = c.parse("the number of tetrahedron attributes")?;
    if per != 4 {
        return Err(c.err_at(
            header,
            format!("{per} nodes per tetrahedron; only linear 4-node tets are supported (re-run TetGen without -o2)"),
        ));
    }
    if n == 0 {
        return Err(c.err_at(header, "the header announces 0 tetrahedra: a mesh needs at least one"));
    }
    // a tet line holds at least 5 numbers and their separators: 10 bytes
    let mut tets = Vec::with_capacity(capacity(n, c.remaining(), 10));
    let mut tags = Vec::with_capacity(capacity(n, c.remaining(), 10));
    for k in 0..n {
        let (tok, ln) = c.record_start(k, n, "tetrahedra", header)?;
        super::cursor::parse_at::<usize>(path, ln, tok, "a tetrahedron number")?;
        let mut t = [0usize; 4];
        for v in &mut t {
            let (tok, ln) = c.expect_token("a corner point number")?;
            let id: usize = super::cursor::parse_at(path, ln, tok, "a corner point number")?;
            *v = id
                .checked_sub(first)
                .filter(|&i| i < n_nodes)
                .ok_or_else(|| c.err_at(ln, no_such_point(id, first, n_nodes)))?;
        }
        let mut tag = 0;
        for a in 0..nattr {
            let (tok, ln) = c.expect_token("a tetrahedron attribute")?;
            let v: f64 = super::cursor::parse_at(path, ln, tok, "a numeric attribute")?;
            if a == 0 {
                tag = float_to_tag(v)
                    .ok_or_else(|| c.err_at(ln, format!("region attribute {v} is not an integer tag")))?;
            }
        }
        tets.push(t);
        tags.push(tag);
    }
    c.expect_no_more_records(n, "tetrahedra", header)?;
    Ok((tets, tags))
}

/// The error for a corner `id` that names no point: the valid numbers written
/// as an inclusive range (`1..=5`), since `first..first + n` read as "up to 6".
fn no_such_point(id: usize, first: usize, n_nodes: usize) -> String {
    match n_nodes {
        0 => format!("point number {id}: the .node file holds no points"),
        n => format!(
            "point number {id} is outside {first}..={} (the .node file has {n} point(s), numbered from {first})",
            first + n - 1
        ),
    }
}

/// Writes both files (numbering from 1, TetGen's default; tags as the region
/// attribute). Each file is written atomically.
pub fn write(path: &Path, mesh: &TetMesh) -> Result<()> {
    let (node_path, ele_path) = sibling_paths(path);
    write_atomic(&node_path, |w| {
        writeln!(w, "# written by HEML\n{} 3 0 0", mesh.n_nodes())?;
        for (i, p) in mesh.nodes().iter().enumerate() {
            writeln!(w, "{} {:e} {:e} {:e}", i + 1, p.x, p.y, p.z)?;
        }
        Ok(())
    })?;
    write_atomic(&ele_path, |w| {
        writeln!(w, "# written by HEML\n{} 4 1", mesh.n_tets())?;
        for (k, (t, tag)) in mesh.tets().iter().zip(mesh.tags()).enumerate() {
            writeln!(w, "{} {} {} {} {} {tag}", k + 1, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1)?;
        }
        Ok(())
    })
}
