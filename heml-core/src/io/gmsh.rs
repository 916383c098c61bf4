//! Gmsh `.msh` files: versions 1 (`$NOD`/`$ELM`), 2.2 (any 2.x) and 4.1, ASCII
//! or binary (either byte order, see `gmsh_binary`).
//!
//! * Nodes may carry arbitrary, non-contiguous tags (v4.1 and v1 files often do);
//!   they are mapped to dense indices in file order.
//! * Region tag of a tet: v1: its physical region; v2: the first element tag (the
//!   physical group; 0 when the element has no tags). v4.1: if the `$Entities`
//!   section gives any volume a physical group, the first physical tag of the
//!   element's volume (0 for volumes without one); otherwise the element's volume
//!   (entity) tag, so that distinct volumes stay distinguishable in meshes saved
//!   without physical groups.
//! * 4-node tets (type 4) are read, and 8-node hexahedra (type 5), which the load
//!   splits into tets ([`MeshData::split_hexes`]); points, lines and surface
//!   elements of any order are skipped and counted; other volume elements (prisms,
//!   pyramids, polyhedra, quadratic and higher-order tets and hexes, e.g. type 11)
//!   and numbers outside Gmsh's table of types are an error, because dropping them
//!   would silently remove material. Re-export such meshes with linear elements
//!   (`gmsh -3 -order 1`).
//! * Node lines of versions 1 and 2 are `tag x y z`, one node per line, and the
//!   coordinate lines of a 4.1 node block `x y z` (`x y z u …` in parametric
//!   blocks): a line with a number missing or extra is an error at that line (read
//!   as a token stream, it would shift every later node and be reported lines
//!   further on, or not at all).
//! * Binary records are checked against the bytes left in the file before they
//!   are reserved or read (a header announcing 10¹⁸ nodes is an error, not an
//!   allocation); errors in binary data name the line and the byte offset.
//! * `$ElementData` blocks of 3 components (fibre directions) become cell vector
//!   fields by their name (the first string tag), see `gmsh_data`.
//! * Physical groups of points, curves and surfaces become node sets named by
//!   `$PhysicalNames` (or `"surface 7"`, …), see `gmsh_groups`.
//! * Unknown sections (`$NodeData`, `$Periodic`, …) are skipped.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use super::atomic::write_atomic;
use super::cursor::{capacity, coordinates_line, finite_point_on_line, parse_at, shorten, Cursor, NodeLine};
use super::gmsh_binary::Binary;
use super::gmsh_data::{ElementData, ElementIds};
use super::gmsh_groups::{dimension, BoundaryGroups, GroupOf};
use super::{no_tets_message, read_bytes, MeshData, MeshFormat};
use crate::error::{HemlError, Result};
use crate::mesh::TetMesh;
use crate::Vec3;

/// The versions the writers produce.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Version {
    /// Version 1 (`$NOD`/`$ELM`; ASCII only), for tools as old as SOFA's loaders.
    V1,
    /// Version 2.2 (legacy, still written by many tools).
    V22,
    /// Version 4.1 (current Gmsh default).
    V41,
}

/// How the reader treats a Gmsh element type.
#[derive(Clone, Copy)]
enum Kind {
    Tet,
    /// A linear hexahedron, split into tets at load.
    Hex,
    /// A point, line or surface element (of any order): skipped and counted.
    Skip(&'static str),
    /// A volume element HEML does not simulate: an error.
    Volume(&'static str),
    /// A number outside Gmsh's table: an error too, since it may be a volume.
    Unknown,
}

/// Every Gmsh element type (`MSH_*` in Gmsh's `GmshDefines.h`, 1–140; the
/// dimensions are `ElementType::getDimension`'s). Only the types known to be
/// points, lines or surfaces are skipped: an unknown or volume type is refused,
/// because skipping it would silently remove material from the body.
fn kind(element_type: i64) -> Kind {
    match element_type {
        4 => Kind::Tet,
        5 => Kind::Hex,
        // 0-D: MSH_PNT, MSH_PNT_SUB
        15 | 133 => Kind::Skip("point"),
        // 1-D: MSH_LIN_2..11, MSH_LIN_B, MSH_LIN_C, MSH_LIN_1, MSH_LIN_SUB
        1 | 8 | 26..=28 | 62..=67 | 70 | 84 | 134 => Kind::Skip("line"),
        // 2-D: triangles of every order, MSH_TRI_B, MSH_TRI_1, MSH_TRI_SUB, MSH_TRI_MINI
        2 | 9 | 20..=25 | 42..=46 | 52..=56 | 68 | 85 | 135 | 138 => Kind::Skip("triangle"),
        // 2-D: quadrangles of every order, MSH_QUA_1
        3 | 10 | 16 | 36..=41 | 47..=51 | 57..=61 | 86 => Kind::Skip("quadrangle"),
        // 2-D: MSH_POLYG_, MSH_POLYG_B
        34 | 69 => Kind::Skip("polygon"),
        // 3-D
        11 | 29..=33 | 71..=75 | 79..=83 | 137 => Kind::Volume("high-order tetrahedron"),
        87 | 136 | 139 => Kind::Volume("order-0, XFEM or MINI tetrahedron"),
        12 | 17 | 88 | 92..=105 => Kind::Volume("hexahedron other than the 8-node linear one"),
        6 | 13 | 18 | 89..=91 | 106..=117 => Kind::Volume("prism"),
        7 | 14 | 19 | 118..=132 => Kind::Volume("pyramid"),
        35 => Kind::Volume("polyhedron"),
        140 => Kind::Volume("trihedron"),
        _ => Kind::Unknown,
    }
}

/// Number of nodes of a Gmsh element type (Gmsh's `ElementType::getNumVertices`),
/// needed to step over binary records; `None` for the types whose count is not
/// fixed (polygons, Bézier and XFEM elements, MINI triangles) and the types this
/// reader refuses anyway (volumes other than the 4-node tet and 8-node hex).
fn nodes_per_element(element_type: i64) -> Option<usize> {
    Some(match element_type {
        15 | 84..=86 => 1,
        1 => 2,
        2 | 8 => 3,
        3 | 4 | 26 => 4,
        27 => 5,
        9 | 28 => 6,
        62..=66 => element_type as usize - 55,
        5 | 16 => 8,
        10 | 20 => 9,
        21 => 10,
        22 | 39 => 12,
        23 | 24 => 15,
        36 | 40 => 16,
        52 => 18,
        41 => 20,
        25 | 53 => 21,
        54 | 57 => 24,
        37 => 25,
        55 => 27,
        42 | 58 => 28,
        56 => 30,
        59 => 32,
        38 | 43 | 60 => 36,
        61 => 40,
        44 => 45,
        47 => 49,
        45 => 55,
        48 => 64,
        46 => 66,
        49 => 81,
        50 => 100,
        51 => 121,
        _ => return None,
    })
}

/// Why element type `ty` cannot be read, or `None` for a tet, a hex or a skipped
/// element; the callers add where (line or byte offset) and the file.
fn refusal(ty: i64) -> Option<String> {
    const ONLY: &str = "only linear tetrahedra (type 4) and linear hexahedra (type 5, split into tets at load) \
                        are simulated";
    match kind(ty) {
        Kind::Tet | Kind::Hex | Kind::Skip(_) => None,
        Kind::Volume(name) => Some(format!(
            "element type {ty} ({name}) is a volume element HEML cannot simulate: {ONLY}; re-mesh with \
             linear elements (gmsh -3 -order 1)"
        )),
        Kind::Unknown => Some(format!(
            "element type {ty} is not a Gmsh element type (1 to 140, as in Gmsh's GmshDefines.h) and may be \
             a volume, which must not be dropped: {ONLY}"
        )),
    }
}

/// The layout of the file being read: version family and, for binary files,
/// byte order and `size_t` width.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Header {
    dialect: Dialect,
    binary: Option<Binary>,
}

/// Version family of a file being read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Dialect {
    /// Gmsh 1 (`$NOD`/`$ELM`, no `$MeshFormat`), as SOFA ships its meshes.
    V1,
    /// Version 2.x.
    V2,
    /// Version 4.1.
    V41,
}

/// Reads a Gmsh file, returning the data and the detected version.
pub fn read(path: &Path) -> Result<(MeshData, MeshFormat)> {
    let bytes = read_bytes(path)?;
    parse(path, &bytes)
}

/// Parses the bytes of a Gmsh file (`path` is only used in error messages).
pub fn parse(path: &Path, bytes: &[u8]) -> Result<(MeshData, MeshFormat)> {
    let mut c = Cursor::new(path, bytes, None);
    let mut header: Option<Header> = None;
    let mut data = MeshData::default();
    let mut node_index: HashMap<u64, usize> = HashMap::new();
    let mut have_nodes = false;
    let mut have_elements = false;
    // v4.1: volume entity tag → first physical tag (if any), and tets' entity tags.
    let mut volume_physical: Option<HashMap<i32, Option<i32>>> = None;
    // element numbers of the tets and hexes, and the `$ElementData` blocks
    let mut ids = ElementIds::default();
    let mut element_data: Vec<ElementData> = Vec::new();
    // physical groups of points, curves and surfaces: node sets
    let mut groups = BoundaryGroups::default();

    while let Some((line, ln)) = c.next_line()? {
        let name = line.split_ascii_whitespace().next().unwrap_or("");
        if !name.starts_with('$') {
            return Err(c.err_at(
                ln,
                format!("expected a section header such as $Nodes, found '{}'", shorten(line)),
            ));
        }
        let dialect = header.map(|h| h.dialect);
        let bin = header.and_then(|h| h.binary);
        match (name, dialect) {
            ("$MeshFormat", None | Some(Dialect::V2 | Dialect::V41)) => {
                header = Some(read_format(&mut c)?);
                expect_end(&mut c, "$EndMeshFormat")?;
            }
            ("$NOD", None | Some(Dialect::V1)) | ("$ELM", Some(Dialect::V1)) => {
                header = Some(Header {
                    dialect: Dialect::V1,
                    binary: None,
                });
                if name == "$NOD" {
                    if have_nodes {
                        return Err(c.err_at(ln, "second $NOD section (only one is supported)"));
                    }
                    read_nodes_v2(&mut c, &mut data, &mut node_index)?;
                    expect_end(&mut c, "$ENDNOD")?;
                    have_nodes = true;
                } else {
                    if !have_nodes {
                        return Err(c.err_at(ln, "$ELM before $NOD"));
                    }
                    if have_elements {
                        return Err(c.err_at(ln, "second $ELM section (only one is supported)"));
                    }
                    read_element_lines(&mut c, &mut data, &mut ids, &mut groups, &node_index, true)?;
                    expect_end(&mut c, "$ENDELM")?;
                    have_elements = true;
                }
            }
            ("$MeshFormat" | "$NOD" | "$ELM", Some(d)) => {
                return Err(c.err_at(
                    ln,
                    format!(
                        "section {name} does not belong in a {} file ($NOD/$ELM are Gmsh 1, $MeshFormat \
                         starts Gmsh 2 and 4 files)",
                        dialect_name(d)
                    ),
                ));
            }
            (_, None) => {
                return Err(c.err_at(
                    ln,
                    format!(
                        "expected $MeshFormat (Gmsh 2 and 4) or $NOD (Gmsh 1) before {} (is this a Gmsh .msh \
                         file?)",
                        shorten(name)
                    ),
                ));
            }
            ("$Entities", Some(Dialect::V41)) => {
                volume_physical = Some(match bin {
                    Some(b) => read_entities_bin(&mut c, b, &mut groups)?,
                    None => read_entities(&mut c, &mut groups)?,
                });
                expect_end(&mut c, "$EndEntities")?;
            }
            ("$Nodes", Some(d)) => {
                if have_nodes {
                    return Err(c.err_at(ln, "second $Nodes section (only one is supported)"));
                }
                match (d, bin) {
                    (Dialect::V41, Some(b)) => read_nodes_v41_bin(&mut c, b, &mut data, &mut node_index)?,
                    (Dialect::V41, None) => read_nodes_v41(&mut c, &mut data, &mut node_index)?,
                    (_, Some(b)) => read_nodes_v2_bin(&mut c, b, &mut data, &mut node_index)?,
                    (_, None) => read_nodes_v2(&mut c, &mut data, &mut node_index)?,
                }
                expect_end(&mut c, "$EndNodes")?;
                have_nodes = true;
            }
            ("$Elements", Some(d)) => {
                if !have_nodes {
                    return Err(c.err_at(ln, "$Elements before $Nodes"));
                }
                if have_elements {
                    return Err(c.err_at(ln, "second $Elements section (only one is supported)"));
                }
                let (data, ids, groups, map) = (&mut data, &mut ids, &mut groups, &node_index);
                match (d, bin) {
                    (Dialect::V41, Some(b)) => read_elements_v41_bin(&mut c, b, data, ids, groups, map)?,
                    (Dialect::V41, None) => read_elements_v41(&mut c, data, ids, groups, map)?,
                    (_, Some(b)) => read_elements_v2_bin(&mut c, b, data, ids, groups, map)?,
                    (_, None) => read_element_lines(&mut c, data, ids, groups, map, false)?,
                }
                expect_end(&mut c, "$EndElements")?;
                have_elements = true;
            }
            ("$PhysicalNames", Some(Dialect::V2 | Dialect::V41)) => {
                groups.read_names(&mut c)?;
                expect_end(&mut c, "$EndPhysicalNames")?;
            }
            ("$ElementData", Some(Dialect::V2 | Dialect::V41)) => {
                element_data.push(ElementData::read(&mut c, bin, ln)?);
                expect_end(&mut c, "$EndElementData")?;
            }
            (_, Some(_)) if bin.is_some() => skip_binary_section(&mut c, name, ln)?,
            _ => skip_section(&mut c, name, ln)?,
        }
    }
    let Some(header) = header else {
        return Err(c.err_at(1, "no $MeshFormat or $NOD section (empty file or not a Gmsh .msh file)"));
    };
    let (nodes_name, elements_name) = match header.dialect {
        Dialect::V1 => ("$NOD", "$ELM"),
        _ => ("$Nodes", "$Elements"),
    };
    if !have_nodes {
        return Err(c.err(format!("missing {nodes_name} section")));
    }
    if !have_elements {
        return Err(c.err(format!("missing {elements_name} section")));
    }
    if data.tets.is_empty() && data.hexes.is_empty() {
        return Err(c.err(no_tets_message(&data)));
    }
    // v4.1 elements were tagged with their volume entity: map to physical groups
    if let (Dialect::V41, Some(phys)) = (header.dialect, &volume_physical) {
        if phys.values().any(Option::is_some) {
            for t in data.tags.iter_mut().chain(data.hex_tags.iter_mut()) {
                *t = phys.get(t).copied().flatten().unwrap_or(0);
            }
        }
    }
    super::gmsh_data::attach(&mut data, &ids, element_data);
    data.node_sets = groups.into_node_sets();
    let format = match (header.dialect, header.binary.is_some()) {
        (Dialect::V1, _) => MeshFormat::Gmsh1,
        (Dialect::V2, false) => MeshFormat::Gmsh22,
        (Dialect::V2, true) => MeshFormat::Gmsh22Binary,
        (Dialect::V41, false) => MeshFormat::Gmsh41,
        (Dialect::V41, true) => MeshFormat::Gmsh41Binary,
    };
    Ok((data, format))
}

fn dialect_name(d: Dialect) -> &'static str {
    match d {
        Dialect::V1 => "Gmsh 1 ($NOD/$ELM)",
        Dialect::V2 => "Gmsh 2",
        Dialect::V41 => "Gmsh 4.1",
    }
}

fn read_format(c: &mut Cursor<'_>) -> Result<Header> {
    let (line, ln) = c.expect_line("the $MeshFormat line")?;
    let f: Vec<&str> = line.split_ascii_whitespace().collect();
    if f.len() < 3 {
        return Err(c.err_at(
            ln,
            format!("expected 'version file-type data-size', found '{}'", shorten(line)),
        ));
    }
    let dialect = match f[0] {
        "4.1" => Dialect::V41,
        v if v.starts_with("2.") || v == "2" => Dialect::V2,
        v => {
            return Err(c.err_at(
                ln,
                format!(
                    "unsupported .msh version {}; supported: 1 ($NOD/$ELM), 2.2 and 4.1, ASCII or binary \
                     (re-save with Gmsh)",
                    shorten(v)
                ),
            ))
        }
    };
    let file_type: i64 = parse_at(c.file(), ln, f[1], "file-type 0 (ASCII) or 1 (binary)")?;
    let size: i64 = parse_at(c.file(), ln, f[2], "data-size")?;
    // data-size is sizeof(double) in 2.x and sizeof(size_t) in 4.1 (4 on 32-bit writers)
    let sizes: &[i64] = if dialect == Dialect::V41 { &[4, 8] } else { &[8] };
    if !sizes.contains(&size) {
        let want = if dialect == Dialect::V41 { "4 or 8" } else { "8" };
        return Err(c.err_at(ln, format!("unsupported data-size {size}, expected {want}")));
    }
    let binary = match file_type {
        0 => None,
        // the integer 1 in binary follows the line (the cursor stands right after it)
        1 => Some(Binary::detect(c, size as usize)?),
        other => return Err(c.err_at(ln, format!("file-type {other}: expected 0 (ASCII) or 1 (binary)"))),
    };
    Ok(Header { dialect, binary })
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

/// Skips an unknown section of a binary file, whose records may hold any byte
/// (the line reader would refuse them as text) up to its `$End` keyword.
fn skip_binary_section(c: &mut Cursor<'_>, name: &str, start: usize) -> Result<()> {
    let end = format!("$End{}", &name[1..]);
    if c.skip_past(end.as_bytes()) {
        Ok(())
    } else {
        Err(c.err_at(start, format!("section {name} is not closed by {end}")))
    }
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
        let p = finite_point_on_line(c, tag, ln)?;
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
        check_node_block(dim, parametric).map_err(|why| c.err(why))?;
        let n = count(c, "the number of nodes in a block")?;
        let extra = if parametric == 1 { dim as usize } else { 0 };
        let what = NodeLine {
            layout: ["x y z", "x y z u", "x y z u v", "x y z u v w"][extra],
            extra,
        };
        // a node tag and its separator: 2 bytes at least
        let mut tags = Vec::with_capacity(capacity(n, c.remaining(), 2));
        for k in 0..n {
            tags.push(tag_line(c, k, n)?);
        }
        for &tag in &tags {
            let (p, ln) = coordinates_line(c, tag, what)?;
            add_node(c, ln, tag, p, data, map)?;
        }
    }
    check_total(c, header_line, "$Nodes", total, data.nodes.len(), "nodes")
}

/// The `k`-th of a v4.1 node block's `n` tag lines: one tag alone on its line. Read
/// as a token stream, a line with two numbers (or a block short of a tag, whose first
/// coordinate line `0 0 0` reads as three tags) would shift every later tag and
/// coordinate, and the error would come lines further on, or not at all.
fn tag_line(c: &mut Cursor<'_>, k: usize, n: usize) -> Result<u64> {
    let (tok, ln) = c.expect_token("a node tag")?;
    let tag = parse_at::<u64>(c.file(), ln, tok, "a node tag")?;
    if let Some((next, l)) = c.clone().token()? {
        if l == ln {
            return Err(c.err_at(
                ln,
                format!(
                    "'{}' follows node tag {tag} (tag {} of {n} in its block); a node block lists one tag per line, then one coordinate line per node",
                    shorten(next),
                    k + 1
                ),
            ));
        }
    }
    Ok(tag)
}

/// The v4.1 header count of a section (at `header_line`) against what its
/// blocks held: a mismatch means a truncated or edited file.
fn check_total(c: &Cursor<'_>, header_line: usize, section: &str, total: usize, held: usize, what: &str) -> Result<()> {
    if held != total {
        return Err(c.err_at(
            header_line,
            format!("the {section} header announces {total} {what} but the blocks hold {held}"),
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

/// The node indices of a tet or hex element line (the tokens after its tags).
fn element_nodes<'t>(
    c: &Cursor<'_>,
    ln: usize,
    toks: impl Iterator<Item = &'t str>,
    map: &HashMap<u64, usize>,
    k: Kind,
) -> Result<Vec<usize>> {
    let toks: Vec<&str> = toks.collect();
    let (want, name) = match k {
        Kind::Hex => (8, "an 8-node hexahedron"),
        _ => (4, "a 4-node tetrahedron"),
    };
    if toks.len() != want {
        return Err(c.err_at(ln, format!("{name} lists {} nodes", toks.len())));
    }
    toks.iter().map(|tok| node_of(c, ln, tok, map)).collect()
}

/// Stores a tet or hex (`nodes` of the right length, checked by the caller) with its
/// region tag and its element number.
fn store(data: &mut MeshData, ids: &mut ElementIds, k: Kind, nodes: &[usize], tag: i32, number: u64) {
    match k {
        Kind::Hex => {
            data.hexes.push(std::array::from_fn(|i| nodes[i]));
            data.hex_tags.push(tag);
            ids.hexes.push(number);
        }
        _ => {
            data.tets.push(std::array::from_fn(|i| nodes[i]));
            data.tags.push(tag);
            ids.tets.push(number);
        }
    }
}

/// Refuses element type `ty` at line `ln` when it is a volume other than the
/// linear tet and hex, or unknown (see [`refusal`]).
fn check_type(c: &Cursor<'_>, ln: usize, ty: i64) -> Result<()> {
    refusal(ty).map_or(Ok(()), |why| Err(c.err_at(ln, why)))
}

/// As [`check_type`] for a binary file: the error names the byte offset of the type.
fn check_binary_type(c: &Cursor<'_>, off: usize, ty: i64) -> Result<()> {
    refusal(ty).map_or(Ok(()), |why| Err(c.err(format!("at byte {off}: {why}"))))
}

/// ASCII element lines, one per element: v2 `number type tag-count tags… nodes…`
/// (the region tag is the first tag), v1 `number type physical-region
/// elementary-region node-count nodes…` (the region tag is the physical region).
fn read_element_lines(
    c: &mut Cursor<'_>,
    data: &mut MeshData,
    ids: &mut ElementIds,
    groups: &mut BoundaryGroups,
    map: &HashMap<u64, usize>,
    v1: bool,
) -> Result<()> {
    let n = count(c, "the number of elements")?;
    for _ in 0..n {
        let (line, ln) = c.expect_line("an element line")?;
        let mut f = line.split_ascii_whitespace();
        let mut next = |what: &str| {
            f.next()
                .ok_or_else(|| c.err_at(ln, format!("element line ends before its {what}")))
        };
        let number: u64 = parse_at(c.file(), ln, next("number")?, "an element number")?;
        let ty: i64 = parse_at(c.file(), ln, next("type")?, "an element type")?;
        check_type(c, ln, ty)?;
        let mut tag = 0;
        if v1 {
            tag = parse_at(c.file(), ln, next("physical region")?, "an integer physical region")?;
            parse_at::<i32>(c.file(), ln, next("elementary region")?, "an integer elementary region")?;
            let nn: usize = parse_at(c.file(), ln, next("number of nodes")?, "the number of nodes")?;
            let listed = f.clone().count();
            if listed != nn {
                return Err(c.err_at(ln, format!("element {number} announces {nn} nodes and lists {listed}")));
            }
            if let Some(want) = nodes_per_element(ty).filter(|&w| w != nn) {
                return Err(c.err_at(
                    ln,
                    format!("element {number} of type {ty} has {nn} nodes, that type has {want}"),
                ));
            }
        } else {
            let ntags: usize = parse_at(c.file(), ln, next("number of tags")?, "the number of element tags")?;
            for k in 0..ntags {
                let t: i32 = parse_at(c.file(), ln, next("tags")?, "an integer element tag")?;
                if k == 0 {
                    tag = t;
                }
            }
        }
        match kind(ty) {
            k @ (Kind::Tet | Kind::Hex) => store(data, ids, k, &element_nodes(c, ln, f, map, k)?, tag, number),
            Kind::Skip(name) => {
                data.skip(name);
                let g = groups.groups(dimension(name), GroupOf::Physical(tag));
                if !g.is_empty() {
                    let nodes = f.map(|tok| node_of(c, ln, tok, map)).collect::<Result<Vec<_>>>()?;
                    groups.add(&g, &nodes);
                }
            }
            // refused by check_type above
            Kind::Volume(_) | Kind::Unknown => {}
        }
    }
    Ok(())
}

fn read_elements_v41(
    c: &mut Cursor<'_>,
    data: &mut MeshData,
    ids: &mut ElementIds,
    groups: &mut BoundaryGroups,
    map: &HashMap<u64, usize>,
) -> Result<()> {
    let header_line = c.line_of_next_token();
    let blocks = count(c, "the number of element entity blocks")?;
    let total = count(c, "the number of elements")?;
    c.parse::<u64>("the minimum element tag")?;
    c.parse::<u64>("the maximum element tag")?;
    let mut seen = 0usize;
    for _ in 0..blocks {
        let dim = c.parse::<i64>("the entity dimension of an element block")?;
        let entity = c.parse::<i32>("the entity tag of an element block")?;
        let ty = c.parse::<i64>("the element type of a block")?;
        let ln = c.line_of_next_token();
        check_type(c, ln, ty)?;
        let n = count(c, "the number of elements in a block")?;
        let k = kind(ty);
        let g = match k {
            Kind::Skip(name) => groups.groups(dimension(name), entity_of(dim, entity)),
            _ => Vec::new(),
        };
        for _ in 0..n {
            let (line, ln) = c.expect_line("an element line")?;
            let mut f = line.split_ascii_whitespace();
            let id = f.next().unwrap_or("");
            let number = parse_at::<u64>(c.file(), ln, id, "an element tag")?;
            match k {
                Kind::Tet | Kind::Hex => store(data, ids, k, &element_nodes(c, ln, f, map, k)?, entity, number),
                Kind::Skip(name) => {
                    data.skip(name);
                    if !g.is_empty() {
                        let nodes = f.map(|tok| node_of(c, ln, tok, map)).collect::<Result<Vec<_>>>()?;
                        groups.add(&g, &nodes);
                    }
                }
                Kind::Volume(_) | Kind::Unknown => {}
            }
        }
        seen = seen.saturating_add(n);
    }
    check_total(c, header_line, "$Elements", total, seen, "elements")
}

/// Three binary coordinates of node `tag`, refused when not finite (as in ASCII).
fn binary_point(c: &mut Cursor<'_>, b: Binary, tag: u64) -> Result<Vec3> {
    let mut p = [0.0; 3];
    for (k, v) in p.iter_mut().enumerate() {
        let axis = ["x", "y", "z"][k];
        let off = c.offset();
        *v = b.float(c, &format!("the {axis} coordinate of node {tag}"))?;
        if !v.is_finite() {
            return Err(c.err(format!(
                "at byte {off}: node {tag}: {axis} coordinate {v} is not a finite number"
            )));
        }
    }
    Ok(Vec3::new(p[0], p[1], p[2]))
}

fn node_of_tag(c: &Cursor<'_>, off: usize, tag: u64, element: u64, map: &HashMap<u64, usize>) -> Result<usize> {
    map.get(&tag).copied().ok_or_else(|| {
        c.err(format!(
            "at byte {off}: element {element} refers to node {tag}, which is not in $Nodes"
        ))
    })
}

/// What one binary element record holds, read by the version's own layout.
struct Record {
    number: u64,
    tag: i32,
    nodes: Vec<(u64, usize)>,
}

/// Stores one binary element of type `ty` (node tags with their byte offsets;
/// their number is the type's, as read; the type was checked with
/// [`check_binary_type`]).
fn store_binary_element(
    c: &Cursor<'_>,
    ty: i64,
    r: &Record,
    data: &mut MeshData,
    ids: &mut ElementIds,
    (groups, of): (&mut BoundaryGroups, GroupOf),
    map: &HashMap<u64, usize>,
) -> Result<()> {
    let nodes = || {
        r.nodes
            .iter()
            .map(|&(tag, off)| node_of_tag(c, off, tag, r.number, map))
            .collect::<Result<Vec<usize>>>()
    };
    match kind(ty) {
        k @ (Kind::Tet | Kind::Hex) => store(data, ids, k, &nodes()?, r.tag, r.number),
        Kind::Skip(name) => {
            data.skip(name);
            let g = groups.groups(dimension(name), of);
            if !g.is_empty() {
                groups.add(&g, &nodes()?);
            }
        }
        Kind::Volume(_) | Kind::Unknown => {}
    }
    Ok(())
}

/// The 4.1 entity of an element block of dimension `dim` (from the file: a value
/// outside 0–2 names no boundary entity).
fn entity_of(dim: i64, entity: i32) -> GroupOf {
    GroupOf::Entity(usize::try_from(dim).unwrap_or(usize::MAX), entity)
}

/// The node count of a binary element type, which is needed to find the next
/// record; the type is refused first when it is a volume or unknown.
fn binary_nodes_per_element(c: &Cursor<'_>, off: usize, ty: i64) -> Result<usize> {
    check_binary_type(c, off, ty)?;
    nodes_per_element(ty).ok_or_else(|| {
        c.err(format!(
            "at byte {off}: element type {ty} has no fixed node count, which is needed to step over its \
             binary records; re-save the file as ASCII, or without this element type"
        ))
    })
}

/// Binary 2.2 `$Nodes`: an ASCII count line, then `int number, 3 doubles` per node.
fn read_nodes_v2_bin(c: &mut Cursor<'_>, b: Binary, data: &mut MeshData, map: &mut HashMap<u64, usize>) -> Result<()> {
    let n = count(c, "the number of nodes")?;
    c.skip_rest_of_line();
    b.check_room(c, n, 4 + 24, "nodes")?;
    data.nodes.reserve(n);
    for _ in 0..n {
        let ln = c.line();
        let tag = b.uint(c, "a node number")?;
        let p = binary_point(c, b, tag)?;
        add_node(c, ln, tag, p, data, map)?;
    }
    Ok(())
}

/// Binary 2.2 `$Elements`: an ASCII count line, then blocks `int type, int count,
/// int tag-count` followed by `count` records `int number, tags, nodes`.
fn read_elements_v2_bin(
    c: &mut Cursor<'_>,
    b: Binary,
    data: &mut MeshData,
    ids: &mut ElementIds,
    groups: &mut BoundaryGroups,
    map: &HashMap<u64, usize>,
) -> Result<()> {
    let n = count(c, "the number of elements")?;
    c.skip_rest_of_line();
    let mut read = 0usize;
    while read < n {
        let off = c.offset();
        let ty = i64::from(b.int(c, "an element type")?);
        let follow = b.uint(c, "the number of elements of a block")?;
        let ntags = b.uint(c, "the number of element tags")? as usize;
        let left = n - read;
        if follow == 0 || follow > left as u64 {
            return Err(c.err(format!(
                "at byte {off}: an element block announces {follow} elements of type {ty}, {left} of the {n} \
                 elements announced by the count line remain"
            )));
        }
        let follow = follow as usize;
        let nn = binary_nodes_per_element(c, off, ty)?;
        let each = ntags
            .checked_add(1 + nn)
            .and_then(|k| k.checked_mul(4))
            .unwrap_or(usize::MAX);
        b.check_room(c, follow, each, "element records")?;
        for _ in 0..follow {
            let number = b.uint(c, "an element number")?;
            let mut tag = 0;
            for k in 0..ntags {
                let t = b.int(c, "an element tag")?;
                if k == 0 {
                    tag = t;
                }
            }
            let mut nodes = Vec::with_capacity(nn);
            for _ in 0..nn {
                let off = c.offset();
                nodes.push((b.uint(c, "a node number of an element")?, off));
            }
            let of = GroupOf::Physical(tag);
            store_binary_element(c, ty, &Record { number, tag, nodes }, data, ids, (groups, of), map)?;
        }
        read += follow;
    }
    Ok(())
}

/// A 4.1 node block's entity dimension (0–3) and parametric flag (0 or 1): any
/// other value was read on as if it were valid (a flag of 2³¹−1 as 0, a
/// dimension of −7 clamped).
fn check_node_block(dim: i64, parametric: i64) -> std::result::Result<(), String> {
    if !(0..=3).contains(&dim) {
        return Err(format!("node block entity dimension {dim}: expected 0, 1, 2 or 3"));
    }
    if !(0..=1).contains(&parametric) {
        return Err(format!("node block parametric flag {parametric}: expected 0 or 1"));
    }
    Ok(())
}

/// Binary 4.1 `$Nodes`: `size_t blocks, total, min, max`, then per block `int dim,
/// int entity, int parametric, size_t count`, the node tags, then the coordinates.
fn read_nodes_v41_bin(c: &mut Cursor<'_>, b: Binary, data: &mut MeshData, map: &mut HashMap<u64, usize>) -> Result<()> {
    let header_line = c.line();
    let blocks = b.count(c, "the number of node entity blocks")?;
    let total = b.count(c, "the number of nodes")?;
    b.size(c, "the minimum node tag")?;
    b.size(c, "the maximum node tag")?;
    b.check_room(c, total, b.size_t + 24, "nodes")?;
    b.check_room(c, blocks, 12 + b.size_t, "node entity blocks")?;
    data.nodes.reserve(total);
    for _ in 0..blocks {
        let dim = b.int(c, "the entity dimension of a node block")?;
        b.int(c, "the entity tag of a node block")?;
        let parametric = b.int(c, "the parametric flag of a node block")?;
        check_node_block(dim.into(), parametric.into()).map_err(|why| c.err(why))?;
        let n = b.count(c, "the number of nodes in a block")?;
        let extra = if parametric == 1 { dim as usize } else { 0 };
        b.check_room(c, n, b.size_t + 8 * (3 + extra), "nodes of a block")?;
        let mut tags = Vec::with_capacity(n);
        for _ in 0..n {
            tags.push(b.size(c, "a node tag")?);
        }
        for tag in tags {
            let ln = c.line();
            let p = binary_point(c, b, tag)?;
            for _ in 0..extra {
                b.float(c, "a parametric coordinate")?;
            }
            add_node(c, ln, tag, p, data, map)?;
        }
    }
    check_total(c, header_line, "$Nodes", total, data.nodes.len(), "nodes")
}

/// Binary 4.1 `$Elements`: `size_t blocks, total, min, max`, then per block `int
/// dim, int entity, int type, size_t count` and `count` records of `size_t` tag
/// and node tags.
fn read_elements_v41_bin(
    c: &mut Cursor<'_>,
    b: Binary,
    data: &mut MeshData,
    ids: &mut ElementIds,
    groups: &mut BoundaryGroups,
    map: &HashMap<u64, usize>,
) -> Result<()> {
    let header_line = c.line();
    let blocks = b.count(c, "the number of element entity blocks")?;
    let total = b.count(c, "the number of elements")?;
    b.size(c, "the minimum element tag")?;
    b.size(c, "the maximum element tag")?;
    b.check_room(c, blocks, 12 + b.size_t, "element entity blocks")?;
    let mut seen = 0usize;
    for _ in 0..blocks {
        let dim = b.int(c, "the entity dimension of an element block")?;
        let entity = b.int(c, "the entity tag of an element block")?;
        let off = c.offset();
        let ty = i64::from(b.int(c, "the element type of a block")?);
        let n = b.count(c, "the number of elements in a block")?;
        let nn = binary_nodes_per_element(c, off, ty)?;
        b.check_room(c, n, b.size_t * (1 + nn), "element records")?;
        for _ in 0..n {
            let number = b.size(c, "an element tag")?;
            let mut nodes = Vec::with_capacity(nn);
            for _ in 0..nn {
                let off = c.offset();
                nodes.push((b.size(c, "a node tag of an element")?, off));
            }
            let r = Record {
                number,
                tag: entity,
                nodes,
            };
            store_binary_element(c, ty, &r, data, ids, (&mut *groups, entity_of(dim.into(), entity)), map)?;
        }
        seen = seen.saturating_add(n);
    }
    check_total(c, header_line, "$Elements", total, seen, "elements")
}

/// Binary 4.1 `$Entities`: volume tag → its first physical tag; the physical tags
/// of points, curves and surfaces go to `groups`.
fn read_entities_bin(c: &mut Cursor<'_>, b: Binary, groups: &mut BoundaryGroups) -> Result<HashMap<i32, Option<i32>>> {
    let mut counts = [0usize; 4];
    for (k, what) in ["points", "curves", "surfaces", "volumes"].iter().enumerate() {
        counts[k] = b.count(c, &format!("the number of {what}"))?;
    }
    let mut volumes = HashMap::new();
    for (dim, &n) in counts.iter().enumerate() {
        // point: int tag, 3 doubles, size_t; others: int tag, 6 doubles, 2 size_t
        let (coords, min) = if dim == 0 {
            (3, 4 + 24 + b.size_t)
        } else {
            (6, 4 + 48 + 2 * b.size_t)
        };
        b.check_room(c, n, min, "entities")?;
        for _ in 0..n {
            let tag = b.int(c, "an entity tag")?;
            for _ in 0..coords {
                b.float(c, "an entity coordinate")?;
            }
            let nphys = b.count(c, "the number of physical tags")?;
            b.check_room(c, nphys, 4, "physical tags")?;
            let mut phys = Vec::with_capacity(nphys);
            for _ in 0..nphys {
                phys.push(b.int(c, "a physical tag")?);
            }
            if dim > 0 {
                let nb = b.count(c, "the number of bounding entities")?;
                b.check_room(c, nb, 4, "bounding entity tags")?;
                c.bytes(nb * 4, "bounding entity tags")?;
            }
            if dim == 3 {
                volumes.insert(tag, phys.first().copied());
            } else {
                groups.set_entity(dim, tag, phys);
            }
        }
    }
    Ok(volumes)
}

/// `$Entities` of v4.1: volume tag → its first physical tag; the physical tags of
/// points, curves and surfaces go to `groups`.
fn read_entities(c: &mut Cursor<'_>, groups: &mut BoundaryGroups) -> Result<HashMap<i32, Option<i32>>> {
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
            // (a count beyond the line's length fails at its first missing tag)
            let mut phys = Vec::with_capacity(nphys.min(f.len()));
            for k in 0..nphys {
                phys.push(parse_at::<i32>(c.file(), ln, get(2 + skip + k)?, "a physical tag")?);
            }
            if dim == 3 {
                volumes.insert(tag, phys.first().copied());
            } else {
                groups.set_entity(dim, tag, phys);
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
        Version::V1 => write_v1(w, mesh),
        Version::V22 => write_v22(w, mesh),
        Version::V41 => write_v41(w, mesh),
    })
}

/// Writes `mesh` as a binary `.msh` (little-endian, as Gmsh and meshio write on
/// x86 and ARM) of version 2.2 or 4.1, with the same tags as [`write()`]; there is
/// no binary version 1.
pub fn write_binary(path: &Path, mesh: &TetMesh, version: Version) -> Result<()> {
    match version {
        Version::V1 => Err(HemlError::Invalid(format!(
            "cannot write '{}': Gmsh version 1 has no binary form",
            path.display()
        ))),
        Version::V22 => write_atomic(path, |w| write_v22_bin(w, mesh)),
        Version::V41 => write_atomic(path, |w| write_v41_bin(w, mesh)),
    }
}

fn write_v1(w: &mut BufWriter<File>, mesh: &TetMesh) -> std::io::Result<()> {
    writeln!(w, "$NOD\n{}", mesh.n_nodes())?;
    for (i, p) in mesh.nodes().iter().enumerate() {
        writeln!(w, "{} {:e} {:e} {:e}", i + 1, p.x, p.y, p.z)?;
    }
    writeln!(w, "$ENDNOD\n$ELM\n{}", mesh.n_tets())?;
    let entity = entity_of_tag(mesh);
    for (k, (t, tag)) in mesh.tets().iter().zip(mesh.tags()).enumerate() {
        let e = entity.get(tag).copied().unwrap_or(1);
        let [a, b, c, d] = t.map(|i| i + 1);
        writeln!(w, "{} 4 {tag} {e} 4 {a} {b} {c} {d}", k + 1)?;
    }
    writeln!(w, "$ENDELM")
}

fn write_v22_bin(w: &mut BufWriter<File>, mesh: &TetMesh) -> std::io::Result<()> {
    let int = |w: &mut BufWriter<File>, v: usize| w.write_all(&(v as i32).to_le_bytes());
    write!(w, "$MeshFormat\n2.2 1 8\n")?;
    int(w, 1)?;
    write!(w, "\n$EndMeshFormat\n$Nodes\n{}\n", mesh.n_nodes())?;
    for (i, p) in mesh.nodes().iter().enumerate() {
        int(w, i + 1)?;
        for x in p.iter() {
            w.write_all(&x.to_le_bytes())?;
        }
    }
    write!(w, "\n$EndNodes\n$Elements\n{}\n", mesh.n_tets())?;
    // one block holding every tet: type 4, count, 2 tags (physical, elementary)
    for v in [4, mesh.n_tets(), 2] {
        int(w, v)?;
    }
    let entity = entity_of_tag(mesh);
    for (k, (t, &tag)) in mesh.tets().iter().zip(mesh.tags()).enumerate() {
        int(w, k + 1)?;
        w.write_all(&tag.to_le_bytes())?;
        int(w, entity.get(&tag).copied().unwrap_or(1))?;
        for &i in t {
            int(w, i as usize + 1)?;
        }
    }
    writeln!(w, "\n$EndElements")
}

fn write_v41_bin(w: &mut BufWriter<File>, mesh: &TetMesh) -> std::io::Result<()> {
    let int = |w: &mut BufWriter<File>, v: i32| w.write_all(&v.to_le_bytes());
    let size = |w: &mut BufWriter<File>, v: usize| w.write_all(&(v as u64).to_le_bytes());
    write!(w, "$MeshFormat\n4.1 1 8\n")?;
    int(w, 1)?;
    write!(w, "\n$EndMeshFormat\n$Entities\n")?;
    let entity = entity_of_tag(mesh);
    for v in [0, 0, 0, entity.len()] {
        size(w, v)?;
    }
    let mut by_entity: Vec<(usize, i32)> = entity.iter().map(|(&t, &e)| (e, t)).collect();
    by_entity.sort_unstable();
    for (e, tag) in by_entity {
        // the bounding box is informative only: the reader does not use it
        int(w, e as i32)?;
        for _ in 0..6 {
            w.write_all(&0f64.to_le_bytes())?;
        }
        size(w, 1)?;
        int(w, tag)?;
        size(w, 0)?;
    }
    write!(w, "\n$EndEntities\n$Nodes\n")?;
    let n = mesh.n_nodes();
    for v in [1, n, n.min(1), n] {
        size(w, v)?;
    }
    for v in [3, 1, 0] {
        int(w, v)?;
    }
    size(w, n)?;
    for i in 1..=n {
        size(w, i)?;
    }
    for p in mesh.nodes() {
        for x in p.iter() {
            w.write_all(&x.to_le_bytes())?;
        }
    }
    write!(w, "\n$EndNodes\n$Elements\n")?;
    let runs = tag_runs(mesh.tags());
    let m = mesh.n_tets();
    for v in [runs.len(), m, m.min(1), m] {
        size(w, v)?;
    }
    for (start, len) in runs {
        let e = entity.get(&mesh.tags()[start]).copied().unwrap_or(1);
        for v in [3, e as i32, 4] {
            int(w, v)?;
        }
        size(w, len)?;
        for k in start..start + len {
            size(w, k + 1)?;
            for &i in &mesh.tets()[k] {
                size(w, i as usize + 1)?;
            }
        }
    }
    writeln!(w, "\n$EndElements")
}

/// Runs of equal tags as (start, length): one element block each, so that tet
/// order is preserved.
fn tag_runs(tags: &[i32]) -> Vec<(usize, usize)> {
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for k in 0..tags.len() {
        match runs.last_mut() {
            Some((start, len)) if tags[*start] == tags[k] => *len += 1,
            _ => runs.push((k, 1)),
        }
    }
    runs
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
    let tags = mesh.tags();
    let runs = tag_runs(tags);
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
