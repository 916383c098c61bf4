//! Writing `.vtu` frames for ParaView: current positions, tets, tags and any point
//! or cell fields a simulation wants to show.

use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

use super::atomic::write_atomic;
use super::vtk_binary::encode_base64;
use super::vtk_cells::VTK_TETRA;
use crate::error::{HemlError, Result};
use crate::mesh::TetMesh;
use crate::Vec3;

/// How DataArrays are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VtuEncoding {
    /// Inline base64 of the raw little-endian bytes: exact and fastest to write.
    Base64,
    /// Inline base64 of zlib-compressed bytes (default): exact too, and several
    /// times smaller for simulation frames (a demo run wrote 79 MB of frames
    /// uncompressed), for a modest cost in writing time (zlib's fastest level).
    #[default]
    Base64Zlib,
    /// Human-readable text (shortest round-trip decimal form): for debugging.
    Ascii,
}

/// One output frame: a tet mesh in some configuration plus fields on it.
///
/// ```
/// use heml_core::io::{write_vtu, VtuFrame};
/// use heml_core::mesh::generate::{box_mesh, HexSplit};
/// let mesh = box_mesh([1.0; 3], [1, 1, 1], HexSplit::Six).unwrap();
/// let velocity = vec![heml_core::Vec3::zeros(); mesh.n_nodes()];
/// let frame = VtuFrame::from_mesh(&mesh).point_vectors("velocity", &velocity);
/// let path = std::env::temp_dir().join(format!("heml-frame-{}.vtu", std::process::id()));
/// write_vtu(&path, &frame).unwrap();
/// # std::fs::remove_file(&path).unwrap();
/// ```
#[derive(Debug, Clone)]
pub struct VtuFrame<'a> {
    /// Node positions (current, or rest for a mesh).
    pub points: &'a [Vec3],
    /// Tets as node indices.
    pub tets: &'a [[u32; 4]],
    /// Region tag per tet, written as the Int32 cell array `tag`.
    pub tags: Option<&'a [i32]>,
    /// Vector fields per node (displacement, velocity, force…).
    pub point_vectors: Vec<(&'a str, &'a [Vec3])>,
    /// Scalar fields per node.
    pub point_scalars: Vec<(&'a str, &'a [f64])>,
    /// Scalar fields per tet (J, energy density…).
    pub cell_scalars: Vec<(&'a str, &'a [f64])>,
    /// Storage of the arrays.
    pub encoding: VtuEncoding,
}

impl<'a> VtuFrame<'a> {
    /// A frame with the given points and tets and no fields.
    pub fn new(points: &'a [Vec3], tets: &'a [[u32; 4]]) -> Self {
        VtuFrame {
            points,
            tets,
            tags: None,
            point_vectors: Vec::new(),
            point_scalars: Vec::new(),
            cell_scalars: Vec::new(),
            encoding: VtuEncoding::default(),
        }
    }

    /// The rest configuration of `mesh`, with its tags.
    pub fn from_mesh(mesh: &'a TetMesh) -> Self {
        Self::new(mesh.nodes(), mesh.tets()).tags(mesh.tags())
    }

    /// `mesh` in a deformed configuration `positions`, with its tags.
    pub fn deformed(mesh: &'a TetMesh, positions: &'a [Vec3]) -> Self {
        Self::new(positions, mesh.tets()).tags(mesh.tags())
    }

    /// Sets the tag array.
    pub fn tags(mut self, tags: &'a [i32]) -> Self {
        self.tags = Some(tags);
        self
    }

    /// Adds a per-node vector field.
    pub fn point_vectors(mut self, name: &'a str, values: &'a [Vec3]) -> Self {
        self.point_vectors.push((name, values));
        self
    }

    /// Adds a per-node scalar field.
    pub fn point_scalars(mut self, name: &'a str, values: &'a [f64]) -> Self {
        self.point_scalars.push((name, values));
        self
    }

    /// Adds a per-tet scalar field.
    pub fn cell_scalars(mut self, name: &'a str, values: &'a [f64]) -> Self {
        self.cell_scalars.push((name, values));
        self
    }

    /// Sets the encoding.
    pub fn encoding(mut self, encoding: VtuEncoding) -> Self {
        self.encoding = encoding;
        self
    }

    fn check(&self) -> Result<()> {
        let (np, nc) = (self.points.len(), self.tets.len());
        if let Some((t, &bad)) = self
            .tets
            .iter()
            .enumerate()
            .find_map(|(t, tet)| tet.iter().find(|&&i| i as usize >= np).map(|b| (t, b)))
        {
            return Err(HemlError::Mesh(format!(
                "frame tet {t} refers to node {bad}, but there are {np} points"
            )));
        }
        let sizes = self.tags.iter().map(|t| ("tag", t.len(), nc));
        let sizes = sizes
            .chain(self.point_vectors.iter().map(|(n, v)| (*n, v.len(), np)))
            .chain(self.point_scalars.iter().map(|(n, v)| (*n, v.len(), np)))
            .chain(self.cell_scalars.iter().map(|(n, v)| (*n, v.len(), nc)));
        for (name, got, expected) in sizes {
            if got != expected {
                return Err(HemlError::Invalid(format!(
                    "vtu field '{name}' has {got} entries, expected {expected}"
                )));
            }
        }
        Ok(())
    }
}

/// Writes one frame as a `.vtu` file (atomically).
pub fn write_vtu(path: &Path, frame: &VtuFrame<'_>) -> Result<()> {
    frame.check()?;
    let mut s = String::new();
    let enc = frame.encoding;
    // `write!` into a String cannot fail.
    let compressor = if enc == VtuEncoding::Base64Zlib {
        " compressor=\"vtkZLibDataCompressor\""
    } else {
        ""
    };
    let _ = writeln!(
        s,
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\"{compressor}>\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">",
        frame.points.len(),
        frame.tets.len()
    );
    if !frame.point_vectors.is_empty() || !frame.point_scalars.is_empty() {
        s.push_str("<PointData>\n");
        for (name, v) in &frame.point_vectors {
            let flat: Vec<f64> = v.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
            array(&mut s, enc, name, 3, &Floats(&flat));
        }
        for (name, v) in &frame.point_scalars {
            array(&mut s, enc, name, 1, &Floats(v));
        }
        s.push_str("</PointData>\n");
    }
    if frame.tags.is_some() || !frame.cell_scalars.is_empty() {
        s.push_str("<CellData>\n");
        if let Some(tags) = frame.tags {
            array(&mut s, enc, "tag", 1, &Ints32(tags));
        }
        for (name, v) in &frame.cell_scalars {
            array(&mut s, enc, name, 1, &Floats(v));
        }
        s.push_str("</CellData>\n");
    }
    s.push_str("<Points>\n");
    let flat: Vec<f64> = frame.points.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    array(&mut s, enc, "Points", 3, &Floats(&flat));
    s.push_str("</Points>\n<Cells>\n");
    let conn: Vec<i64> = frame.tets.iter().flat_map(|t| t.map(i64::from)).collect();
    array(&mut s, enc, "connectivity", 1, &Ints64(&conn));
    let offsets: Vec<i64> = (1..=frame.tets.len() as i64).map(|k| 4 * k).collect();
    array(&mut s, enc, "offsets", 1, &Ints64(&offsets));
    let types = vec![VTK_TETRA; frame.tets.len()];
    array(&mut s, enc, "types", 1, &Bytes(&types));
    s.push_str("</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
    write_atomic(path, |w| w.write_all(s.as_bytes()))
}

/// A typed slice that can be written as a DataArray.
trait Payload {
    const TYPE: &'static str;
    fn ascii(&self, out: &mut String);
    fn le_bytes(&self) -> Vec<u8>;
}

struct Floats<'a>(&'a [f64]);
struct Ints32<'a>(&'a [i32]);
struct Ints64<'a>(&'a [i64]);
struct Bytes<'a>(&'a [u8]);

macro_rules! payload {
    ($t:ident, $name:literal, $fmt:literal) => {
        impl Payload for $t<'_> {
            const TYPE: &'static str = $name;
            fn ascii(&self, out: &mut String) {
                for v in self.0 {
                    let _ = write!(out, $fmt, v);
                }
            }
            fn le_bytes(&self) -> Vec<u8> {
                self.0.iter().flat_map(|v| v.to_le_bytes()).collect()
            }
        }
    };
}
payload!(Floats, "Float64", "{:e} ");
payload!(Ints32, "Int32", "{} ");
payload!(Ints64, "Int64", "{} ");
payload!(Bytes, "UInt8", "{} ");

fn array<P: Payload>(s: &mut String, enc: VtuEncoding, name: &str, comps: usize, data: &P) {
    let format = if enc == VtuEncoding::Ascii { "ascii" } else { "binary" };
    let _ = writeln!(
        s,
        "<DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{comps}\" format=\"{format}\">",
        P::TYPE,
        xml_escape(name)
    );
    match enc {
        VtuEncoding::Ascii => data.ascii(s),
        VtuEncoding::Base64 => s.push_str(&encode_base64(&data.le_bytes(), false)),
        VtuEncoding::Base64Zlib => s.push_str(&encode_base64(&data.le_bytes(), true)),
    }
    s.push_str("\n</DataArray>\n");
}

/// Escapes the characters that would end an XML attribute value.
pub(crate) fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}
