//! Gmsh `.msh` files, ASCII versions 2.2 (any 2.x) and 4.1.
//!
//! * Nodes may carry arbitrary, non-contiguous tags (v4.1 files often do); they are
//!   mapped to dense indices in file order.
//! * Region tag of a tet: v2: the first element tag (the physical group; 0 when the
//!   element has no tags). v4.1: if the `$Entities` section gives any volume a
//!   physical group, the first physical tag of the element's volume (0 for volumes
//!   without one); otherwise the element's volume (entity) tag, so that distinct
//!   volumes stay distinguishable in meshes saved without physical groups.
//! * 4-node tets (type 4) are read; points, lines and surface elements are skipped
//!   and counted; other volume elements (hexahedra, prisms, pyramids and quadratic
//!   tets, e.g. type 11) are an error, because dropping them would silently remove
//!   material. Re-export such meshes with linear tets (`gmsh -3 -order 1`).
//! * Binary `.msh` is refused with an explicit message: it is easy to re-save as
//!   ASCII and supporting it would double the parser for little gain.
//! * Unknown sections (`$PhysicalNames`, `$NodeData`, …) are skipped.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use super::atomic::write_atomic;
use super::cursor::{capacity, finite_point, parse_at, shorten, Cursor};
use super::{no_tets_message, read_bytes, MeshData, MeshFormat};
use crate::error::{HemlError, Result};
use crate::mesh::TetMesh;
use crate::Vec3;

/// The two supported ASCII versions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Version {
    /// Version 2.2 (legacy, still written by many tools).
    V22,
    /// Version 4.1 (current Gmsh default).
    V41,
}

/// How the reader treats a Gmsh element type.
enum Kind {
    Tet,
    Skip(&'static str),
    Volume(&'static str),
}

fn kind(element_type: i64) -> Kind {
    match element_type {
        4 => Kind::Tet,
        15 => Kind::Skip("point"),
        1 | 8 | 26 | 27 | 28 => Kind::Skip("line"),
        2 | 9 | 20 | 21 | 22 | 23 | 24 | 25 => Kind::Skip("triangle"),
        3 | 10 | 16 | 36 | 37 | 38 => Kind::Skip("quadrangle"),
        5 | 12 | 17 | 92 | 93 => Kind::Volume("hexahedron"),
        6 | 13 | 18 => Kind::Volume("prism"),
        7 | 14 | 19 => Kind::Volume("pyramid"),
        11 | 29 | 30 | 31 => Kind::Volume("high-order tetrahedron"),
        _ => Kind::Skip("other"),
    }
}

/// Reads a Gmsh file, returning the data and the detected version.
pub fn read(path: &Path) -> Result<(MeshData, MeshFormat)> {
    let bytes = read_bytes(path)?;
    parse(path, &bytes)
}

/// Parses the bytes of a Gmsh file (`path` is only used in error messages).
pub fn parse(path: &Path, bytes: &[u8]) -> Result<(MeshData, MeshFormat)> {
    let mut c = Cursor::new(path, bytes, None);
    let mut version: Option<Version> = None;
    let mut data = MeshData::default();
    let mut node_index: HashMap<u64, usize> = HashMap::new();
    let mut have_nodes = false;
    let mut have_elements = false;
    // v4.1: volume entity tag → first physical tag (if any), and tets' entity tags.
    let mut volume_physical: Option<HashMap<i32, Option<i32>>> = None;
    let mut tet_entities: Vec<i32> = Vec::new();

    while let Some((line, ln)) = c.next_line()? {
        let name = line.split_ascii_whitespace().next().unwrap_or("");
        if !name.starts_with('$') {
            return Err(c.err_at(
                ln,
                format!("expected a section header such as $Nodes, found '{}'", shorten(line)),
            ));
        }
        match (name, version) {
            ("$MeshFormat", _) => {
                version = Some(read_format(&mut c)?);
                expect_end(&mut c, "$EndMeshFormat")?;
            }
            (_, None) => {
                return Err(c.err_at(
                    ln,
                    format!("expected $MeshFormat before {name} (is this a Gmsh .msh file?)"),
                ));
            }
            ("$Entities", Some(Version::V41)) => {
                volume_physical = Some(read_entities(&mut c)?);
                expect_end(&mut c, "$EndEntities")?;
            }
            ("$Nodes", Some(v)) => {
                if have_nodes {
                    return Err(c.err_at(ln, "second $Nodes section (only one is supported)"));
                }
                match v {
                    Version::V22 => read_nodes_v2(&mut c, &mut data, &mut node_index)?,
                    Version::V41 => read_nodes_v41(&mut c, &mut data, &mut node_index)?,
                }
                expect_end(&mut c, "$EndNodes")?;
                have_nodes = true;
            }
            ("$Elements", Some(v)) => {
                if !have_nodes {
                    return Err(c.err_at(ln, "$Elements before $Nodes"));
                }
                if have_elements {
                    return Err(c.err_at(ln, "second $Elements section (only one is supported)"));
                }
                match v {
                    Version::V22 => read_elements_v2(&mut c, &mut data, &node_index)?,
                    Version::V41 => read_elements_v41(&mut c, &mut data, &node_index, &mut tet_entities)?,
                }
                expect_end(&mut c, "$EndElements")?;
                have_elements = true;
            }
            _ => skip_section(&mut c, name, ln)?,
        }
    }
    let Some(version) = version else {
        return Err(c.err_at(1, "no $MeshFormat section (empty file or not a Gmsh .msh file)"));
    };
    if !have_nodes {
        return Err(c.err("missing $Nodes section"));
    }
    if !have_elements {
        return Err(c.err("missing $Elements section"));
    }
    if data.tets.is_empty() {
        return Err(c.err(no_tets_message(&data)));
    }
    if version == Version::V41 {
        data.tags = match &volume_physical {
            Some(phys) if phys.values().any(Option::is_some) => tet_entities
                .iter()
                .map(|e| phys.get(e).copied().flatten().unwrap_or(0))
                .collect(),
            _ => tet_entities,
        };
    }
    let format = match version {
        Version::V22 => MeshFormat::Gmsh22,
        Version::V41 => MeshFormat::Gmsh41,
    };
    Ok((data, format))
}

fn read_format(c: &mut Cursor<'_>) -> Result<Version> {
    let (line, ln) = c.expect_line("the $MeshFormat line")?;
    let f: Vec<&str> = line.split_ascii_whitespace().collect();
    if f.len() < 3 {
        return Err(c.err_at(
            ln,
            format!("expected 'version file-type data-size', found '{}'", shorten(line)),
        ));
    }
    let version = match f[0] {
        "4.1" => Version::V41,
        v if v.starts_with("2.") || v == "2" => Version::V22,
        v => {
            return Err(c.err_at(
                ln,
                format!(
                    "unsupported .msh version {}; supported: 2.2 and 4.1 ASCII (re-save with Gmsh)",
                    shorten(v)
                ),
            ))
        }
    };
    let file_type: i64 = parse_at(c.file(), ln, f[1], "file-type 0 (ASCII) or 1 (binary)")?;
    if file_type != 0 {
        return Err(c.err_at(
            ln,
            "binary .msh not supported, re-save as ASCII (Gmsh: File > Export, or `gmsh -save -format msh41 -bin 0`)",
        ));
    }
    let size: i64 = parse_at(c.file(), ln, f[2], "data-size")?;
    if size != 8 {
        return Err(c.err_at(ln, format!("unsupported data-size {size}, expected 8")));
    }
    Ok(version)
}

fn expect_end(c: &mut Cursor<'_>, end: &str) -> Result<()> {
    let (line, ln) = c.expect_line(end)?;
    if line != end {
        return Err(c.err_at(
            ln,
            format!("expected {end}, found '{}' (wrong element/node count?)", shorten(line)),
        ));
    }
    Ok(())
}

fn skip_section(c: &mut Cursor<'_>, name: &str, start: usize) -> Result<()> {
    let end = format!("$End{}", &name[1..]);
    loop {
        match c.next_line()? {
            Some((line, _)) if line == end => return Ok(()),
            Some(_) => {}
            None => return Err(c.err_at(start, format!("section {name} is not closed by {end}"))),
        }
    }
}

fn count(c: &mut Cursor<'_>, what: &str) -> Result<usize> {
    c.parse::<usize>(what)
}

fn add_node(
    c: &Cursor<'_>,
    ln: usize,
    tag: u64,
    p: Vec3,
    data: &mut MeshData,
    map: &mut HashMap<u64, usize>,
) -> Result<()> {
    if map.insert(tag, data.nodes.len()).is_some() {
        return Err(c.err_at(ln, format!("node tag {tag} appears twice")));
    }
    data.nodes.push(p);
    Ok(())
}

fn read_nodes_v2(c: &mut Cursor<'_>, data: &mut MeshData, map: &mut HashMap<u64, usize>) -> Result<()> {
    let header = c.line_of_next_token();
    let n = count(c, "the number of nodes")?;
    // a node line holds 4 numbers and their separators: 8 bytes at least
    data.nodes.reserve(capacity(n, c.remaining(), 8));
    for k in 0..n {
        let (tag, ln) = c.record_number::<u64>(k, n, "nodes", header)?;
        let p = finite_point(c, tag)?;
        add_node(c, ln, tag, p, data, map)?;
    }
    Ok(())
}

fn read_nodes_v41(c: &mut Cursor<'_>, data: &mut MeshData, map: &mut HashMap<u64, usize>) -> Result<()> {
    let header_line = c.line_of_next_token();
    let blocks = count(c, "the number of node entity blocks")?;
    let total = count(c, "the number of nodes")?;
    c.parse::<u64>("the minimum node tag")?;
    c.parse::<u64>("the maximum node tag")?;
    // a node costs a tag and 3 coordinates with separators: 8 bytes at least
    data.nodes.reserve(capacity(total, c.remaining(), 8));
    for _ in 0..blocks {
        let dim = c.parse::<i64>("the entity dimension of a node block")?;
        c.parse::<i32>("the entity tag of a node block")?;
        let parametric = c.parse::<i64>("the parametric flag (0 or 1) of a node block")?;
        let n = count(c, "the number of nodes in a block")?;
        let extra = if parametric == 1 { dim.clamp(0, 3) as usize } else { 0 };
        // a node tag and its separator: 2 bytes at least
        let mut tags = Vec::with_capacity(capacity(n, c.remaining(), 2));
        for _ in 0..n {
            let (tok, ln) = c.expect_token("a node tag")?;
            tags.push((parse_at::<u64>(c.file(), ln, tok, "a node tag")?, ln));
        }
        for &(tag, _) in &tags {
            let ln = c.line_of_next_token();
            let p = finite_point(c, tag)?;
            for _ in 0..extra {
                c.parse::<f64>("a parametric coordinate")?;
            }
            add_node(c, ln, tag, p, data, map)?;
        }
    }
    if data.nodes.len() != total {
        return Err(c.err_at(
            header_line,
            format!(
                "the $Nodes header announces {total} nodes but the blocks hold {}",
                data.nodes.len()
            ),
        ));
    }
    Ok(())
}

fn node_of(c: &Cursor<'_>, ln: usize, tok: &str, map: &HashMap<u64, usize>) -> Result<usize> {
    let tag: u64 = parse_at(c.file(), ln, tok, "a node tag")?;
    map.get(&tag)
        .copied()
        .ok_or_else(|| c.err_at(ln, format!("element refers to node {tag}, which is not in $Nodes")))
}

fn tet_nodes<'t>(
    c: &Cursor<'_>,
    ln: usize,
    toks: impl Iterator<Item = &'t str>,
    map: &HashMap<u64, usize>,
) -> Result<[usize; 4]> {
    let toks: Vec<&str> = toks.collect();
    if toks.len() != 4 {
        return Err(c.err_at(ln, format!("a 4-node tetrahedron lists {} nodes", toks.len())));
    }
    let mut t = [0; 4];
    for (k, tok) in toks.iter().enumerate() {
        t[k] = node_of(c, ln, tok, map)?;
    }
    Ok(t)
}

fn volume_error(c: &Cursor<'_>, ln: usize, ty: i64, name: &str) -> HemlError {
    c.err_at(
        ln,
        format!(
            "element type {ty} ({name}) is a volume element HEML cannot simulate; only 4-node tetrahedra \
             (type 4) are supported: re-mesh with linear tets (gmsh -3 -order 1)"
        ),
    )
}

fn read_elements_v2(c: &mut Cursor<'_>, data: &mut MeshData, map: &HashMap<u64, usize>) -> Result<()> {
    let n = count(c, "the number of elements")?;
    for _ in 0..n {
        let (line, ln) = c.expect_line("an element line")?;
        let mut f = line.split_ascii_whitespace();
        let mut next = |what: &str| {
            f.next()
                .ok_or_else(|| c.err_at(ln, format!("element line ends before its {what}")))
        };
        parse_at::<u64>(c.file(), ln, next("number")?, "an element number")?;
        let ty: i64 = parse_at(c.file(), ln, next("type")?, "an element type")?;
        let ntags: usize = parse_at(c.file(), ln, next("number of tags")?, "the number of element tags")?;
        let mut tag = 0;
        for k in 0..ntags {
            let t: i32 = parse_at(c.file(), ln, next("tags")?, "an integer element tag")?;
            if k == 0 {
                tag = t;
            }
        }
        match kind(ty) {
            Kind::Tet => {
                data.tets.push(tet_nodes(c, ln, f, map)?);
                data.tags.push(tag);
            }
            Kind::Skip(name) => data.skip(name),
            Kind::Volume(name) => return Err(volume_error(c, ln, ty, name)),
        }
    }
    Ok(())
}

fn read_elements_v41(
    c: &mut Cursor<'_>,
    data: &mut MeshData,
    map: &HashMap<u64, usize>,
    entities: &mut Vec<i32>,
) -> Result<()> {
    let header_line = c.line_of_next_token();
    let blocks = count(c, "the number of element entity blocks")?;
    let total = count(c, "the number of elements")?;
    c.parse::<u64>("the minimum element tag")?;
    c.parse::<u64>("the maximum element tag")?;
    let mut seen = 0usize;
    for _ in 0..blocks {
        c.parse::<i64>("the entity dimension of an element block")?;
        let entity = c.parse::<i32>("the entity tag of an element block")?;
        let ty = c.parse::<i64>("the element type of a block")?;
        let ln = c.line_of_next_token();
        let n = count(c, "the number of elements in a block")?;
        let k = kind(ty);
        if let Kind::Volume(name) = k {
            return Err(volume_error(c, ln, ty, name));
        }
        for _ in 0..n {
            let (line, ln) = c.expect_line("an element line")?;
            let mut f = line.split_ascii_whitespace();
            let id = f.next().unwrap_or("");
            parse_at::<u64>(c.file(), ln, id, "an element tag")?;
            match k {
                Kind::Tet => {
                    data.tets.push(tet_nodes(c, ln, f, map)?);
                    entities.push(entity);
                }
                Kind::Skip(name) => data.skip(name),
                Kind::Volume(_) => {}
            }
        }
        seen = seen.saturating_add(n);
    }
    if seen != total {
        return Err(c.err_at(
            header_line,
            format!("the $Elements header announces {total} elements but the blocks hold {seen}"),
        ));
    }
    Ok(())
}

/// `$Entities` of v4.1: volume tag → its first physical tag.
fn read_entities(c: &mut Cursor<'_>) -> Result<HashMap<i32, Option<i32>>> {
    let counts = [
        count(c, "the number of points")?,
        count(c, "the number of curves")?,
        count(c, "the number of surfaces")?,
        count(c, "the number of volumes")?,
    ];
    let mut volumes = HashMap::new();
    for (dim, &n) in counts.iter().enumerate() {
        // points: tag x y z; others: tag and a bounding box of 6 numbers
        let skip = if dim == 0 { 3 } else { 6 };
        for _ in 0..n {
            let (line, ln) = c.expect_line("an entity line")?;
            let f: Vec<&str> = line.split_ascii_whitespace().collect();
            let get = |i: usize| {
                f.get(i)
                    .copied()
                    .ok_or_else(|| c.err_at(ln, "entity line is too short"))
            };
            let tag: i32 = parse_at(c.file(), ln, get(0)?, "an entity tag")?;
            let nphys: usize = parse_at(c.file(), ln, get(1 + skip)?, "the number of physical tags")?;
            let phys = if nphys > 0 {
                Some(parse_at::<i32>(c.file(), ln, get(2 + skip)?, "a physical tag")?)
            } else {
                None
            };
            if dim == 3 {
                volumes.insert(tag, phys);
            }
        }
    }
    Ok(volumes)
}

/// Writes `mesh` as an ASCII `.msh` of the given version. Tags become physical
/// groups: one volume entity per distinct tag (so v4.1 files keep tags through the
/// `$Entities` section); coordinates are printed in shortest round-trip form.
pub fn write(path: &Path, mesh: &TetMesh, version: Version) -> Result<()> {
    write_atomic(path, |w| match version {
        Version::V22 => write_v22(w, mesh),
        Version::V41 => write_v41(w, mesh),
    })
}

/// Distinct tags in order of appearance → 1-based entity tag.
fn entity_of_tag(mesh: &TetMesh) -> BTreeMap<i32, usize> {
    let mut m = BTreeMap::new();
    for &t in mesh.tags() {
        let n = m.len() + 1;
        m.entry(t).or_insert(n);
    }
    m
}

fn write_v22(w: &mut BufWriter<File>, mesh: &TetMesh) -> std::io::Result<()> {
    writeln!(w, "$MeshFormat\n2.2 0 8\n$EndMeshFormat")?;
    writeln!(w, "$Nodes\n{}", mesh.n_nodes())?;
    for (i, p) in mesh.nodes().iter().enumerate() {
        writeln!(w, "{} {:e} {:e} {:e}", i + 1, p.x, p.y, p.z)?;
    }
    writeln!(w, "$EndNodes\n$Elements\n{}", mesh.n_tets())?;
    let entity = entity_of_tag(mesh);
    for (k, (t, tag)) in mesh.tets().iter().zip(mesh.tags()).enumerate() {
        let e = entity.get(tag).copied().unwrap_or(1);
        writeln!(
            w,
            "{} 4 2 {tag} {e} {} {} {} {}",
            k + 1,
            t[0] + 1,
            t[1] + 1,
            t[2] + 1,
            t[3] + 1
        )?;
    }
    writeln!(w, "$EndElements")
}

fn write_v41(w: &mut BufWriter<File>, mesh: &TetMesh) -> std::io::Result<()> {
    writeln!(w, "$MeshFormat\n4.1 0 8\n$EndMeshFormat")?;
    let entity = entity_of_tag(mesh);
    // per-entity bounding boxes
    let mut bbox: BTreeMap<usize, (Vec3, Vec3)> = BTreeMap::new();
    for (t, tag) in mesh.tets().iter().zip(mesh.tags()) {
        let e = entity.get(tag).copied().unwrap_or(1);
        let b = bbox
            .entry(e)
            .or_insert((Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY)));
        for &i in t {
            let p = mesh.nodes()[i as usize];
            b.0 = b.0.inf(&p);
            b.1 = b.1.sup(&p);
        }
    }
    writeln!(w, "$Entities\n0 0 0 {}", entity.len())?;
    let mut by_entity: Vec<(usize, i32)> = entity.iter().map(|(&t, &e)| (e, t)).collect();
    by_entity.sort_unstable();
    for (e, tag) in by_entity {
        let (lo, hi) = bbox.get(&e).copied().unwrap_or((Vec3::zeros(), Vec3::zeros()));
        writeln!(
            w,
            "{e} {:e} {:e} {:e} {:e} {:e} {:e} 1 {tag} 0",
            lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
        )?;
    }
    writeln!(w, "$EndEntities")?;
    let n = mesh.n_nodes();
    writeln!(w, "$Nodes\n1 {n} {} {n}\n3 1 0 {n}", n.min(1))?;
    for i in 1..=n {
        writeln!(w, "{i}")?;
    }
    for p in mesh.nodes() {
        writeln!(w, "{:e} {:e} {:e}", p.x, p.y, p.z)?;
    }
    writeln!(w, "$EndNodes")?;
    // one element block per run of equal tags, so that tet order is preserved
    let tags = mesh.tags();
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for k in 0..tags.len() {
        match runs.last_mut() {
            Some((start, len)) if tags[*start] == tags[k] => *len += 1,
            _ => runs.push((k, 1)),
        }
    }
    let m = mesh.n_tets();
    writeln!(w, "$Elements\n{} {m} {} {m}", runs.len(), m.min(1))?;
    for (start, len) in runs {
        let e = entity.get(&tags[start]).copied().unwrap_or(1);
        writeln!(w, "3 {e} 4 {len}")?;
        for k in start..start + len {
            let t = mesh.tets()[k];
            writeln!(w, "{} {} {} {} {}", k + 1, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1)?;
        }
    }
    writeln!(w, "$EndElements")
}
