//! What VTK legacy and VTK XML files share: cell type codes, the choice of the cell
//! array that holds region tags, and the assembly of tets from a cell list.

use super::{direction_defect, float_to_tag, MeshData, TAG_ARRAY_NAMES};
use crate::error::{HemlError, Result};
use crate::Vec3;

/// VTK cell type of a linear tetrahedron.
pub(crate) const VTK_TETRA: u8 = 10;

enum CellKind {
    Tet,
    /// VTK_HEXAHEDRON (12): corners in the order hexes are stored.
    Hex,
    /// VTK_VOXEL (11): corners in (x, y, z) bit order, permuted to the hex order.
    Voxel,
    /// A vertex, line or surface cell (of any order): skipped and counted.
    Skip(&'static str),
    /// A volume cell HEML does not simulate: an error.
    Volume(&'static str),
    /// A number outside VTK's list: an error too, since it may be a volume.
    Unknown,
}

/// Every VTK cell type (`VTKCellType` in VTK's `vtkCellType.h`, 0–81). Only the
/// types known to be vertices, lines or surfaces are skipped: an unknown or volume
/// type is refused, because skipping it would silently remove material.
fn cell_kind(t: i64) -> CellKind {
    match t {
        10 => CellKind::Tet,
        11 => CellKind::Voxel,
        12 => CellKind::Hex,
        0 => CellKind::Skip("empty cell"),
        1 | 2 => CellKind::Skip("vertex"),
        // line, poly-line, quadratic and cubic edges, parametric, higher-order,
        // Lagrange and Bézier curves
        3 | 4 | 21 | 35 | 51 | 60 | 68 | 75 => CellKind::Skip("line"),
        // triangles, strips and polygons of every order, parametric surfaces
        5 | 6 | 7 | 22 | 34 | 36 | 52 | 53 | 61 | 63 | 69 | 76 => CellKind::Skip("triangle/polygon"),
        // pixel and quadrilaterals of every order
        8 | 9 | 23 | 28 | 30 | 54 | 62 | 70 | 77 => CellKind::Skip("quad"),
        24 | 55 | 64 | 71 | 78 => CellKind::Volume("quadratic/higher-order tetrahedron"),
        25 | 29 | 33 | 56 | 67 | 72 | 79 => CellKind::Volume("quadratic/higher-order hexahedron"),
        13 | 26 | 31 | 32 | 65 | 73 | 80 => CellKind::Volume("wedge"),
        14 | 27 | 37 | 66 | 74 | 81 => CellKind::Volume("pyramid"),
        15 | 16 => CellKind::Volume("pentagonal/hexagonal prism"),
        41 | 42 => CellKind::Volume("convex point set/polyhedron"),
        _ => CellKind::Unknown,
    }
}

/// Why cell `c` of VTK type `ty` cannot be read, or `None` for a tet, a hex or a
/// skipped cell; the readers add where (line) and the file.
fn refusal(c: usize, ty: f64) -> Option<String> {
    const ONLY: &str = "only linear tetrahedra (type 10) and linear hexahedra (types 11 and 12, split into tets \
                        at load) are simulated";
    match cell_kind(ty as i64) {
        CellKind::Tet | CellKind::Hex | CellKind::Voxel | CellKind::Skip(_) => None,
        CellKind::Volume(name) => Some(format!(
            "cell {c} has VTK type {ty} ({name}), a volume cell HEML cannot simulate: {ONLY}"
        )),
        CellKind::Unknown => Some(format!(
            "cell {c} has VTK type {ty}, which is not a VTK cell type (0 to 81, as in VTK's vtkCellType.h) and \
             may be a volume, which must not be dropped: {ONLY}"
        )),
    }
}

/// One single-component cell array, as read.
pub(crate) struct CellArray {
    pub name: String,
    pub values: Vec<f64>,
    /// Whether the file declared an integer type.
    pub integer: bool,
    /// Line where the array is declared (for errors about its values).
    pub line: usize,
}

/// What an [`assemble`] error is about, so that each reader can name the line
/// that holds it (an ASCII file knows the line of every cell; a binary one only
/// the line of the array).
#[derive(Debug, Clone, Copy)]
pub(crate) enum At {
    /// The cell's node list (its connectivity entries).
    Cell(usize),
    /// The cell's type code.
    Type(usize),
    /// The cell arrays as a whole (their sizes).
    Arrays,
    /// A known line.
    Line(usize),
}

/// The cell array holding region tags: the first whose name is a known tag name
/// (see [`TAG_ARRAY_NAMES`]), else the first integer-typed one, else none.
pub(crate) fn choose_tags(arrays: &[CellArray], n_cells: usize) -> Option<&CellArray> {
    let fits: Vec<&CellArray> = arrays.iter().filter(|a| a.values.len() == n_cells).collect();
    TAG_ARRAY_NAMES
        .iter()
        .find_map(|want| fits.iter().find(|a| a.name.eq_ignore_ascii_case(want)))
        .or_else(|| fits.iter().find(|a| a.integer))
        .copied()
}

/// Cells given as `offsets` (n_cells + 1 entries starting at 0) into
/// `connectivity`, with `types`; the tets are kept, lower-dimensional cells
/// counted, linear hexahedra and voxels kept for the split at load
/// ([`MeshData::split_hexes`]), other volume cells rejected; `vectors` are
/// 3-component cell arrays (3 × n_cells values each) copied to the tets and hexes.
/// `err` builds an error at the place named by [`At`].
pub(crate) fn assemble(
    nodes: Vec<Vec3>,
    offsets: &[usize],
    connectivity: &[f64],
    types: &[f64],
    tags: Option<&CellArray>,
    vectors: &[(String, Vec<f64>)],
    err: &dyn Fn(At, String) -> HemlError,
) -> Result<MeshData> {
    let n_cells = offsets.len().saturating_sub(1);
    if let Some((name, a)) = vectors.iter().find(|(_, a)| a.len() != n_cells.saturating_mul(3)) {
        return Err(err(
            At::Arrays,
            format!(
                "cell array '{name}' holds {} values for {n_cells} cells of 3 components",
                a.len()
            ),
        ));
    }
    if types.len() != n_cells {
        return Err(err(
            At::Arrays,
            format!("{} cell types for {n_cells} cells", types.len()),
        ));
    }
    let mut data = MeshData {
        nodes,
        ..MeshData::default()
    };
    for c in 0..n_cells {
        let (a, b) = (offsets[c], offsets[c + 1]);
        if a > b || b > connectivity.len() {
            return Err(err(
                At::Cell(c),
                format!(
                    "cell {c}: offsets {a}..{b} do not fit the {} connectivity entries",
                    connectivity.len()
                ),
            ));
        }
        let ty = types[c];
        if ty.fract() != 0.0 {
            return Err(err(At::Type(c), format!("cell {c}: cell type {ty} is not an integer")));
        }
        if let Some(why) = refusal(c, ty) {
            return Err(err(At::Type(c), why));
        }
        let kind = cell_kind(ty as i64);
        let (want, name) = match kind {
            CellKind::Tet => (4, "a tetrahedron (type 10)"),
            CellKind::Hex => (8, "a hexahedron (type 12)"),
            CellKind::Voxel => (8, "a voxel (type 11)"),
            _ => (0, ""),
        };
        if want > 0 {
            if b - a != want {
                return Err(err(At::Cell(c), format!("cell {c} is {name} with {} nodes", b - a)));
            }
            let mut v = [0usize; 8];
            for (k, &x) in connectivity[a..b].iter().enumerate() {
                v[k] = node_index(x, data.nodes.len()).ok_or_else(|| {
                    err(
                        At::Cell(c),
                        format!("cell {c} refers to node {x}, but there are {} points", data.nodes.len()),
                    )
                })?;
            }
            let tag = match tags {
                Some(arr) => {
                    let x = arr.values[c];
                    float_to_tag(x).ok_or_else(|| {
                        err(
                            At::Line(arr.line),
                            format!("cell {c}: tag array '{}' holds {x}, not an i32 integer", arr.name),
                        )
                    })?
                }
                None => 0,
            };
            match kind {
                CellKind::Tet => {
                    data.tets.push([v[0], v[1], v[2], v[3]]);
                    data.tags.push(tag);
                    for (name, a) in vectors {
                        let value = vector_of(&mut data, name, a, c);
                        data.cell_vectors.entry(name.clone()).or_default().push(value);
                    }
                }
                _ => {
                    // a voxel's corners are in bit order: swap 2-3 and 6-7 for the hex order
                    let hex = if matches!(kind, CellKind::Voxel) {
                        [v[0], v[1], v[3], v[2], v[4], v[5], v[7], v[6]]
                    } else {
                        v
                    };
                    data.hexes.push(hex);
                    data.hex_tags.push(tag);
                    for (name, a) in vectors {
                        let value = vector_of(&mut data, name, a, c);
                        data.hex_vectors.entry(name.clone()).or_default().push(value);
                    }
                }
            }
            continue;
        }
        if let CellKind::Skip(name) = kind {
            data.skip(name);
        }
    }
    Ok(data)
}

/// Cell `c`'s vector of the 3-component array `a` (named `name`), its first defect
/// as a direction noted in `data` ([`MeshData::vector_defects`]).
fn vector_of(data: &mut MeshData, name: &str, a: &[f64], c: usize) -> Vec3 {
    let value = Vec3::new(a[3 * c], a[3 * c + 1], a[3 * c + 2]);
    if !data.vector_defects.contains_key(name) {
        if let Some(why) = direction_defect(&format!("cell {c}"), value) {
            data.vector_defects.insert(name.to_string(), why);
        }
    }
    value
}

fn node_index(v: f64, n: usize) -> Option<usize> {
    (v.fract() == 0.0 && v >= 0.0 && v < n as f64).then_some(v as usize)
}
