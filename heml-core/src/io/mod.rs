//! Mesh input/output: readers for the tetrahedral mesh formats soft-tissue users
//! actually have, writers for the same formats (so every reader is round-trip
//! tested), VTU frames and `.pvd` series for ParaView.
//!
//! | extension | format | read | written by [`write_mesh`] / [`write_mesh_as`] |
//! |---|---|---|---|
//! | `.msh` | Gmsh 4.1, ASCII or binary (meshio's `gmsh` default) | ✓ | ASCII (default), binary |
//! | `.msh` | Gmsh 2.2 (any 2.x), ASCII or binary (meshio's `gmsh22`) | ✓ | ASCII, binary |
//! | `.msh` | Gmsh 1 (`$NOD`/`$ELM`: SOFA's `liver.msh`, `truthcylinder1.msh`) | ✓ | ✓ |
//! | `.vtk` | VTK legacy UNSTRUCTURED_GRID, ASCII or binary | ✓ | ASCII |
//! | `.vtu` | VTK XML UnstructuredGrid: ascii, base64 or appended (raw/base64); uncompressed, zlib or lzma | ✓ | base64 + zlib (default), base64, ascii |
//! | `.node` + `.ele` | TetGen | ✓ | ✓ |
//! | `.mesh` | Medit / INRIA, ASCII | ✓ | ✓ |
//! | `.ply` | PLY volume mesh as OpenSurgSim writes it (`3d_element`, `boundary_condition`, `material`), ASCII or binary | ✓ | ASCII (default), binary |
//!
//! Binary Gmsh files are read in either byte order (the integer 1 after
//! `$MeshFormat` tells the writer's); binary writers write little-endian. The
//! version is detected from the content, whatever the extension says
//! ([`ReadReport::format`]).
//!
//! Design choices, and why:
//! * **Hand-written parsers.** Every error must name the file and the line, and no
//!   input may make the reader panic; owning the parsers makes both easy to
//!   guarantee and to test (see `tests/integration/mesh_io.rs`, which fuzzes truncations).
//! * **Only linear tetrahedra are simulated.** Lower-dimensional elements (points,
//!   lines, triangles, quads: typically boundary surfaces) are skipped and counted
//!   in [`MeshData::skipped`]. Linear hexahedra (Gmsh type 5, VTK hexahedron and
//!   voxel) are split into tets at load with a chosen [`HexSplit`]
//!   ([`ReadOptions::hex_split`], `hex_split` in a scene's `[mesh]`; see
//!   [`crate::mesh::hex_split`] for how each split stays conforming on an
//!   unstructured hex mesh). Other *volume* elements (prisms, pyramids, quadratic
//!   tets…) are rejected with an error: dropping them silently would remove
//!   material from the body. So is a type number the format's own table does not
//!   know (Gmsh's `GmshDefines.h`, VTK's `vtkCellType.h`): only types known to be
//!   points, lines or surfaces are skipped, since an unknown one may be a volume.
//! * **Every writer is atomic** ([`atomic`]): output goes to a temporary file in the
//!   same directory that is renamed over the target, so a crash or an error never
//!   leaves a half-written file behind.

pub mod atomic;
mod cursor;
pub mod gmsh;
mod gmsh_binary;
mod gmsh_data;
mod gmsh_groups;
pub mod medit;
pub mod ply;
pub mod pvd;
pub mod tetgen;
mod vtk_binary;
mod vtk_cells;
pub mod vtk_legacy;
pub mod vtu;
mod vtu_write;

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use crate::error::{HemlError, Result};
use crate::mesh::generate::HexSplit;
use crate::mesh::hex_split::split_hexes;
use crate::mesh::overlap::Overlap;
use crate::mesh::TetMesh;
use crate::Vec3;

pub use pvd::{read_pvd, PvdWriter};
pub use vtu::{write_vtu, FieldPrecision, VtuEncoding, VtuFrame};

/// The raw content of a mesh file, before validation: what a reader found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshData {
    /// Node positions, densely indexed from 0.
    pub nodes: Vec<Vec3>,
    /// Tetrahedra as indices into `nodes`, in file order and orientation.
    pub tets: Vec<[usize; 4]>,
    /// One region tag per tet (0 where the file has none).
    pub tags: Vec<i32>,
    /// Non-tetrahedral elements that were skipped: element type name → count.
    pub skipped: BTreeMap<String, usize>,
    /// Linear hexahedra as indices into `nodes` (VTK / Gmsh corner order: bottom
    /// face 0-1-2-3, top face 4-5-6-7 above it), to be split into tets at load
    /// ([`MeshData::split_hexes`]).
    pub hexes: Vec<[usize; 8]>,
    /// One region tag per hexahedron (0 where the file has none).
    pub hex_tags: Vec<i32>,
    /// Named 3-component cell fields (VTU), one vector per tet in `tets` order.
    pub cell_vectors: BTreeMap<String, Vec<Vec3>>,
    /// The same fields per hexahedron, copied to its tets when it is split.
    pub hex_vectors: BTreeMap<String, Vec<Vec3>>,
    /// Why a cell field of the file cannot give a direction per cell, by name: its
    /// first zero or non-finite vector, a tet or hexahedron without a value, or a
    /// component count other than 3 (such a field is not in `cell_vectors`). Named
    /// element ids are the file's. Not an error by itself (a file may carry other
    /// data): a scene that names the field in `fibre_fields` reports it.
    pub vector_defects: BTreeMap<String, String>,
    /// Per-tet weights and covers when tets overlap (hexahedra split
    /// [`HexSplit::Ten`]); `None`: every tet weight 1, cover 0.
    pub overlap: Option<crate::mesh::overlap::Overlap>,
    /// Named node sets of the file (ids into `nodes`, sorted, no repeats): the
    /// physical points, curves and surfaces of a Gmsh file (by their
    /// `$PhysicalNames` name, else e.g. `"surface 7"`), the boundary references of
    /// a Medit file (`"surface 3"`, `"curve 2"`), the boundary conditions of an
    /// OpenSurgSim `.ply` ([`ply::BOUNDARY_SET`]). A scene's `node_set = "name"`
    /// selects one.
    pub node_sets: BTreeMap<String, Vec<usize>>,
    /// The material the file declares, when it declares one (OpenSurgSim `.ply`).
    pub material: Option<FileMaterial>,
}

/// A material stated in a mesh file (OpenSurgSim's `material` element): HEML does
/// not take it as the law by itself — a scene or program chooses the law — but
/// reports it ([`ReadReport::material`]), and `heml info` estimates its stable step
/// with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FileMaterial {
    /// Mass density (kg/m³ in SI files).
    pub density: f64,
    /// Young's modulus E (Pa in SI files).
    pub young_modulus: f64,
    /// Poisson's ratio ν.
    pub poisson_ratio: f64,
}

impl MeshData {
    /// Validates the data into a [`TetMesh`] (index checks, degenerate tets rejected,
    /// negative tets reoriented). Hexahedra not split yet are split with the
    /// default [`HexSplit`] (six tets each).
    pub fn into_mesh(mut self) -> Result<TetMesh> {
        self.split_hexes(HexSplit::default())?;
        let mut mesh = TetMesh::with_tags(self.nodes, self.tets, self.tags)?;
        for (name, v) in self.cell_vectors {
            mesh = mesh.with_cell_vectors(name, v)?;
        }
        for (name, ids) in self.node_sets {
            mesh = mesh.with_node_set(name, ids)?;
        }
        match self.overlap {
            Some(o) => mesh.with_overlap(o),
            None => Ok(mesh),
        }
    }

    /// Replaces the hexahedra by tets cut with `split` (conforming between
    /// neighbouring hexes, see [`crate::mesh::hex_split`]), appended after the
    /// file's tets with their hex's tag; [`HexSplit::TwentyFour`] also appends its
    /// face and cell centres to the nodes. Returns the number of hexes split.
    ///
    /// ```
    /// use heml_core::io::MeshData;
    /// use heml_core::mesh::generate::HexSplit;
    /// use heml_core::Vec3;
    ///
    /// let mut data = MeshData {
    ///     nodes: (0..8).map(|b| Vec3::new((b & 1) as f64, ((b >> 1) & 1) as f64, (b >> 2) as f64)).collect(),
    ///     hexes: vec![[0, 1, 3, 2, 4, 5, 7, 6]],
    ///     hex_tags: vec![7],
    ///     ..MeshData::default()
    /// };
    /// assert_eq!(data.split_hexes(HexSplit::Five).unwrap(), 1);
    /// assert_eq!((data.tets.len(), data.tags.as_slice()), (5, &[7; 5][..]));
    /// assert!((data.into_mesh().unwrap().total_volume() - 1.0).abs() < 1e-15);
    /// ```
    pub fn split_hexes(&mut self, split: HexSplit) -> Result<usize> {
        if self.hexes.is_empty() {
            return Ok(0);
        }
        if self.hex_tags.len() != self.hexes.len() {
            return Err(HemlError::Mesh(format!(
                "{} hexahedron tags for {} hexahedra",
                self.hex_tags.len(),
                self.hexes.len()
            )));
        }
        let hexes = std::mem::take(&mut self.hexes);
        let tags = std::mem::take(&mut self.hex_tags);
        let tets = split_hexes(&mut self.nodes, &hexes, split).map_err(HemlError::Mesh)?;
        let per = split.tets_per_cell();
        if let Some(o) = split.overlap(hexes.len()) {
            let n = self.tets.len();
            let all = self.overlap.get_or_insert_with(|| Overlap::plain(n));
            all.weights.extend(o.weights);
            all.covers.extend(o.covers);
        } else if let Some(all) = &mut self.overlap {
            let more = Overlap::plain(tets.len());
            all.weights.extend(more.weights);
            all.covers.extend(more.covers);
        }
        self.tets.extend(tets);
        self.tags.extend(tags.iter().flat_map(|&t| std::iter::repeat_n(t, per)));
        for (name, v) in std::mem::take(&mut self.hex_vectors) {
            self.cell_vectors
                .entry(name)
                .or_default()
                .extend(v.iter().flat_map(|&a| std::iter::repeat_n(a, per)));
        }
        Ok(hexes.len())
    }

    /// The arrays of an existing mesh (for the writers).
    pub fn from_mesh(mesh: &TetMesh) -> Self {
        MeshData {
            nodes: mesh.nodes().to_vec(),
            tets: mesh.tets().iter().map(|t| t.map(|i| i as usize)).collect(),
            tags: mesh.tags().to_vec(),
            overlap: mesh.overlap().cloned(),
            node_sets: mesh.node_sets().clone(),
            ..MeshData::default()
        }
    }

    /// Counts one skipped element of type `name`.
    pub(crate) fn skip(&mut self, name: impl Into<String>) {
        *self.skipped.entry(name.into()).or_insert(0) += 1;
    }
}

/// A mesh file format (and version, where it matters).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MeshFormat {
    /// Gmsh `.msh` version 2.2 (2.x), ASCII.
    Gmsh22,
    /// Gmsh `.msh` version 4.1, ASCII.
    Gmsh41,
    /// Gmsh `.msh` version 1 (`$NOD`/`$ELM`, no `$MeshFormat`), as SOFA ships its meshes.
    Gmsh1,
    /// Gmsh `.msh` version 2.2, binary (meshio's `gmsh22` default); either byte order.
    Gmsh22Binary,
    /// Gmsh `.msh` version 4.1, binary (meshio's `gmsh` default); either byte order.
    Gmsh41Binary,
    /// VTK legacy `.vtk` UNSTRUCTURED_GRID.
    VtkLegacy,
    /// VTK XML `.vtu` UnstructuredGrid.
    Vtu,
    /// TetGen `.node` + `.ele` pair.
    TetGen,
    /// Medit / INRIA `.mesh` (ASCII).
    Medit,
    /// PLY `.ply` volume mesh (OpenSurgSim's `3d_element`), ASCII.
    Ply,
    /// PLY `.ply` volume mesh, binary (either byte order).
    PlyBinary,
}

impl fmt::Display for MeshFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            MeshFormat::Gmsh22 => "Gmsh msh 2.2 ASCII",
            MeshFormat::Gmsh41 => "Gmsh msh 4.1 ASCII",
            MeshFormat::Gmsh1 => "Gmsh msh 1",
            MeshFormat::Gmsh22Binary => "Gmsh msh 2.2 binary",
            MeshFormat::Gmsh41Binary => "Gmsh msh 4.1 binary",
            MeshFormat::VtkLegacy => "VTK legacy",
            MeshFormat::Vtu => "VTK XML (vtu)",
            MeshFormat::TetGen => "TetGen node/ele",
            MeshFormat::Medit => "Medit mesh",
            MeshFormat::Ply => "PLY ASCII",
            MeshFormat::PlyBinary => "PLY binary",
        })
    }
}

/// File extensions understood by [`read_mesh`] and [`write_mesh`].
pub const SUPPORTED_EXTENSIONS: &[&str] = &["msh", "vtk", "vtu", "node", "ele", "mesh", "ply"];

/// How [`read_mesh_with`] turns a file into a mesh.
///
/// ```
/// use heml_core::io::ReadOptions;
/// use heml_core::mesh::generate::HexSplit;
/// let opts = ReadOptions { hex_split: HexSplit::TwentyFour };
/// assert_eq!(ReadOptions::default().hex_split, HexSplit::Six);
/// # let _ = opts;
/// ```
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// How hexahedral cells are cut into tets (default [`HexSplit::Six`], which
    /// works on every hex mesh; [`HexSplit::Five`] needs corners that can be
    /// 2-coloured along the edges, as in a structured grid, and is refused with
    /// the failing hex otherwise).
    pub hex_split: HexSplit,
}

/// What [`read_mesh`] found, for logs and for users to check their input.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadReport {
    /// The file read (for TetGen, the path given).
    pub path: PathBuf,
    /// The detected format.
    pub format: MeshFormat,
    /// Number of nodes.
    pub n_nodes: usize,
    /// Number of tetrahedra.
    pub n_tets: usize,
    /// Non-tet elements skipped: element type name → count.
    pub skipped: BTreeMap<String, usize>,
    /// Tets whose node order was swapped to make their rest volume positive.
    pub reoriented: usize,
    /// Nodes that belong to no tet (they get no mass).
    pub unreferenced_nodes: usize,
    /// Hexahedra split into tets at load (their tets are counted in `n_tets`).
    pub hexes_split: usize,
    /// The file's named node sets and their sizes.
    pub node_sets: BTreeMap<String, usize>,
    /// The material the file declares, if any.
    pub material: Option<FileMaterial>,
}

impl fmt::Display for ReadReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: {}, {} nodes, {} tets",
            self.path.display(),
            self.format,
            self.n_nodes,
            self.n_tets
        )?;
        if !self.skipped.is_empty() {
            let s: Vec<String> = self.skipped.iter().map(|(k, v)| format!("{v} {k}")).collect();
            write!(f, ", skipped {}", s.join(", "))?;
        }
        if self.hexes_split > 0 {
            write!(f, " (from {} hexahedra)", self.hexes_split)?;
        }
        if self.reoriented > 0 {
            write!(f, ", {} tets reoriented", self.reoriented)?;
        }
        if self.unreferenced_nodes > 0 {
            write!(f, ", {} unreferenced nodes", self.unreferenced_nodes)?;
        }
        for (name, n) in &self.node_sets {
            write!(f, ", node set '{name}' ({n} nodes)")?;
        }
        if let Some(m) = self.material {
            write!(
                f,
                ", material in the file: density {}, E {}, nu {}",
                m.density, m.young_modulus, m.poisson_ratio
            )?;
        }
        Ok(())
    }
}

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default()
}

fn unknown_extension(path: &Path, verb: &str) -> HemlError {
    HemlError::Invalid(format!(
        "cannot {verb} '{}': unknown mesh extension '{}'; supported: {}",
        path.display(),
        extension(path),
        SUPPORTED_EXTENSIONS
            .iter()
            .map(|e| format!(".{e}"))
            .collect::<Vec<_>>()
            .join(", ")
    ))
}

/// Reads a file whole, mapping failures to [`HemlError::Io`] with its path.
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    read_file(path, MAX_INPUT_BYTES)
}

/// Largest input file read (4 GiB): a mesh at the scene generator's own cap of 5·10⁷
/// tets takes ~2.5 GB as ASCII Gmsh; a larger "file" (a link to `/dev/zero`, a
/// sparse file) is refused before it is read instead of filling the memory.
pub(crate) const MAX_INPUT_BYTES: u64 = 4 << 30;

/// Reads a regular file of at most `max` bytes. A directory, pipe or device is
/// refused before it is read: a pipe named `x.msh` blocked the reader forever, and
/// `/dev/zero` was read until the memory ran out.
pub(crate) fn read_file(path: &Path, max: u64) -> Result<Vec<u8>> {
    use std::io::Read;
    let io = |e| HemlError::io(path, e);
    let file = std::fs::File::open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if !meta.is_file() {
        return Err(HemlError::Invalid(format!(
            "{}: not a regular file (a directory, pipe or device); expected a file",
            path.display()
        )));
    }
    if meta.len() > max {
        return Err(HemlError::Invalid(format!(
            "{}: {} bytes, above the {max} bytes an input file may have",
            path.display(),
            meta.len()
        )));
    }
    let mut bytes = Vec::new();
    bytes.try_reserve_exact(meta.len() as usize).map_err(|_| {
        HemlError::Invalid(format!(
            "{}: cannot allocate {} bytes to read it",
            path.display(),
            meta.len()
        ))
    })?;
    // (a file that grows while read is still held to the cap)
    file.take(max + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > max {
        return Err(HemlError::Invalid(format!(
            "{}: grew past the {max} bytes an input file may have while it was read",
            path.display()
        )));
    }
    Ok(bytes)
}

/// Reads the raw content of a mesh file, choosing the reader by extension.
pub fn read_mesh_data(path: &Path) -> Result<(MeshData, MeshFormat)> {
    match extension(path).as_str() {
        "msh" => gmsh::read(path),
        "vtk" => vtk_legacy::read(path).map(|d| (d, MeshFormat::VtkLegacy)),
        "vtu" => vtu::read(path).map(|d| (d, MeshFormat::Vtu)),
        "node" | "ele" => tetgen::read(path).map(|d| (d, MeshFormat::TetGen)),
        "mesh" => medit::read(path).map(|d| (d, MeshFormat::Medit)),
        "ply" => ply::read(path).map(|(d, binary)| (d, if binary { MeshFormat::PlyBinary } else { MeshFormat::Ply })),
        _ => Err(unknown_extension(path, "read")),
    }
}

/// Reads a tetrahedral mesh, choosing the format by extension, and validates it.
///
/// ```
/// use heml_core::io::{read_mesh, write_mesh};
/// use heml_core::mesh::generate::{box_mesh, HexSplit};
///
/// let dir = std::env::temp_dir().join(format!("heml-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let path = dir.join("cube.msh");
/// let cube = box_mesh([1.0, 1.0, 1.0], [2, 2, 2], HexSplit::Six).unwrap();
/// write_mesh(&path, &cube).unwrap();
///
/// let (mesh, report) = read_mesh(&path).unwrap();
/// assert_eq!(mesh.n_tets(), 48);
/// assert_eq!(report.n_nodes, 27);
/// println!("{report}"); // ".../cube.msh: Gmsh msh 4.1 ASCII, 27 nodes, 48 tets"
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn read_mesh(path: &Path) -> Result<(TetMesh, ReadReport)> {
    read_mesh_with(path, &ReadOptions::default())
}

/// [`read_mesh`] with options (how hexahedra are split).
pub fn read_mesh_with(path: &Path, options: &ReadOptions) -> Result<(TetMesh, ReadReport)> {
    let (mut data, format) = read_mesh_data(path)?;
    let in_file = |e| match e {
        HemlError::Mesh(msg) => HemlError::Mesh(format!("{}: {msg}", path.display())),
        other => other,
    };
    let hexes_split = data.split_hexes(options.hex_split).map_err(in_file)?;
    let skipped = data.skipped.clone();
    let material = data.material;
    let node_sets = data.node_sets.iter().map(|(k, v)| (k.clone(), v.len())).collect();
    let mesh = data.into_mesh().map_err(in_file)?;
    let report = ReadReport {
        path: path.to_path_buf(),
        format,
        n_nodes: mesh.n_nodes(),
        n_tets: mesh.n_tets(),
        skipped,
        reoriented: mesh.reoriented_count(),
        unreferenced_nodes: mesh.unreferenced_nodes().len(),
        hexes_split,
        node_sets,
        material,
    };
    Ok((mesh, report))
}

/// Writes `mesh` in the format given by the extension of `path` (`.msh` is written
/// as Gmsh 4.1 ASCII, `.vtu` as zlib-compressed base64, `.ply` as ASCII; `.node`/`.ele`
/// write both TetGen files).
pub fn write_mesh(path: &Path, mesh: &TetMesh) -> Result<()> {
    let format = match extension(path).as_str() {
        "msh" => MeshFormat::Gmsh41,
        "vtk" => MeshFormat::VtkLegacy,
        "vtu" => MeshFormat::Vtu,
        "node" | "ele" => MeshFormat::TetGen,
        "mesh" => MeshFormat::Medit,
        "ply" => MeshFormat::Ply,
        _ => return Err(unknown_extension(path, "write")),
    };
    write_mesh_as(path, mesh, format)
}

/// Writes `mesh` to `path` in an explicit format (e.g. Gmsh 2.2 for older tools).
pub fn write_mesh_as(path: &Path, mesh: &TetMesh, format: MeshFormat) -> Result<()> {
    match format {
        MeshFormat::Gmsh22 => gmsh::write(path, mesh, gmsh::Version::V22),
        MeshFormat::Gmsh41 => gmsh::write(path, mesh, gmsh::Version::V41),
        MeshFormat::Gmsh1 => gmsh::write(path, mesh, gmsh::Version::V1),
        MeshFormat::Gmsh22Binary => gmsh::write_binary(path, mesh, gmsh::Version::V22),
        MeshFormat::Gmsh41Binary => gmsh::write_binary(path, mesh, gmsh::Version::V41),
        MeshFormat::VtkLegacy => vtk_legacy::write(path, mesh),
        MeshFormat::Vtu => write_vtu(path, &VtuFrame::from_mesh(mesh)),
        MeshFormat::TetGen => tetgen::write(path, mesh),
        MeshFormat::Medit => medit::write(path, mesh),
        MeshFormat::Ply => ply::write(path, mesh),
        MeshFormat::PlyBinary => ply::write_binary(path, mesh),
    }
}

/// The error text for a file that holds no tetrahedron, with what it did hold: an
/// empty body cannot be simulated, and accepting it made `heml info` print an
/// inverted bounding box and `heml run` write empty frames.
pub(crate) fn no_tets_message(data: &MeshData) -> String {
    let mut msg = format!(
        "no tetrahedra in the file ({} nodes, 0 tets): a mesh needs at least one linear tetrahedron or \
         hexahedron",
        data.nodes.len()
    );
    if !data.skipped.is_empty() {
        let s: Vec<String> = data.skipped.iter().map(|(k, v)| format!("{v} {k}")).collect();
        msg.push_str(&format!(
            "; skipped {} (a surface mesh? mesh its volume first)",
            s.join(", ")
        ));
    }
    msg
}

/// Why the vector `v` of element `element` (its id as the file names it, e.g.
/// "cell 12" or "element 7") cannot be a direction: not finite or zero.
pub(crate) fn direction_defect(element: &str, v: Vec3) -> Option<String> {
    if !v.iter().all(|c| c.is_finite()) {
        Some(format!("{element}: ({}, {}, {}) is not finite", v.x, v.y, v.z))
    } else if v.norm() <= 1e-300 {
        Some(format!("{element}: the vector is zero"))
    } else {
        None
    }
}

/// The defect of a cell field with `n` components ([`MeshData::vector_defects`]).
pub(crate) fn wrong_components(n: usize) -> String {
    format!("it has {n} component(s) per cell; a direction needs 3")
}

/// Converts a region attribute read as a float (TetGen, VTK float arrays) into a
/// tag, refusing values that are not integers in `i32` range.
pub(crate) fn float_to_tag(v: f64) -> Option<i32> {
    (v.is_finite() && v.fract() == 0.0 && v >= i32::MIN as f64 && v <= i32::MAX as f64).then_some(v as i32)
}

/// Names of cell arrays that hold region tags in files written by common tools, in
/// order of preference (compared case-insensitively).
pub(crate) const TAG_ARRAY_NAMES: &[&str] = &[
    "tag",
    "gmsh:physical",
    "medit:ref",
    "cellentityids",
    "materialids",
    "material",
    "region",
    "gmsh:geometrical",
];
