//! VTK XML `.vtu` (UnstructuredGrid) files: reading, plus the [`VtuFrame`] writer
//! re-exported from `vtu_write`.
//!
//! Read: DataArrays in `ascii`, inline `binary` (base64) and `appended` form (raw
//! or base64 encoding), uncompressed, `vtkZLibDataCompressor` or
//! `vtkLZMADataCompressor` (decoded in pure Rust), header type UInt32 or UInt64,
//! either byte order, several Pieces (concatenated). Region tags come from a
//! CellData array named like a tag (`tag`, `gmsh:physical`, `CellEntityIds`,
//! `MaterialIds`, …), else the first integer cell array. LZ4 is refused with a
//! clear error.

use std::path::Path;

use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;

use super::cursor::{line_of, shorten, LineCounter};
use super::read_bytes;
use super::vtk_binary::{Compressor, HeaderType, Layout};
use super::vtk_cells::{assemble, choose_tags, At, CellArray};
use super::{no_tets_message, wrong_components, MeshData};
use crate::error::{HemlError, Result};
use crate::Vec3;

pub use super::vtu_write::{write_vtu, FieldPrecision, VtuEncoding, VtuFrame};

/// Reads a `.vtu` unstructured grid.
pub fn read(path: &Path) -> Result<MeshData> {
    let bytes = read_bytes(path)?;
    parse(path, &bytes)
}

#[derive(Clone, Copy, PartialEq)]
enum Parent {
    Other,
    Points,
    Cells,
    CellData,
}

/// A DataArray as declared, with its inline text.
struct ArraySpec {
    name: String,
    ty: String,
    components: usize,
    format: String,
    offset: Option<usize>,
    text_start: usize,
    text_end: usize,
    line: usize,
}

#[derive(Default)]
struct Piece {
    n_points: usize,
    n_cells: usize,
    line: usize,
    points: Option<ArraySpec>,
    connectivity: Option<ArraySpec>,
    offsets: Option<ArraySpec>,
    types: Option<ArraySpec>,
    cell_arrays: Vec<ArraySpec>,
}

struct Ctx<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    layout: Layout,
    /// Appended data (after the `_` marker) and whether it is base64.
    appended: Option<(&'a [u8], bool)>,
    /// All appended offsets, sorted, to find where a base64 array ends.
    appended_offsets: Vec<usize>,
}

impl Ctx<'_> {
    fn err(&self, line: usize, msg: impl Into<String>) -> HemlError {
        HemlError::Parse {
            file: self.path.to_path_buf(),
            line,
            msg: msg.into(),
        }
    }
}

fn attr(e: &BytesStart<'_>, key: &str) -> Option<String> {
    e.attributes()
        .flatten()
        .find(|a| a.key.as_ref() == key.as_bytes())
        .map(|a| String::from_utf8_lossy(&a.value).into_owned())
}

/// Most attributes one element of a `.vtu` file may have (VTK writes at most
/// seven): the parser's duplicate check compares each attribute with those before
/// it, so 100 000 of them took 73 s.
const MAX_ATTRIBUTES: usize = 64;

/// Refuses an element with more than [`MAX_ATTRIBUTES`] attributes, or with a
/// malformed or repeated one (a repeated `byte_order` was read as its first value).
fn check_attributes(e: &BytesStart<'_>) -> std::result::Result<(), String> {
    let name = String::from_utf8_lossy(e.local_name().as_ref()).into_owned();
    if e.attributes().with_checks(false).take(MAX_ATTRIBUTES + 1).count() > MAX_ATTRIBUTES {
        return Err(format!(
            "<{}> has more than {MAX_ATTRIBUTES} attributes",
            shorten(&name)
        ));
    }
    match e.attributes().find_map(|a| a.err()) {
        Some(err) => {
            let msg: String = err.to_string().chars().take(MAX_XML_MESSAGE).collect();
            Err(format!("<{}>: bad attribute: {msg}", shorten(&name)))
        }
        None => Ok(()),
    }
}

/// Parses the bytes of a `.vtu` file (`path` is used in error messages).
pub fn parse(path: &Path, bytes: &[u8]) -> Result<MeshData> {
    parse_counting(path, bytes).0
}

/// Longest piece of a parser message quoted in an error: quick-xml's messages can
/// quote a whole tag, which for a hostile file is 100 kB of stderr.
const MAX_XML_MESSAGE: usize = 80;

/// [`parse`], also returning how many bytes were scanned to number the lines of
/// the tags (the work that used to be quadratic; tested to be one pass).
fn parse_counting(path: &Path, bytes: &[u8]) -> (Result<MeshData>, usize) {
    // a UTF-8 byte-order mark is allowed before the XML declaration (meshio reads
    // such files; here it shifted every data slice by its three bytes)
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut lines = LineCounter::new(bytes);
    let r = parse_with(path, bytes, &mut lines);
    (r, lines.scanned())
}

fn parse_with(path: &Path, bytes: &[u8], lines: &mut LineCounter<'_>) -> Result<MeshData> {
    let perr = |line: usize, msg: String| HemlError::Parse {
        file: path.to_path_buf(),
        line,
        msg,
    };
    // Raw appended data is not XML: cut it off before handing the text to the parser.
    let (xml, appended_tag) = match find(bytes, b"<AppendedData") {
        Some(i) => (&bytes[..i], Some(i)),
        None => (bytes, None),
    };
    let appended = match appended_tag {
        Some(i) => {
            let tag_end = bytes[i..].iter().position(|&b| b == b'>').map(|p| i + p);
            let tag_end = tag_end.ok_or_else(|| perr(line_of(bytes, i), "unterminated <AppendedData> tag".into()))?;
            let tag = String::from_utf8_lossy(&bytes[i..tag_end]).to_ascii_lowercase();
            let base64 = !tag.contains("\"raw\"");
            let us = bytes[tag_end..]
                .iter()
                .position(|&b| b == b'_')
                .map(|p| tag_end + p + 1);
            let us = us.ok_or_else(|| perr(line_of(bytes, i), "appended data lacks its '_' start marker".into()))?;
            let mut data = &bytes[us..];
            if base64 {
                if let Some(end) = find(data, b"</AppendedData") {
                    data = &data[..end];
                }
            }
            Some((data, base64))
        }
        None => None,
    };

    let mut reader = Reader::from_reader(xml);
    let mut layout = Layout {
        header: HeaderType::U32,
        little_endian: true,
        compressor: Compressor::None,
    };
    let mut seen_root = false;
    let mut pieces: Vec<Piece> = Vec::new();
    let mut parent = Parent::Other;
    let mut current: Option<ArraySpec> = None;

    loop {
        // where the next event starts: a tag's `<` (text between tags is an event
        // of its own), so that a tag written over several lines is named by its first
        let tag_start = reader.buffer_position() as usize;
        let ev = reader.read_event().map_err(|e| {
            let pos = reader.error_position() as usize;
            let msg = e.to_string();
            let cut: String = msg.chars().take(MAX_XML_MESSAGE).collect();
            let more = if cut.len() < msg.len() { "…" } else { "" };
            perr(line_of(bytes, pos), format!("malformed XML: {cut}{more}"))
        })?;
        let pos = reader.buffer_position() as usize;
        let (start, empty) = match ev {
            Event::Start(e) => (Some(e), false),
            Event::Empty(e) => (Some(e), true),
            Event::End(e) => {
                match e.local_name().as_ref() {
                    b"DataArray" => {
                        if let Some(mut spec) = current.take() {
                            // the text is everything between the start tag and `</DataArray`
                            let end = xml[..pos].iter().rposition(|&b| b == b'<').unwrap_or(pos);
                            spec.text_end = end.max(spec.text_start);
                            store(&mut pieces, parent, spec, &perr)?;
                        }
                    }
                    b"Points" | b"Cells" | b"CellData" | b"PointData" | b"FieldData" => parent = Parent::Other,
                    _ => {}
                }
                (None, false)
            }
            Event::Eof => break,
            _ => (None, false),
        };
        if let Some(e) = start {
            let line = lines.line_at(tag_start);
            check_attributes(&e).map_err(|msg| perr(line, msg))?;
            match e.local_name().as_ref() {
                b"VTKFile" => {
                    seen_root = true;
                    let ty = attr(&e, "type").unwrap_or_default();
                    if ty != "UnstructuredGrid" {
                        return Err(perr(
                            line,
                            format!(
                                "VTKFile type '{}' is not supported; expected UnstructuredGrid",
                                shorten(&ty)
                            ),
                        ));
                    }
                    layout.little_endian = match attr(&e, "byte_order").as_deref() {
                        None | Some("LittleEndian") => true,
                        Some("BigEndian") => false,
                        Some(other) => {
                            return Err(perr(
                                line,
                                format!("byte_order '{}': expected LittleEndian or BigEndian", shorten(other)),
                            ))
                        }
                    };
                    layout.header = match attr(&e, "header_type").as_deref() {
                        None | Some("UInt32") => HeaderType::U32,
                        Some("UInt64") => HeaderType::U64,
                        Some(other) => return Err(perr(line, format!("unsupported header_type '{}'", shorten(other)))),
                    };
                    layout.compressor = match attr(&e, "compressor").as_deref() {
                        None | Some("") => Compressor::None,
                        Some("vtkZLibDataCompressor") => Compressor::Zlib,
                        Some("vtkLZMADataCompressor") => Compressor::Lzma,
                        Some(other) => {
                            return Err(perr(
                                line,
                                format!(
                                    "compressor '{}' is not supported (only vtkZLibDataCompressor and \
                                     vtkLZMADataCompressor); re-save with zlib, lzma or no compression",
                                    shorten(other)
                                ),
                            ))
                        }
                    };
                }
                b"Piece" => {
                    let get = |k: &str| -> Result<usize> {
                        let v = attr(&e, k).ok_or_else(|| perr(line, format!("<Piece> lacks {k}")))?;
                        v.trim()
                            .parse()
                            .map_err(|_| perr(line, format!("<Piece> {k}='{}' is not a count", shorten(&v))))
                    };
                    pieces.push(Piece {
                        n_points: get("NumberOfPoints")?,
                        n_cells: get("NumberOfCells")?,
                        line,
                        ..Piece::default()
                    });
                }
                b"Points" => parent = Parent::Points,
                b"Cells" => parent = Parent::Cells,
                b"CellData" => parent = Parent::CellData,
                b"PointData" | b"FieldData" => parent = Parent::Other,
                b"DataArray" => {
                    let components = match attr(&e, "NumberOfComponents") {
                        Some(v) => v
                            .trim()
                            .parse()
                            .map_err(|_| perr(line, format!("NumberOfComponents='{}' is not a count", shorten(&v))))?,
                        None => 1,
                    };
                    let offset = match attr(&e, "offset") {
                        Some(v) => Some(
                            v.trim()
                                .parse()
                                .map_err(|_| perr(line, format!("offset='{}' is not a count", shorten(&v))))?,
                        ),
                        None => None,
                    };
                    let spec = ArraySpec {
                        name: attr(&e, "Name").unwrap_or_default(),
                        ty: attr(&e, "type").unwrap_or_default(),
                        components,
                        format: attr(&e, "format").unwrap_or_else(|| "ascii".into()),
                        offset,
                        text_start: pos,
                        text_end: pos,
                        line,
                    };
                    if empty {
                        store(&mut pieces, parent, spec, &perr)?;
                    } else {
                        current = Some(spec);
                    }
                }
                _ => {}
            }
        }
    }
    if !seen_root {
        return Err(perr(1, "no <VTKFile> element (not a VTK XML file?)".into()));
    }
    if pieces.is_empty() {
        return Err(perr(
            line_of(bytes, xml.len()),
            "no <Piece> in the UnstructuredGrid (file truncated?)".into(),
        ));
    }
    let mut appended_offsets: Vec<usize> = pieces
        .iter()
        .flat_map(|p| {
            [&p.points, &p.connectivity, &p.offsets, &p.types]
                .into_iter()
                .flatten()
                .chain(p.cell_arrays.iter())
        })
        .filter_map(|s| s.offset)
        .collect();
    appended_offsets.sort_unstable();
    let ctx = Ctx {
        path,
        bytes,
        layout,
        appended,
        appended_offsets,
    };

    let mut out = MeshData::default();
    for piece in &pieces {
        let data = read_piece(&ctx, piece)?;
        let base = out.nodes.len();
        out.nodes.extend(data.nodes);
        out.tets.extend(data.tets.into_iter().map(|t| t.map(|i| i + base)));
        out.tags.extend(data.tags);
        out.hexes.extend(data.hexes.into_iter().map(|h| h.map(|i| i + base)));
        out.hex_tags.extend(data.hex_tags);
        for (k, v) in data.skipped {
            *out.skipped.entry(k).or_insert(0) += v;
        }
        for (k, v) in data.cell_vectors {
            out.cell_vectors.entry(k).or_default().extend(v);
        }
        for (k, v) in data.hex_vectors {
            out.hex_vectors.entry(k).or_default().extend(v);
        }
    }
    // a cell field missing from some piece covers only part of the cells: dropped
    let (n_tets, n_hexes) = (out.tets.len(), out.hexes.len());
    out.cell_vectors.retain(|_, v| v.len() == n_tets);
    out.hex_vectors.retain(|_, v| v.len() == n_hexes);
    if out.tets.is_empty() && out.hexes.is_empty() {
        return Err(perr(pieces[0].line, no_tets_message(&out)));
    }
    Ok(out)
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn store(
    pieces: &mut [Piece],
    parent: Parent,
    spec: ArraySpec,
    perr: &dyn Fn(usize, String) -> HemlError,
) -> Result<()> {
    let Some(piece) = pieces.last_mut() else {
        return Err(perr(spec.line, "<DataArray> outside a <Piece>".into()));
    };
    match parent {
        Parent::Points => piece.points = Some(spec),
        Parent::Cells => match spec.name.as_str() {
            "connectivity" => piece.connectivity = Some(spec),
            "offsets" => piece.offsets = Some(spec),
            "types" => piece.types = Some(spec),
            _ => {}
        },
        Parent::CellData => piece.cell_arrays.push(spec),
        Parent::Other => {}
    }
    Ok(())
}

fn read_piece(ctx: &Ctx<'_>, p: &Piece) -> Result<MeshData> {
    let missing = |what: &str| ctx.err(p.line, format!("<Piece> has no {what} DataArray (file truncated?)"));
    let pts_spec = p.points.as_ref().ok_or_else(|| missing("Points"))?;
    if pts_spec.components != 3 {
        return Err(ctx.err(
            pts_spec.line,
            format!("Points have {} components, expected 3", pts_spec.components),
        ));
    }
    let n3 = p
        .n_points
        .checked_mul(3)
        .ok_or_else(|| ctx.err(p.line, "NumberOfPoints overflows"))?;
    let pts = values(ctx, pts_spec, n3, "NumberOfPoints × 3")?;
    if let Some(k) = pts.iter().position(|x| !x.is_finite()) {
        return Err(ctx.err(
            pts_spec.line,
            format!(
                "node {}: {} coordinate {} is not a finite number",
                k / 3,
                ["x", "y", "z"][k % 3],
                pts[k]
            ),
        ));
    }
    let nodes: Vec<Vec3> = pts.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
    let conn_spec = p.connectivity.as_ref().ok_or_else(|| missing("connectivity"))?;
    let off_spec = p.offsets.as_ref().ok_or_else(|| missing("offsets"))?;
    let types_spec = p.types.as_ref().ok_or_else(|| missing("types"))?;
    let offs = values(ctx, off_spec, p.n_cells, "NumberOfCells")?;
    // the connectivity holds as many entries as the last offset says
    let n_conn = match offs.last() {
        None => 0,
        Some(&o) if o.fract() == 0.0 && o >= 0.0 && o <= usize::MAX as f64 => o as usize,
        Some(&o) => {
            return Err(ctx.err(
                off_spec.line,
                format!("the last offset {o} is not a valid connectivity size"),
            ))
        }
    };
    let conn = values(ctx, conn_spec, n_conn, "the last offset")?;
    let types = values(ctx, types_spec, p.n_cells, "NumberOfCells")?;
    // VTK XML offsets are the *end* of each cell; prepend the start of the first.
    let mut offsets = Vec::with_capacity(offs.len() + 1);
    offsets.push(0usize);
    for (c, &o) in offs.iter().enumerate() {
        if !(o.fract() == 0.0 && o >= 0.0 && o <= conn.len() as f64) {
            return Err(ctx.err(
                off_spec.line,
                format!(
                    "offset {o} of cell {c} is outside the connectivity (size {})",
                    conn.len()
                ),
            ));
        }
        offsets.push(o as usize);
    }
    let mut arrays = Vec::new();
    for s in p.cell_arrays.iter().filter(|s| s.components == 1) {
        arrays.push(CellArray {
            name: s.name.clone(),
            values: values(ctx, s, p.n_cells, "NumberOfCells")?,
            integer: s.ty.contains("Int"),
            line: s.line,
        });
    }
    let tags = choose_tags(&arrays, p.n_cells);
    // 3-component cell arrays (fibre directions): read whole, n_cells × 3 values
    let mut vectors = Vec::new();
    for s in p.cell_arrays.iter().filter(|s| s.components == 3) {
        let n = p
            .n_cells
            .checked_mul(3)
            .ok_or_else(|| ctx.err(s.line, "NumberOfCells × 3 overflows"))?;
        vectors.push((s.name.clone(), values(ctx, s, n, "3 × NumberOfCells")?));
    }
    let mut data = assemble(nodes, &offsets, &conn, &types, tags, &vectors, &|at, msg| {
        let line = match at {
            At::Type(_) => types_spec.line,
            At::Line(l) => l,
            At::Cell(_) | At::Arrays => conn_spec.line,
        };
        ctx.err(line, msg)
    })?;
    for s in p.cell_arrays.iter().filter(|s| s.components != 3) {
        data.vector_defects
            .insert(s.name.clone(), wrong_components(s.components));
    }
    Ok(data)
}

/// Decodes one DataArray to exactly `expected` f64 values (`why` names the count
/// it comes from, for the error). Binary sizes are checked from the block header
/// before any decoding ([`Layout::decode_raw`]); ASCII reading stops at the first
/// value too many.
fn values(ctx: &Ctx<'_>, s: &ArraySpec, expected: usize, why: &str) -> Result<Vec<f64>> {
    let e = |msg: String| ctx.err(s.line, format!("DataArray '{}': {msg}", shorten(&s.name)));
    let size = type_size(&s.ty).ok_or_else(|| e(format!("unsupported type '{}'", shorten(&s.ty))))?;
    let bytes = expected
        .checked_mul(size)
        .ok_or_else(|| e(format!("{expected} values ({why}) overflow the addressable size")))?;
    // decoding errors say what the header should have declared
    let sized = |msg: String| e(format!("{msg} ({why}: {expected} values of {}, {bytes} bytes)", s.ty));
    let text = &ctx.bytes[s.text_start..s.text_end];
    let out: Vec<f64> = match s.format.as_str() {
        "ascii" => {
            let text = std::str::from_utf8(text).map_err(|_| e("invalid UTF-8 in ascii data".into()))?;
            // at most one value too many is read: enough to report the mismatch
            let mut v = Vec::with_capacity(expected.min(text.len() / 2 + 1));
            for (k, tok) in text
                .split_ascii_whitespace()
                .take(expected.saturating_add(1))
                .enumerate()
            {
                let x: f64 = tok
                    .parse()
                    .map_err(|_| e(format!("value {k} '{}' is not a number", shorten(tok))))?;
                v.push(x);
            }
            v
        }
        "binary" => {
            let raw = ctx.layout.decode_base64(text, bytes).map_err(sized)?;
            numbers(&raw, &s.ty, size, ctx.layout.little_endian).map_err(e)?
        }
        "appended" => {
            let (data, base64) = ctx
                .appended
                .ok_or_else(|| e("format 'appended' but the file has no <AppendedData>".into()))?;
            let off = s
                .offset
                .ok_or_else(|| e("format 'appended' without an offset".into()))?;
            let start = data
                .get(off..)
                .ok_or_else(|| e(format!("offset {off} is past the end of the appended data")))?;
            let raw = if base64 {
                let next = ctx.appended_offsets.iter().copied().find(|&o| o > off);
                let len = next.map_or(start.len(), |n| (n - off).min(start.len()));
                ctx.layout.decode_base64(&start[..len], bytes).map_err(sized)?
            } else {
                ctx.layout.decode_raw(start, bytes).map_err(sized)?.0
            };
            numbers(&raw, &s.ty, size, ctx.layout.little_endian).map_err(e)?
        }
        other => return Err(e(format!("unknown format '{}'", shorten(other)))),
    };
    if out.len() != expected {
        let got = if out.len() > expected {
            "more".to_string()
        } else {
            out.len().to_string()
        };
        return Err(e(format!("holds {got} values, expected {expected} ({why})")));
    }
    Ok(out)
}

fn type_size(ty: &str) -> Option<usize> {
    Some(match ty {
        "Int8" | "UInt8" => 1,
        "Int16" | "UInt16" => 2,
        "Int32" | "UInt32" | "Float32" => 4,
        "Int64" | "UInt64" | "Float64" => 8,
        _ => return None,
    })
}

fn numbers(raw: &[u8], ty: &str, size: usize, le: bool) -> std::result::Result<Vec<f64>, String> {
    if !raw.chunks_exact(size).remainder().is_empty() {
        return Err(format!("{} bytes is not a whole number of {ty} values", raw.len()));
    }
    let mut out = Vec::with_capacity(raw.len() / size);
    for b in raw.chunks_exact(size) {
        let mut a = [0u8; 8];
        if le {
            a[..size].copy_from_slice(b);
        } else {
            for (k, &x) in b.iter().rev().enumerate() {
                a[k] = x;
            }
        }
        // `a` now holds the value little-endian in its first `size` bytes
        let v = match ty {
            "Int8" => a[0] as i8 as f64,
            "UInt8" => a[0] as f64,
            "Int16" => i16::from_le_bytes([a[0], a[1]]) as f64,
            "UInt16" => u16::from_le_bytes([a[0], a[1]]) as f64,
            "Int32" => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            "UInt32" => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            "Float32" => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            "Int64" => i64::from_le_bytes(a) as f64,
            "UInt64" => u64::from_le_bytes(a) as f64,
            _ => f64::from_le_bytes(a),
        };
        out.push(v);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-tet `.vtu` with `extra` inserted in its `<FieldData>` and `points`
    /// as the Points DataArray (ASCII).
    fn one_tet(extra: &str, points_tag: &str) -> String {
        format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\">\n<UnstructuredGrid>\n\
             <FieldData>\n{extra}</FieldData>\n<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n\
             <Points>\n{points_tag}0 0 0 1 0 0 0 1 0 0 0 1</DataArray>\n</Points>\n<Cells>\n\
             <DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2 3</DataArray>\n\
             <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4</DataArray>\n\
             <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10</DataArray>\n\
             </Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n"
        )
    }

    #[test]
    fn tag_lines_are_numbered_in_one_pass_over_the_file() {
        // 100k tags took ~10 s when every tag's line was counted from byte 0 (work
        // quadratic in the file size). Speed is not asserted as wall time: the line
        // counter counts the bytes it examines, and one pass means at most the file's
        // length. The numbering must also stay right: an error after the 100k tags
        // names its line.
        let n = 100_000;
        let extra: String = (0..n).map(|_| "<Dummy/>\n").collect();
        let good = one_tet(
            &extra,
            "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">",
        );
        let (r, scanned) = parse_counting(Path::new("many.vtu"), good.as_bytes());
        assert_eq!(r.unwrap().tets.len(), 1);
        assert!(
            scanned <= good.len(),
            "{scanned} bytes scanned for a {}-byte file",
            good.len()
        );

        // Points with 2 components: the error names the Points DataArray's line:
        // 4 lines up to <FieldData>, the n dummy tags, then </FieldData>, <Piece>,
        // <Points> and the DataArray
        let bad = one_tet(
            &extra,
            "<DataArray type=\"Float64\" NumberOfComponents=\"2\" format=\"ascii\">",
        );
        let (r, scanned) = parse_counting(Path::new("many.vtu"), bad.as_bytes());
        let e = r.unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("many.vtu:{}: Points have 2 components", n + 8)),
            "{e}"
        );
        assert!(scanned <= bad.len());
    }

    #[test]
    fn malformed_xml_errors_are_short_and_name_the_line() {
        // a 100 kB tag name used to be echoed whole in the message
        let name = "x".repeat(100_000);
        let text = one_tet(
            &format!("\n\n</{name}>\n"),
            "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">",
        );
        let e = parse(Path::new("bad.vtu"), text.as_bytes()).unwrap_err().to_string();
        assert!(e.starts_with("bad.vtu:7: malformed XML"), "{}", &e[..e.len().min(200)]);
        assert!(e.len() < 200, "{} bytes of message", e.len());

        // a tag written over several lines is named by its first line (8), not its
        // last (11)
        let text = one_tet(
            "",
            "<DataArray\n type=\"Float64\"\n NumberOfComponents=\"2\"\n format=\"ascii\">",
        );
        let e = parse(Path::new("multi.vtu"), text.as_bytes()).unwrap_err().to_string();
        assert!(e.starts_with("multi.vtu:8: Points have 2 components"), "{e}");
    }
}
