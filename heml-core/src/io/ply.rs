//! PLY files (`.ply`) holding a tetrahedral volume, as OpenSurgSim writes its
//! deformable FEM bodies.
//!
//! PLY (the Stanford polygon format) declares its elements in a text header —
//! `element NAME COUNT` followed by that element's `property TYPE NAME` or
//! `property list COUNT_TYPE ITEM_TYPE NAME` lines — and then stores the records
//! as ASCII or binary (either byte order). A volume mesh is a convention on top:
//! OpenSurgSim's `Fem3DPlyReaderDelegate` reads
//!
//! | element | properties read | becomes |
//! |---|---|---|
//! | `vertex` | `x`, `y`, `z` | the nodes (other properties, e.g. texture `s`, `t`, ignored) |
//! | `3d_element` | list `vertex_indices` (0-based): 4 → tetrahedron, 8 → hexahedron (split at load), optional `tag` | the tets and their tags |
//! | `boundary_condition` | `vertex_index` | the node set `"boundary_condition"` (a scene selects it with `node_set = "boundary_condition"`) |
//! | `material` | `mass_density`, `young_modulus`, `poisson_ratio` | [`MeshData::material`] |
//!
//! OpenSurgSim's cube element orders its corners as VTK's hexahedron (the bottom
//! face 0-1-2-3, the top face 4-7 above it), the order [`MeshData::hexes`] takes.
//! Surface and line elements (`face`, `2d_element`, `1d_element`, `edge`) are
//! skipped and counted, like other elements without vertex lists; an element of
//! another name that lists vertices (`vertex_indices`) may be a volume, so it is
//! refused with its name rather than dropped.
//!
//! The writer writes ASCII (or binary little-endian with [`write_binary`]):
//! `vertex`, `3d_element` with a `tag` property (which OpenSurgSim ignores), and
//! the node set `"boundary_condition"` of the mesh when it has one.
//!
//! Hand-written like the other readers (see [`super`]). The `ply-rs` crate (0.1.3)
//! was considered: it reads every record into a map from property names to values
//! (a map per tet), its binary errors carry no byte offset, and a negative list
//! count of a signed type is cast into a huge one; reading straight into the mesh
//! arrays with the other readers' cursor keeps a record at a few numbers and every
//! error at its line (ASCII) or byte offset (binary).

use std::io::Write;
use std::path::Path;

use super::atomic::write_atomic;
use super::cursor::{capacity, shorten, Cursor};
use super::{read_bytes, FileMaterial, MeshData};
use crate::error::{HemlError, Result};
use crate::mesh::TetMesh;
use crate::Vec3;

/// The node set that OpenSurgSim's `boundary_condition` element becomes.
pub const BOUNDARY_SET: &str = "boundary_condition";

/// A scalar type of a PLY property.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    /// The type named `name` (both the classic and the sized names).
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

/// A property of an element: a scalar, or a list with its count's type.
#[derive(Debug, Clone)]
struct Property {
    name: String,
    kind: Scalar,
    /// The type of the list's count, for a list property.
    count: Option<Scalar>,
}

/// An element declaration of the header.
#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    /// Header line of the declaration (for errors).
    line: usize,
    props: Vec<Property>,
}

impl Element {
    fn scalar(&self, name: &str) -> Option<usize> {
        self.props.iter().position(|p| p.name == name && p.count.is_none())
    }

    fn list(&self, names: &[&str]) -> Option<usize> {
        self.props
            .iter()
            .position(|p| p.count.is_some() && names.contains(&p.name.as_str()))
    }
}

/// How the records are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Binary { little_endian: bool },
}

/// Elements that carry no volume and are skipped (counted).
const SURFACE_ELEMENTS: &[&str] = &["face", "2d_element", "1d_element", "edge", "tristrips"];

/// Names of the vertex list of an element.
const VERTEX_LISTS: &[&str] = &["vertex_indices", "vertex_index"];

/// Most items of one list: a volume element has 8 vertices; a face of a polygon
/// mesh a few hundred at most. A larger count is corrupt data, refused before the
/// list is read.
const MAX_LIST: usize = 1 << 16;

/// Reads a PLY volume mesh. The format (ASCII or binary) is returned too.
pub fn read(path: &Path) -> Result<(MeshData, bool)> {
    let bytes = read_bytes(path)?;
    parse(path, &bytes)
}

/// Parses the bytes of a PLY file (`path` names it in errors): the mesh data and
/// whether the records were binary.
///
/// ```
/// use heml_core::io::ply;
/// use std::path::Path;
///
/// let text = "ply\nformat ascii 1.0\n\
///     element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
///     element 3d_element 1\nproperty list uchar uint vertex_indices\n\
///     element boundary_condition 1\nproperty uint vertex_index\nend_header\n\
///     0 0 0\n1 0 0\n0 1 0\n0 0 1\n4 0 1 2 3\n0\n";
/// let (data, binary) = ply::parse(Path::new("tet.ply"), text.as_bytes()).unwrap();
/// assert!(!binary);
/// assert_eq!((data.nodes.len(), data.tets), (4, vec![[0, 1, 2, 3]]));
/// assert_eq!(data.node_sets[ply::BOUNDARY_SET], vec![0]);
///
/// // a fifth vertex in the element: an error naming the line
/// let bad = text.replace("4 0 1 2 3", "5 0 1 2 3 3");
/// let e = ply::parse(Path::new("tet.ply"), bad.as_bytes()).unwrap_err().to_string();
/// assert!(e.starts_with("tet.ply:16: 3d_element 0: 5 vertices"), "{e}");
/// ```
pub fn parse(path: &Path, bytes: &[u8]) -> Result<(MeshData, bool)> {
    let mut c = Cursor::new(path, bytes, None);
    let (encoding, elements) = header(&mut c)?;
    let mut data = MeshData::default();
    let mut src = Source { c, encoding };
    let mut raw_cells: Vec<(Vec<u64>, String)> = Vec::new();
    let mut cell_tags: Vec<i32> = Vec::new();
    let mut boundary: Option<Vec<u64>> = None;
    for el in &elements {
        let needs_props = matches!(el.name.as_str(), "vertex" | "3d_element" | "boundary_condition");
        if el.props.is_empty() && !needs_props {
            // records without properties hold no bytes: nothing to read however
            // large the count (looping over 4·10⁹ empty records took seconds)
            if el.count > 0 {
                *data.skipped.entry(el.name.clone()).or_insert(0) += el.count;
            }
            continue;
        }
        match el.name.as_str() {
            "vertex" => read_vertices(&mut src, el, &mut data)?,
            "3d_element" => {
                let n = (!data.nodes.is_empty()).then_some(data.nodes.len());
                read_cells(&mut src, el, n, &mut raw_cells, &mut cell_tags)?
            }
            "boundary_condition" => {
                let at = el.scalar("vertex_index").ok_or_else(|| {
                    src.c
                        .err_at(el.line, "element boundary_condition has no property vertex_index")
                })?;
                let mut ids = Vec::with_capacity(capacity(el.count, src.c.remaining(), 1));
                for k in 0..el.count {
                    src.record(el, k, |src, i, p| {
                        let v = src.value(p, &format!("{} {k}", el.name))?;
                        if i == at {
                            let what = format!("{} {k}: vertex_index", el.name);
                            let id = src.index(v, p, &what)?;
                            src.check_index(id, (!data.nodes.is_empty()).then_some(data.nodes.len()), &what)?;
                            ids.push(id);
                        }
                        Ok(())
                    })?;
                }
                boundary = Some(ids);
            }
            "material" => {
                let mut values = [None; 3];
                let keys = ["mass_density", "young_modulus", "poisson_ratio"];
                for k in 0..el.count {
                    src.record(el, k, |src, _, p| {
                        let v = src.value(p, &format!("material {k}: {}", p.name))?;
                        if let (0, Some(slot)) = (k, keys.iter().position(|&n| n == p.name)) {
                            values[slot] = Some(v.as_f64());
                        }
                        Ok(())
                    })?;
                }
                if let [Some(density), Some(young_modulus), Some(poisson_ratio)] = values {
                    data.material = Some(FileMaterial {
                        density,
                        young_modulus,
                        poisson_ratio,
                    });
                }
            }
            name => {
                if !SURFACE_ELEMENTS.contains(&name) && el.list(VERTEX_LISTS).is_some() {
                    return Err(src.c.err_at(
                        el.line,
                        format!(
                            "element '{}' lists vertices: volume elements are read from '3d_element' \
                             (OpenSurgSim's convention); surfaces ({}) are skipped",
                            shorten(name),
                            SURFACE_ELEMENTS.join(", ")
                        ),
                    ));
                }
                for k in 0..el.count {
                    src.record(el, k, |src, _, p| src.value(p, &format!("{} {k}", el.name)).map(drop))?;
                }
                if el.count > 0 {
                    *data.skipped.entry(el.name.clone()).or_insert(0) += el.count;
                }
            }
        }
    }
    if src.encoding == Encoding::Ascii {
        if let Some((tok, line)) = src.c.token()? {
            return Err(src.c.err_at(
                line,
                format!(
                    "found '{}' after the records the header announces: a count in the header is wrong",
                    shorten(tok)
                ),
            ));
        }
    } else if src.c.remaining() > 0 {
        return Err(src.binary_err(format!(
            "{} bytes after the records the header announces: a count in the header is wrong",
            src.c.remaining()
        )));
    }
    let n = data.nodes.len();
    let check = |v: u64, what: &str| -> Result<usize> {
        usize::try_from(v)
            .ok()
            .filter(|&i| i < n)
            .ok_or_else(|| HemlError::Mesh(format!("{}: {what}: vertex {v} is outside 0..{n}", path.display())))
    };
    for ((ids, what), tag) in raw_cells.into_iter().zip(cell_tags) {
        let mut idx = Vec::with_capacity(ids.len());
        for v in ids {
            idx.push(check(v, &what)?);
        }
        match *idx.as_slice() {
            [a, b, c, d] => {
                data.tets.push([a, b, c, d]);
                data.tags.push(tag);
            }
            [a, b, c, d, e, f, g, h] => {
                data.hexes.push([a, b, c, d, e, f, g, h]);
                data.hex_tags.push(tag);
            }
            _ => unreachable!("cells are checked for 4 or 8 vertices when read"),
        }
    }
    if let Some(ids) = boundary {
        let mut set = Vec::with_capacity(ids.len());
        for v in ids {
            set.push(check(v, "boundary_condition")?);
        }
        set.sort_unstable();
        set.dedup();
        data.node_sets.insert(BOUNDARY_SET.to_string(), set);
    }
    if data.tets.is_empty() && data.hexes.is_empty() {
        return Err(HemlError::Mesh(format!(
            "{}: {}",
            path.display(),
            super::no_tets_message(&data)
        )));
    }
    Ok((data, src.encoding != Encoding::Ascii))
}

/// Reads the header up to `end_header`: the encoding and the element declarations.
fn header(c: &mut Cursor<'_>) -> Result<(Encoding, Vec<Element>)> {
    match c.next_line()? {
        Some(("ply", _)) => {}
        _ => return Err(c.err_at(1, "not a PLY file: the first line must be 'ply'")),
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let (line, ln) = c.expect_line("the PLY header (no end_header)")?;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["end_header"] => break,
            ["comment", ..] | ["obj_info", ..] => {}
            ["format", kind, version] => {
                if *version != "1.0" {
                    return Err(c.err_at(ln, format!("PLY version '{}', expected 1.0", shorten(version))));
                }
                encoding = Some(match *kind {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::Binary { little_endian: true },
                    "binary_big_endian" => Encoding::Binary { little_endian: false },
                    other => {
                        return Err(c.err_at(
                            ln,
                            format!(
                                "format '{}', expected ascii, binary_little_endian or binary_big_endian",
                                shorten(other)
                            ),
                        ))
                    }
                });
            }
            ["element", name, count] => {
                let count: usize = super::cursor::parse_at(c.file(), ln, count, "an element count")?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    line: ln,
                    props: Vec::new(),
                });
            }
            ["property", rest @ ..] => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| c.err_at(ln, "a property before any element"))?;
                let ty = |name: &str| {
                    Scalar::parse(name).ok_or_else(|| {
                        c.err_at(
                            ln,
                            format!(
                                "unknown property type '{}' (expected char, uchar, short, ushort, int, uint, \
                                 float, double or their sized names int8 … float64)",
                                shorten(name)
                            ),
                        )
                    })
                };
                let prop = match rest {
                    ["list", count, item, name] => {
                        let count = ty(count)?;
                        if !count.is_integer() {
                            return Err(c.err_at(ln, "a list's count type must be an integer type"));
                        }
                        Property {
                            name: name.to_string(),
                            kind: ty(item)?,
                            count: Some(count),
                        }
                    }
                    [kind, name] => Property {
                        name: name.to_string(),
                        kind: ty(kind)?,
                        count: None,
                    },
                    _ => {
                        return Err(c.err_at(
                            ln,
                            "expected 'property TYPE NAME' or 'property list COUNT_TYPE ITEM_TYPE NAME'",
                        ))
                    }
                };
                el.props.push(prop);
            }
            _ => return Err(c.err_at(ln, format!("unexpected header line '{}'", shorten(line)))),
        }
    }
    let encoding = encoding.ok_or_else(|| c.err_at(1, "the PLY header has no format line"))?;
    Ok((encoding, elements))
}

/// A value as read: integers kept exact.
#[derive(Debug, Clone, Copy)]
enum Value {
    Int(i64),
    Float(f64),
}

impl Value {
    fn as_f64(self) -> f64 {
        match self {
            Value::Int(i) => i as f64,
            Value::Float(x) => x,
        }
    }
}

/// The records after the header, ASCII tokens or binary bytes.
struct Source<'a> {
    c: Cursor<'a>,
    encoding: Encoding,
}

impl Source<'_> {
    /// An error in binary data, at the current byte offset.
    fn binary_err(&self, msg: impl Into<String>) -> HemlError {
        HemlError::Parse {
            file: self.c.file().to_path_buf(),
            line: 0,
            msg: format!("{} (binary data, byte offset {})", msg.into(), self.c.offset()),
        }
    }

    /// An error at the current position (line, or byte offset in binary data).
    fn err(&self, line: usize, msg: String) -> HemlError {
        match self.encoding {
            Encoding::Ascii => self.c.err_at(line, msg),
            Encoding::Binary { .. } => self.binary_err(msg),
        }
    }

    /// One scalar of type `ty`; `what` names it in errors.
    fn scalar(&mut self, ty: Scalar, what: &str) -> Result<Value> {
        match self.encoding {
            Encoding::Ascii => {
                let (tok, line) = self.c.expect_token(what)?;
                if ty.is_integer() {
                    tok.parse::<i64>().map(Value::Int).map_err(|_| {
                        self.c
                            .err_at(line, format!("{what}: expected an integer, found '{}'", shorten(tok)))
                    })
                } else {
                    tok.parse::<f64>().map(Value::Float).map_err(|_| {
                        self.c
                            .err_at(line, format!("{what}: expected a number, found '{}'", shorten(tok)))
                    })
                }
            }
            Encoding::Binary { little_endian } => {
                if self.c.remaining() < ty.size() {
                    return Err(
                        self.binary_err(format!("unexpected end of file while reading {what} (file truncated?)"))
                    );
                }
                let b = self.c.bytes(ty.size(), what)?;
                let mut a = [0u8; 8];
                a[..b.len()].copy_from_slice(b);
                if !little_endian {
                    a[..b.len()].reverse();
                }
                Ok(match ty {
                    Scalar::I8 => Value::Int(a[0] as i8 as i64),
                    Scalar::U8 => Value::Int(a[0] as i64),
                    Scalar::I16 => Value::Int(i16::from_le_bytes([a[0], a[1]]) as i64),
                    Scalar::U16 => Value::Int(u16::from_le_bytes([a[0], a[1]]) as i64),
                    Scalar::I32 => Value::Int(i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as i64),
                    Scalar::U32 => Value::Int(u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as i64),
                    Scalar::F32 => Value::Float(f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64),
                    Scalar::F64 => Value::Float(f64::from_le_bytes(a)),
                })
            }
        }
    }

    /// A scalar property's value, or a list's values skipped (returns its count).
    fn value(&mut self, p: &Property, what: &str) -> Result<Value> {
        match p.count {
            None => self.scalar(p.kind, what),
            Some(ct) => {
                let n = self.list_len(ct, what)?;
                for _ in 0..n {
                    self.scalar(p.kind, what)?;
                }
                Ok(Value::Int(n as i64))
            }
        }
    }

    /// The count of a list, checked against [`MAX_LIST`].
    fn list_len(&mut self, ct: Scalar, what: &str) -> Result<usize> {
        let line = self.c.line_of_next_token();
        match self.scalar(ct, what)? {
            Value::Int(n) if (0..=MAX_LIST as i64).contains(&n) => Ok(n as usize),
            v => Err(self.err(
                line,
                format!("{what}: list count {}, expected 0..={MAX_LIST}", v.as_f64()),
            )),
        }
    }

    /// A vertex index: a non-negative integer (an integer-valued float is
    /// accepted, as some writers store indices as floats).
    fn index(&self, v: Value, p: &Property, what: &str) -> Result<u64> {
        let line = self.c.line();
        match v {
            Value::Int(i) if i >= 0 => Ok(i as u64),
            Value::Float(x) if x >= 0.0 && x.fract() == 0.0 && x < 9.007_199_254_740_992e15 && !p.kind.is_integer() => {
                Ok(x as u64)
            }
            v => Err(self.err(
                line,
                format!("{what}: {} is not a vertex index (an integer >= 0)", v.as_f64()),
            )),
        }
    }

    /// Checks vertex index `id` against the `n` vertices when they are known (the
    /// `vertex` element came first, as usual): the error then names the line.
    /// Otherwise the index is checked once the vertices are read.
    fn check_index(&self, id: u64, n: Option<usize>, what: &str) -> Result<()> {
        match n {
            Some(n) if id >= n as u64 => Err(self.err(
                self.c.line(),
                format!("{what}: vertex {id} is outside 0..{n} (the file's {n} vertices)"),
            )),
            _ => Ok(()),
        }
    }

    /// Reads record `k` of `el`, calling `each(self, property index, property)` for
    /// each property in order; a truncated file names the record.
    fn record(
        &mut self,
        el: &Element,
        k: usize,
        mut each: impl FnMut(&mut Self, usize, &Property) -> Result<()>,
    ) -> Result<()> {
        if self.c.remaining() == 0 || (self.encoding == Encoding::Ascii && self.c.clone().token()?.is_none()) {
            return Err(self.err(
                self.c.line(),
                format!(
                    "unexpected end of file: the header (line {}) announces {} {} records, the file ends after {k} \
                     (file truncated?)",
                    el.line, el.count, el.name
                ),
            ));
        }
        for (i, p) in el.props.iter().enumerate() {
            each(self, i, p)?;
        }
        Ok(())
    }
}

/// Reads the `vertex` records into `data.nodes`.
fn read_vertices(src: &mut Source<'_>, el: &Element, data: &mut MeshData) -> Result<()> {
    let at: Vec<usize> = ["x", "y", "z"]
        .iter()
        .map(|n| {
            el.scalar(n).ok_or_else(|| {
                src.c
                    .err_at(el.line, format!("element vertex has no scalar property {n}"))
            })
        })
        .collect::<Result<_>>()?;
    let min = el
        .props
        .iter()
        .map(|p| {
            if src.encoding == Encoding::Ascii {
                2
            } else {
                p.kind.size()
            }
        })
        .sum();
    data.nodes.reserve(capacity(el.count, src.c.remaining(), min));
    for k in 0..el.count {
        let line = src.c.line_of_next_token();
        let mut p = [f64::NAN; 3];
        src.record(el, k, |src, i, prop| {
            let v = src.value(prop, &format!("vertex {k}: {}", prop.name))?;
            if let Some(axis) = at.iter().position(|&a| a == i) {
                p[axis] = v.as_f64();
            }
            Ok(())
        })?;
        if !p.iter().all(|x| x.is_finite()) {
            return Err(src.err(
                line,
                format!("vertex {k}: coordinates ({}, {}, {}) are not finite", p[0], p[1], p[2]),
            ));
        }
        data.nodes.push(Vec3::new(p[0], p[1], p[2]));
    }
    Ok(())
}

/// Reads the `3d_element` records: each cell's vertex ids (4 or 8) with a name for
/// errors, and its tag.
fn read_cells(
    src: &mut Source<'_>,
    el: &Element,
    n_nodes: Option<usize>,
    cells: &mut Vec<(Vec<u64>, String)>,
    tags: &mut Vec<i32>,
) -> Result<()> {
    let at = el.list(VERTEX_LISTS).ok_or_else(|| {
        src.c
            .err_at(el.line, "element 3d_element has no list property vertex_indices")
    })?;
    let tag_at = el.scalar("tag");
    // a record holds at least a count and four indices
    let min = if src.encoding == Encoding::Ascii { 10 } else { 5 };
    cells.reserve(capacity(el.count, src.c.remaining(), min));
    for k in 0..el.count {
        let line = src.c.line_of_next_token();
        let what = format!("3d_element {k}");
        let mut ids = Vec::new();
        let mut tag = 0;
        src.record(el, k, |src, i, p| {
            if i == at {
                let ct = p.count.expect("a list");
                let n = src.list_len(ct, &what)?;
                if n != 4 && n != 8 {
                    return Err(src.err(
                        line,
                        format!("{what}: {n} vertices; expected 4 (a tetrahedron) or 8 (a hexahedron)"),
                    ));
                }
                for _ in 0..n {
                    let v = src.scalar(p.kind, &what)?;
                    let id = src.index(v, p, &what)?;
                    src.check_index(id, n_nodes, &what)?;
                    ids.push(id);
                }
            } else {
                let v = src.value(p, &format!("{what}: {}", p.name))?;
                if Some(i) == tag_at {
                    tag = match v {
                        Value::Int(t) => i32::try_from(t).ok(),
                        Value::Float(x) => super::float_to_tag(x),
                    }
                    .ok_or_else(|| src.err(line, format!("{what}: tag {} is not an i32 integer", v.as_f64())))?;
                }
            }
            Ok(())
        })?;
        cells.push((ids, what));
        tags.push(tag);
    }
    Ok(())
}

/// Writes `mesh` as an ASCII PLY volume mesh (see the module doc).
pub fn write(path: &Path, mesh: &TetMesh) -> Result<()> {
    write_atomic(path, |w| {
        write_header(w, mesh, "ascii")?;
        for p in mesh.nodes() {
            writeln!(w, "{:e} {:e} {:e}", p.x, p.y, p.z)?;
        }
        for (t, tag) in mesh.tets().iter().zip(mesh.tags()) {
            writeln!(w, "4 {} {} {} {} {tag}", t[0], t[1], t[2], t[3])?;
        }
        if let Some(set) = mesh.node_set(BOUNDARY_SET) {
            for i in set {
                writeln!(w, "{i}")?;
            }
        }
        Ok(())
    })
}

/// Writes `mesh` as a binary little-endian PLY volume mesh.
pub fn write_binary(path: &Path, mesh: &TetMesh) -> Result<()> {
    write_atomic(path, |w| {
        write_header(w, mesh, "binary_little_endian")?;
        for p in mesh.nodes() {
            for c in [p.x, p.y, p.z] {
                w.write_all(&c.to_le_bytes())?;
            }
        }
        for (t, tag) in mesh.tets().iter().zip(mesh.tags()) {
            w.write_all(&[4u8])?;
            for i in t {
                w.write_all(&i.to_le_bytes())?;
            }
            w.write_all(&tag.to_le_bytes())?;
        }
        if let Some(set) = mesh.node_set(BOUNDARY_SET) {
            for &i in set {
                // node ids fit in u32: a mesh's tets hold them as u32
                w.write_all(&(i as u32).to_le_bytes())?;
            }
        }
        Ok(())
    })
}

fn write_header(w: &mut impl Write, mesh: &TetMesh, format: &str) -> std::io::Result<()> {
    writeln!(w, "ply\nformat {format} 1.0\ncomment written by HEML")?;
    writeln!(
        w,
        "element vertex {}\nproperty double x\nproperty double y\nproperty double z",
        mesh.n_nodes()
    )?;
    writeln!(
        w,
        "element 3d_element {}\nproperty list uchar uint vertex_indices\nproperty int tag",
        mesh.n_tets()
    )?;
    if let Some(set) = mesh.node_set(BOUNDARY_SET) {
        writeln!(
            w,
            "element boundary_condition {}\nproperty uint vertex_index",
            set.len()
        )?;
    }
    writeln!(w, "end_header")
}

#[cfg(test)]
mod tests {
    use super::*;

    const CUBE_NODES: &str = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n";

    fn header(elements: &str) -> String {
        format!("ply\nformat ascii 1.0\n{elements}end_header\n")
    }

    const VERTEX: &str = "element vertex 8\nproperty double x\nproperty double y\nproperty double z\n";
    const CELLS: &str = "element 3d_element 1\nproperty list uchar int vertex_indices\n";

    /// An 8-vertex element is a hexahedron in VTK's corner order (OpenSurgSim's
    /// cube): it splits at load into tets of the cube's volume.
    #[test]
    fn eight_vertices_are_a_hexahedron() {
        let text = header(&format!("{VERTEX}{CELLS}")) + CUBE_NODES + "8 0 1 2 3 4 5 6 7\n";
        let (data, _) = parse(Path::new("cube.ply"), text.as_bytes()).unwrap();
        assert_eq!((data.tets.len(), data.hexes.len()), (0, 1));
        let mesh = data.into_mesh().unwrap();
        assert_eq!((mesh.n_tets(), mesh.reoriented_count()), (6, 0));
        assert!((mesh.total_volume() - 1.0).abs() < 1e-15);
    }

    /// The vertices may follow the elements: indices are then checked once they are
    /// read, and an index out of range is still an error (without a line).
    #[test]
    fn elements_before_vertices_are_checked_after() {
        let text = header(&format!("{CELLS}{VERTEX}")) + "8 0 1 2 3 4 5 6 7\n" + CUBE_NODES;
        let (data, _) = parse(Path::new("late.ply"), text.as_bytes()).unwrap();
        assert_eq!(data.hexes, vec![[0, 1, 2, 3, 4, 5, 6, 7]]);
        let bad = text.replace("8 0 1 2 3 4 5 6 7", "8 0 1 2 3 4 5 6 8");
        let e = parse(Path::new("late.ply"), bad.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("late.ply: 3d_element 0: vertex 8 is outside 0..8"), "{e}");
    }

    /// Hostile lists: a negative or huge count, a negative index, a fractional one,
    /// a tag beyond i32, and binary data cut short are errors that say what and where.
    #[test]
    fn bad_lists_and_values_are_named() {
        let base = header(&format!("{VERTEX}{CELLS}property double tag\n")) + CUBE_NODES;
        let cases = [
            ("-4 0 1 2 3 0", "list count -4"),
            ("70000 0 1 2 3 0", "list count 70000"),
            ("4 0 1 -2 3 0", "-2 is not a vertex index"),
            ("4 0 1 2.5 3 0", "expected an integer, found '2.5'"),
            ("4 0 1 2 3 1e10", "tag 10000000000 is not an i32 integer"),
        ];
        for (record, want) in cases {
            let text = base.clone() + record + "\n";
            let e = parse(Path::new("x.ply"), text.as_bytes()).unwrap_err().to_string();
            assert!(e.starts_with("x.ply:19: ") && e.contains(want), "{record}: {e}");
        }
        let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\n\
            property double y\nproperty double z\nend_header\n"
            .to_vec();
        bin.extend_from_slice(&[0u8; 30]);
        let e = parse(Path::new("b.ply"), &bin).unwrap_err().to_string();
        assert!(e.contains("b.ply:0: ") && e.contains("file truncated"), "{e}");
    }

    /// An element without properties holds no bytes: a count of 2⁶⁴ − 1 is skipped
    /// at once (it was a loop of that many empty records), and a vertex or
    /// 3d_element without its properties is an error at its declaration.
    #[test]
    fn elements_without_properties_are_not_looped_over() {
        let text = header(&format!("element camera 18446744073709551615\n{VERTEX}{CELLS}"))
            + CUBE_NODES
            + "8 0 1 2 3 4 5 6 7\n";
        let (data, _) = parse(Path::new("c.ply"), text.as_bytes()).unwrap();
        assert_eq!(data.skipped["camera"], usize::MAX);
        let bare = header("element 3d_element 18446744073709551615\n");
        let e = parse(Path::new("c.ply"), bare.as_bytes()).unwrap_err().to_string();
        assert!(
            e.starts_with("c.ply:3: element 3d_element has no list property vertex_indices"),
            "{e}"
        );
    }
}
