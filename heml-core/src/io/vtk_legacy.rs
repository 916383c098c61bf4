//! VTK legacy `.vtk` files, `DATASET UNSTRUCTURED_GRID`, ASCII or BINARY.
//!
//! Both cell layouts are read: the classic `CELLS n size` list of
//! `count i0 i1 …` records and the VTK ≥ 5.1 `OFFSETS`/`CONNECTIVITY` pair. Region
//! tags come from a `CELL_DATA` array (`SCALARS` or `FIELD`): one named like a tag
//! (`tag`, `gmsh:physical`, `CellEntityIds`, `MaterialIds`, …), else the first
//! integer array. 3-component cell arrays (`VECTORS`, `NORMALS`, `SCALARS name
//! type 3`, `FIELD` arrays of 3 components) are kept by name as cell vector
//! fields ([`MeshData::cell_vectors`]: fibre directions); all other attribute data
//! is parsed and ignored. Binary files are big-endian, as the format prescribes.

use std::collections::BTreeMap;
use std::path::Path;

use super::atomic::write_atomic;
use super::cursor::{capacity, shorten, Cursor};
use super::read_bytes;
use super::vtk_cells::{assemble, choose_tags, At, CellArray, VTK_TETRA};
use super::{no_tets_message, wrong_components, MeshData};
use crate::error::Result;
use crate::mesh::TetMesh;
use crate::Vec3;

/// Reads a legacy VTK unstructured grid.
pub fn read(path: &Path) -> Result<MeshData> {
    let bytes = read_bytes(path)?;
    parse(path, &bytes)
}

#[derive(Clone, Copy, PartialEq)]
enum Section {
    None,
    Point,
    Cell,
}

/// Parses the bytes of a legacy VTK file (`path` is used in error messages).
pub fn parse(path: &Path, bytes: &[u8]) -> Result<MeshData> {
    let mut c = Cursor::new(path, bytes, None);
    let (head, ln) = c.raw_line()?.ok_or_else(|| c.err_at(1, "empty file"))?;
    if !head.to_ascii_lowercase().starts_with("# vtk datafile") {
        return Err(c.err_at(
            ln,
            format!("expected '# vtk DataFile Version x.y', found '{}'", shorten(head)),
        ));
    }
    c.raw_line()?.ok_or_else(|| c.eof("the title line"))?;
    let (mode, ln) = c.raw_line()?.ok_or_else(|| c.eof("ASCII or BINARY"))?;
    let binary = match mode.to_ascii_uppercase().as_str() {
        "ASCII" => false,
        "BINARY" => true,
        _ => return Err(c.err_at(ln, format!("expected ASCII or BINARY, found '{}'", shorten(mode)))),
    };
    let mut r = Reader { c, binary };

    let mut points: Option<Vec<Vec3>> = None;
    let mut cells: Option<Cells> = None;
    let mut types: Option<(Vec<f64>, ValueLines, usize)> = None; // values, their lines, header line
    let mut cell_arrays: Vec<CellArray> = Vec::new();
    // 3-component cell arrays (fibre directions), n_cells × 3 values each
    let mut vectors: Vec<(String, Vec<f64>)> = Vec::new();
    let mut defects: BTreeMap<String, String> = BTreeMap::new();
    let mut section = Section::None;
    let mut section_len = 0usize;
    // every CELL_DATA / POINT_DATA header: its section, count and line
    let mut sections: Vec<(Section, usize, usize)> = Vec::new();
    // the last keyword that read values, and its line, to explain a wrong count
    let mut last_values: Option<(String, usize)> = None;
    let mut dataset = false;

    while let Some((kw, ln)) = r.c.token()? {
        let kw_upper = kw.to_ascii_uppercase();
        match kw_upper.as_str() {
            "DATASET" => {
                let (kind, ln) = r.c.expect_line("the dataset type")?;
                if !kind.eq_ignore_ascii_case("UNSTRUCTURED_GRID") {
                    return Err(r.c.err_at(
                        ln,
                        format!(
                            "dataset type {} is not supported; expected UNSTRUCTURED_GRID",
                            shorten(kind)
                        ),
                    ));
                }
                dataset = true;
            }
            "POINTS" => {
                let args = r.args(2, "POINTS n type")?;
                let n = r.count(&args[0], ln)?;
                let n3 = n
                    .checked_mul(3)
                    .ok_or_else(|| r.c.err_at(ln, "point count overflows"))?;
                let (v, lines) = r.values(n3, &args[1], ln, "point coordinates")?;
                if let Some(k) = v.iter().position(|x| !x.is_finite()) {
                    return Err(r.c.err_at(
                        lines.line(k, ln),
                        format!(
                            "node {}: {} coordinate {} is not a finite number",
                            k / 3,
                            ["x", "y", "z"][k % 3],
                            v[k]
                        ),
                    ));
                }
                points = Some(v.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])).collect());
            }
            "CELLS" => {
                let args = r.args(2, "CELLS n size")?;
                let a = r.count(&args[0], ln)?;
                let b = r.count(&args[1], ln)?;
                if r.c.peek_is("OFFSETS") {
                    // VTK 5 layout: `a` offsets, `b` connectivity entries
                    r.expect_kw("OFFSETS")?;
                    let (ty, tl) = r.c.expect_line("the OFFSETS type")?;
                    let (offs, _) = r.values(a, ty, tl, "cell offsets")?;
                    r.expect_kw("CONNECTIVITY")?;
                    let (ty, tl) = r.c.expect_line("the CONNECTIVITY type")?;
                    let (conn, conn_lines) = r.values(b, ty, tl, "cell connectivity")?;
                    let mut offsets = Vec::with_capacity(offs.len());
                    for &o in &offs {
                        if !(o.fract() == 0.0 && o >= 0.0 && o <= conn.len() as f64) {
                            return Err(r.c.err_at(
                                tl,
                                format!("cell offset {o} outside the connectivity (size {})", conn.len()),
                            ));
                        }
                        offsets.push(o as usize);
                    }
                    if offsets.first().is_some_and(|&o| o != 0) {
                        return Err(r.c.err_at(tl, "the first cell offset must be 0"));
                    }
                    cells = Some(Cells {
                        offsets,
                        conn,
                        line: ln,
                        lines: conn_lines,
                        classic: false,
                    });
                } else {
                    let (list, list_lines) = r.values(b, "int", ln, "cell list")?;
                    // a cell takes at least its count: at most one per number of the list
                    let mut offsets = Vec::with_capacity(capacity(a, list.len(), 1) + 1);
                    let mut conn = Vec::with_capacity(list.len());
                    let mut pos = 0usize;
                    offsets.push(0);
                    for cell in 0..a {
                        let k = list.get(pos).copied().ok_or_else(|| {
                            r.c.err_at(
                                ln,
                                format!("CELLS announces {a} cells in {b} numbers but they run out at cell {cell}"),
                            )
                        })?;
                        if !(k.fract() == 0.0 && k >= 0.0 && k < (list.len() - pos) as f64) {
                            return Err(r.c.err_at(
                                list_lines.line(pos, ln),
                                format!("cell {cell} has an invalid node count {k}"),
                            ));
                        }
                        let k = k as usize;
                        conn.extend_from_slice(&list[pos + 1..pos + 1 + k]);
                        pos += 1 + k;
                        offsets.push(conn.len());
                    }
                    if pos != list.len() {
                        return Err(r.c.err_at(
                            ln,
                            format!("CELLS size {b} does not match the {a} cells listed ({pos} numbers)"),
                        ));
                    }
                    cells = Some(Cells {
                        offsets,
                        conn,
                        line: ln,
                        lines: list_lines,
                        classic: true,
                    });
                }
                last_values = Some(("CELLS".into(), ln));
            }
            "CELL_TYPES" => {
                let args = r.args(1, "CELL_TYPES n")?;
                let n = r.count(&args[0], ln)?;
                let (v, lines) = r.values(n, "int", ln, "cell types")?;
                types = Some((v, lines, ln));
            }
            "CELL_DATA" | "POINT_DATA" => {
                let args = r.args(1, "CELL_DATA n")?;
                section_len = r.count(&args[0], ln)?;
                section = if kw_upper == "CELL_DATA" {
                    Section::Cell
                } else {
                    Section::Point
                };
                sections.push((section, section_len, ln));
            }
            "SCALARS" => {
                let args = r.args(2, "SCALARS name type [components]")?;
                let ncomp = match args.get(2) {
                    Some(s) => r.count(s, ln)?,
                    None => 1,
                };
                if r.c.peek_is("LOOKUP_TABLE") {
                    r.c.token()?;
                    r.c.expect_line("the lookup table name")?;
                }
                let n = section_len
                    .checked_mul(ncomp)
                    .ok_or_else(|| r.c.err_at(ln, "array size overflows"))?;
                let (values, _) = r.values(n, &args[1], ln, "scalar values")?;
                if section == Section::Cell {
                    match ncomp {
                        1 => cell_arrays.push(CellArray {
                            name: args[0].clone(),
                            values,
                            integer: is_integer(&args[1]),
                            line: ln,
                        }),
                        3 => vectors.push((args[0].clone(), values)),
                        n => {
                            defects.insert(args[0].clone(), wrong_components(n));
                        }
                    }
                }
            }
            "FIELD" => {
                let args = r.args(2, "FIELD name n_arrays")?;
                let n_arrays = r.count(&args[1], ln)?;
                for _ in 0..n_arrays {
                    let (name, aln) = r.c.expect_token("a field array name")?;
                    let name = name.to_string();
                    let a = r.args(3, "array components tuples type")?;
                    let ncomp = r.count(&a[0], aln)?;
                    let ntup = r.count(&a[1], aln)?;
                    let n = ncomp
                        .checked_mul(ntup)
                        .ok_or_else(|| r.c.err_at(aln, "array size overflows"))?;
                    let (values, _) = r.values(n, &a[2], aln, "field values")?;
                    r.skip_metadata()?;
                    if section == Section::Cell {
                        match ncomp {
                            1 => cell_arrays.push(CellArray {
                                name,
                                values,
                                integer: is_integer(&a[2]),
                                line: aln,
                            }),
                            3 if ntup == section_len => vectors.push((name, values)),
                            3 => {
                                let why = format!(
                                    "FIELD array (line {aln}) holds {ntup} tuples for the {section_len} cells of \
                                     CELL_DATA: cells without a value"
                                );
                                defects.insert(name, why);
                            }
                            n => {
                                defects.insert(name, wrong_components(n));
                            }
                        }
                    }
                }
            }
            "VECTORS"
            | "NORMALS"
            | "TENSORS"
            | "TENSORS6"
            | "TEXTURE_COORDINATES"
            | "COLOR_SCALARS"
            | "LOOKUP_TABLE" => {
                if section == Section::None {
                    return Err(r.c.err_at(ln, format!("{kw} outside CELL_DATA/POINT_DATA")));
                }
                let mut name = String::new();
                let (per, ty) = match kw_upper.as_str() {
                    "VECTORS" | "NORMALS" | "TENSORS" | "TENSORS6" => {
                        let a = r.args(2, "name type")?;
                        name.clone_from(&a[0]);
                        let per = match kw_upper.as_str() {
                            "TENSORS" => 9,
                            "TENSORS6" => 6,
                            _ => 3,
                        };
                        (per, a[1].clone())
                    }
                    "TEXTURE_COORDINATES" => {
                        let a = r.args(3, "name dim type")?;
                        (r.count(&a[1], ln)?, a[2].clone())
                    }
                    "COLOR_SCALARS" => {
                        let a = r.args(2, "name n_values")?;
                        (
                            r.count(&a[1], ln)?,
                            if r.binary {
                                "unsigned_char".into()
                            } else {
                                "float".into()
                            },
                        )
                    }
                    _ => {
                        // a lookup table definition: name size, then 4·size colours
                        let a = r.args(2, "name size")?;
                        let size = r.count(&a[1], ln)?;
                        let n = size.checked_mul(4).ok_or_else(|| r.c.err_at(ln, "size overflows"))?;
                        r.values(n, if r.binary { "unsigned_char" } else { "float" }, ln, "lookup table")?;
                        last_values = Some(("LOOKUP_TABLE".into(), ln));
                        continue;
                    }
                };
                let n = section_len
                    .checked_mul(per)
                    .ok_or_else(|| r.c.err_at(ln, "array size overflows"))?;
                let (values, _) = r.values(n, &ty, ln, "attribute values")?;
                if section == Section::Cell && !name.is_empty() {
                    if per == 3 {
                        vectors.push((name, values));
                    } else {
                        defects.insert(name, wrong_components(per));
                    }
                }
            }
            "METADATA" => r.skip_metadata_body()?,
            _ => {
                if let (Ok(_), Some((prev, pl))) = (kw.parse::<f64>(), &last_values) {
                    return Err(r.c.err_at(
                        ln,
                        format!(
                            "found the number '{}' where a keyword was expected: the {prev} section (line {pl}) \
                             holds more values than its header announces",
                            shorten(kw)
                        ),
                    ));
                }
                return Err(r.c.err_at(ln, format!("unexpected keyword '{}'", shorten(kw))));
            }
        }
        if matches!(
            kw_upper.as_str(),
            "POINTS"
                | "CELL_TYPES"
                | "SCALARS"
                | "FIELD"
                | "VECTORS"
                | "NORMALS"
                | "TENSORS"
                | "TENSORS6"
                | "TEXTURE_COORDINATES"
                | "COLOR_SCALARS"
                | "LOOKUP_TABLE"
        ) {
            last_values = Some((kw_upper, ln));
        }
    }
    let c = &r.c;
    if !dataset {
        return Err(c.err("missing 'DATASET UNSTRUCTURED_GRID'"));
    }
    let points = points.ok_or_else(|| c.err("missing POINTS section"))?;
    let cells = cells.ok_or_else(|| c.err("missing CELLS section"))?;
    let (types, type_lines, types_line) = types.ok_or_else(|| c.err("missing CELL_TYPES section"))?;
    let n_cells = cells.offsets.len().saturating_sub(1);
    for &(kind, n, line) in &sections {
        let (name, want, what) = match kind {
            Section::Cell => ("CELL_DATA", n_cells, "cells"),
            _ => ("POINT_DATA", points.len(), "points"),
        };
        if n != want {
            return Err(c.err_at(
                line,
                format!("{name} announces {n} values but the grid has {want} {what}"),
            ));
        }
    }
    let tags = choose_tags(&cell_arrays, n_cells);
    use At::{Arrays, Cell, Line, Type};
    let line_of = |at: At| match at {
        // a cell's first entry: its count in the classic list (before it: the
        // counts and nodes of the previous cells), its first node in VTK 5's
        Cell(k) if cells.classic => cells.lines.line(cells.offsets[k] + k, cells.line),
        Cell(k) => cells.lines.line(cells.offsets[k], cells.line),
        Type(k) => type_lines.line(k, types_line),
        Arrays => cells.line,
        Line(l) => l,
    };
    // (an array sized for another cell count was refused with its CELL_DATA header above)
    let mut data = assemble(
        points,
        &cells.offsets,
        &cells.conn,
        &types,
        tags,
        &vectors,
        &|at, msg| c.err_at(line_of(at), msg),
    )?;
    for (name, why) in defects {
        data.vector_defects.entry(name).or_insert(why);
    }
    if data.tets.is_empty() && data.hexes.is_empty() {
        return Err(c.err_at(cells.line, no_tets_message(&data)));
    }
    Ok(data)
}

/// The cells as read: offsets into the connectivity, and where their values sit.
struct Cells {
    offsets: Vec<usize>,
    conn: Vec<f64>,
    /// The `CELLS` header line.
    line: usize,
    /// Lines of the values: of the classic list (counts included) or of the
    /// VTK 5 connectivity.
    lines: ValueLines,
    /// Classic `count i0 i1 …` layout.
    classic: bool,
}

/// Where the values of an ASCII array sit: `(index of the first value on a line,
/// that line)`, one entry per line, so that an error about value `k` (a cell, a
/// coordinate) names its own line, not the header's, for the cost of one entry
/// per line. Empty for binary arrays, which have no lines.
#[derive(Default)]
struct ValueLines(Vec<(usize, usize)>);

impl ValueLines {
    /// The line of value `index`, or `default` when unknown (binary data).
    fn line(&self, index: usize, default: usize) -> usize {
        match self.0.partition_point(|&(i, _)| i <= index) {
            0 => default,
            k => self.0[k - 1].1,
        }
    }
}

fn is_integer(ty: &str) -> bool {
    !matches!(ty.to_ascii_lowercase().as_str(), "float" | "double")
}

/// The cursor plus the ASCII/BINARY switch.
struct Reader<'a> {
    c: Cursor<'a>,
    binary: bool,
}

impl Reader<'_> {
    /// The rest of the keyword's line, split; at least `min` fields.
    fn args(&mut self, min: usize, form: &str) -> Result<Vec<String>> {
        let (line, ln) = self.c.expect_line(form)?;
        let f: Vec<String> = line.split_ascii_whitespace().map(str::to_string).collect();
        if f.len() < min {
            return Err(self
                .c
                .err_at(ln, format!("expected '{form}', found '{}'", shorten(line))));
        }
        Ok(f)
    }

    fn count(&self, tok: &str, ln: usize) -> Result<usize> {
        super::cursor::parse_at(self.c.file(), ln, tok, "a non-negative count")
    }

    fn expect_kw(&mut self, kw: &str) -> Result<()> {
        let (t, ln) = self.c.expect_token(kw)?;
        if !t.eq_ignore_ascii_case(kw) {
            return Err(self.c.err_at(ln, format!("expected {kw}, found '{}'", shorten(t))));
        }
        Ok(())
    }

    /// `n` values of VTK type `ty`, as text tokens or big-endian binary, and the
    /// lines they sit on (ASCII only).
    fn values(&mut self, n: usize, ty: &str, ln: usize, what: &str) -> Result<(Vec<f64>, ValueLines)> {
        let ty = ty.to_ascii_lowercase();
        let size = match ty.as_str() {
            "char" | "unsigned_char" => 1,
            "short" | "unsigned_short" => 2,
            "int" | "unsigned_int" | "float" => 4,
            "long" | "unsigned_long" | "double" | "vtktypeint64" | "vtktypeuint64" | "vtkidtype" => 8,
            _ => return Err(self.c.err_at(ln, format!("unsupported data type '{}'", shorten(&ty)))),
        };
        // a binary value takes `size` bytes, a text one at least 2 (digit, separator)
        let per = if self.binary { size } else { 2 };
        let mut out = Vec::with_capacity(capacity(n, self.c.remaining(), per));
        let mut lines = ValueLines::default();
        if self.binary {
            let len = n
                .checked_mul(size)
                .ok_or_else(|| self.c.err_at(ln, "array size overflows"))?;
            let raw = self.c.bytes(len, what)?;
            for b in raw.chunks_exact(size) {
                out.push(be_value(&ty, b));
            }
        } else {
            for k in 0..n {
                let (v, tl) = self.c.record_number::<f64>(k, n, what, ln)?;
                if lines.0.last().is_none_or(|&(_, l)| l != tl) {
                    lines.0.push((k, tl));
                }
                out.push(v);
            }
        }
        Ok((out, lines))
    }

    /// Skips an optional METADATA block after an array.
    fn skip_metadata(&mut self) -> Result<()> {
        if self.c.peek_is("METADATA") {
            self.c.token()?;
            self.skip_metadata_body()?;
        }
        Ok(())
    }

    /// METADATA runs up to the next blank line.
    fn skip_metadata_body(&mut self) -> Result<()> {
        self.c.skip_rest_of_line();
        while let Some((line, _)) = self.c.raw_line()? {
            if line.is_empty() {
                break;
            }
        }
        Ok(())
    }
}

fn be_value(ty: &str, b: &[u8]) -> f64 {
    let a8 = |b: &[u8]| {
        let mut a = [0u8; 8];
        a.copy_from_slice(&b[..8]);
        a
    };
    let a4 = |b: &[u8]| {
        let mut a = [0u8; 4];
        a.copy_from_slice(&b[..4]);
        a
    };
    match ty {
        "char" => b[0] as i8 as f64,
        "unsigned_char" => b[0] as f64,
        "short" => i16::from_be_bytes([b[0], b[1]]) as f64,
        "unsigned_short" => u16::from_be_bytes([b[0], b[1]]) as f64,
        "int" => i32::from_be_bytes(a4(b)) as f64,
        "unsigned_int" => u32::from_be_bytes(a4(b)) as f64,
        "float" => f32::from_be_bytes(a4(b)) as f64,
        "double" => f64::from_be_bytes(a8(b)),
        "unsigned_long" | "vtktypeuint64" => u64::from_be_bytes(a8(b)) as f64,
        _ => i64::from_be_bytes(a8(b)) as f64,
    }
}

/// Writes `mesh` as an ASCII legacy VTK file (classic cell layout, readable by
/// every VTK version), with the tags as the integer cell scalar `tag`.
pub fn write(path: &Path, mesh: &TetMesh) -> Result<()> {
    use std::io::Write;
    write_atomic(path, |w| {
        writeln!(
            w,
            "# vtk DataFile Version 3.0\nHEML tetrahedral mesh\nASCII\nDATASET UNSTRUCTURED_GRID"
        )?;
        writeln!(w, "POINTS {} double", mesh.n_nodes())?;
        for p in mesh.nodes() {
            writeln!(w, "{:e} {:e} {:e}", p.x, p.y, p.z)?;
        }
        let m = mesh.n_tets();
        writeln!(w, "CELLS {m} {}", 5 * m)?;
        for t in mesh.tets() {
            writeln!(w, "4 {} {} {} {}", t[0], t[1], t[2], t[3])?;
        }
        writeln!(w, "CELL_TYPES {m}")?;
        for _ in 0..m {
            writeln!(w, "{VTK_TETRA}")?;
        }
        writeln!(w, "CELL_DATA {m}\nSCALARS tag int 1\nLOOKUP_TABLE default")?;
        for t in mesh.tags() {
            writeln!(w, "{t}")?;
        }
        Ok(())
    })
}
