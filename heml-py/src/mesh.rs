//! `heml.Mesh`: a validated tetrahedral mesh from NumPy arrays, a file or a
//! generator, its boundary surface, and the meshio bridge.

use std::path::PathBuf;
use std::sync::Arc;

use heml::io::MeshData;
use heml::mesh::generate::HexSplit;
use heml::mesh::surface::BoundarySurface;
use heml::TetMesh;
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::exceptions::{PyImportError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::arrays;
use crate::errors::{HemlError, IntoPyResult};

/// A validated linear tetrahedral mesh (immutable).
///
/// Built from `nodes` ((n, 3) float64) and `tets` ((m, 4) integers), with optional
/// per-tet integer `tags` (regions: integers in the int32 range, or floats with
/// integral values; anything else is a `ValueError` naming the tet, never
/// truncated). Construction checks finite coordinates,
/// indices in range, no degenerate tet, and reorients negatively oriented tets
/// (their nodes 2 and 3 are swapped), exactly as the Rust `TetMesh`: a bad mesh
/// raises `HemlError` naming the offending tets or nodes. The arrays are copied
/// into the mesh; the `nodes`, `tets` and `tags` properties return fresh copies.
#[pyclass(frozen, module = "heml")]
pub struct Mesh {
    pub(crate) inner: Arc<TetMesh>,
}

impl Mesh {
    pub(crate) fn wrap(mesh: TetMesh) -> Mesh {
        Mesh { inner: Arc::new(mesh) }
    }
}

/// Surface triangles as an (k, 3) int64 array, or PyVista's padded layout.
fn faces_array<'py>(py: Python<'py>, s: &BoundarySurface, padded: bool) -> PyResult<Bound<'py, PyAny>> {
    let tris = s.triangles();
    Ok(if padded {
        let flat: Vec<i64> = tris
            .iter()
            .flat_map(|t| [3, t[0] as i64, t[1] as i64, t[2] as i64])
            .collect();
        PyArray1::from_vec(py, flat).into_any()
    } else {
        let flat: Vec<i64> = tris.iter().flat_map(|t| t.map(i64::from)).collect();
        PyArray1::from_vec(py, flat).reshape([tris.len(), 3])?.into_any()
    })
}

/// The `(points, faces)` of a surface over the positions `x`.
pub(crate) fn surface_tuple<'py>(
    py: Python<'py>,
    s: &BoundarySurface,
    x: &[heml::Vec3],
    padded: bool,
) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyAny>)> {
    Ok((arrays::vec3s_to_py(py, x)?, faces_array(py, s, padded)?))
}

#[pymethods]
impl Mesh {
    #[new]
    #[pyo3(signature = (nodes, tets, tags = None))]
    fn new(nodes: &Bound<'_, PyAny>, tets: &Bound<'_, PyAny>, tags: Option<&Bound<'_, PyAny>>) -> PyResult<Mesh> {
        let nodes = arrays::points(nodes, "nodes", None)?.to_vec("nodes")?;
        let tets = arrays::index_rows::<4>(tets, "tets")?;
        let tags = match tags {
            None => {
                let mut t = Vec::new();
                arrays::reserve(&mut t, tets.len(), "tags")?;
                t.resize(tets.len(), 0);
                t
            }
            Some(t) => arrays::int32_tags(t, "tags", "tet", 0)?,
        };
        TetMesh::with_tags(nodes, tets, tags).py().map(Mesh::wrap)
    }

    /// Rest node positions, (n, 3) float64 (a copy).
    #[getter]
    fn nodes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        arrays::vec3s_to_py(py, self.inner.nodes())
    }

    /// Tet node indices, (m, 4) int64, positively oriented (a copy).
    #[getter]
    fn tets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        let flat: Vec<i64> = self.inner.tets().iter().flat_map(|t| t.map(i64::from)).collect();
        PyArray1::from_vec(py, flat).reshape([self.inner.n_tets(), 4])
    }

    /// Region tag of each tet, (m,) int32 (a copy; 0 where the source had none).
    #[getter]
    fn tags<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i32>> {
        PyArray1::from_slice(py, self.inner.tags())
    }

    /// The mesh file's named node sets, as a dict of name → sorted node ids ((k,)
    /// int64 arrays, copies): a Gmsh file's physical points, curves and surfaces by
    /// name (`"surface 7"` without one), a Medit file's boundary references
    /// (`"surface 3"`), an OpenSurgSim `.ply`'s
    /// `"boundary_condition"` nodes (pass them as a system's `fixed`). Empty for
    /// other files.
    #[getter]
    fn node_sets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, ids) in self.inner.node_sets() {
            let ids: Vec<i64> = ids.iter().map(|&i| i as i64).collect();
            d.set_item(name, PyArray1::from_vec(py, ids))?;
        }
        Ok(d)
    }

    /// Number of nodes.
    #[getter]
    fn n_nodes(&self) -> usize {
        self.inner.n_nodes()
    }

    /// Number of tets.
    #[getter]
    fn n_tets(&self) -> usize {
        self.inner.n_tets()
    }

    /// How many tets were reoriented at construction (negative input orientation).
    #[getter]
    fn reoriented_count(&self) -> usize {
        self.inner.reoriented_count()
    }

    /// Total rest volume (m³).
    #[getter]
    fn volume(&self) -> f64 {
        self.inner.total_volume()
    }

    /// Lumped nodal masses for `density` (kg/m³, a finite number > 0, else
    /// `HemlError`): m_i = Σ ρ Vol_k / 4, (n,) float64.
    fn lumped_masses<'py>(&self, py: Python<'py>, density: f64) -> PyResult<Bound<'py, PyArray1<f64>>> {
        if !(density.is_finite() && density > 0.0) {
            return Err(HemlError::new_err(format!(
                "lumped_masses: density {density} must be a finite number > 0"
            )));
        }
        Ok(PyArray1::from_vec(py, self.inner.lumped_masses(density)))
    }

    /// The outward boundary surface as `(points, faces)`: `points` are all the mesh
    /// nodes ((n, 3) float64, rest positions; `faces` index into them) and `faces`
    /// the boundary triangles, (k, 3) int64, counter-clockwise seen from outside.
    /// With `padded=True`, `faces` is PyVista's flat layout `[3, a, b, c, 3, …]`,
    /// so `pyvista.PolyData(*mesh.surface(padded=True))` shows it (or
    /// `pyvista.PolyData.from_regular_faces(*mesh.surface())`).
    #[pyo3(signature = (padded = false))]
    fn surface<'py>(&self, py: Python<'py>, padded: bool) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyAny>)> {
        let s = BoundarySurface::of_tet_mesh(&self.inner);
        surface_tuple(py, &s, self.inner.nodes(), padded)
    }

    /// A `meshio.Mesh` with one `"tetra"` cell block and the tags as cell data
    /// `"tag"` (arrays copied). Needs meshio (`pip install meshio`).
    fn to_meshio<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let meshio = import_meshio(py)?;
        let cells = PyList::new(py, [("tetra", self.tets(py)?)])?;
        let cell_data = PyDict::new(py);
        cell_data.set_item("tag", PyList::new(py, [self.tags(py)])?)?;
        let kwargs = PyDict::new(py);
        kwargs.set_item("cell_data", cell_data)?;
        meshio.call_method("Mesh", (self.nodes(py)?, cells), Some(&kwargs))
    }

    /// A mesh from a `meshio.Mesh`: its points and every `"tetra"` cell block
    /// (other cell types are skipped); tags from the first cell data among
    /// `"tag"`, `"gmsh:physical"`, `"medit:ref"`, `"CellEntityIds"` that it has
    /// (0 otherwise): integers in the int32 range or integral floats, else a
    /// `ValueError` naming the block and cell (never truncated or wrapped). Points
    /// with 2 coordinates are refused.
    #[staticmethod]
    fn from_meshio(m: &Bound<'_, PyAny>) -> PyResult<Mesh> {
        let nodes = arrays::points(&m.getattr("points")?, "meshio points", None)?.to_vec("meshio points")?;
        let cells = m.getattr("cells")?;
        let cell_data = m.getattr("cell_data")?.cast_into::<PyDict>()?;
        let tag_key = ["tag", "gmsh:physical", "medit:ref", "CellEntityIds"]
            .into_iter()
            .find(|k| cell_data.contains(*k).unwrap_or(false));
        let mut tets = Vec::new();
        let mut tags = Vec::new();
        for (b, block) in cells.try_iter()?.enumerate() {
            let block = block?;
            if block.getattr("type")?.extract::<String>()? != "tetra" {
                continue;
            }
            let t = arrays::index_rows::<4>(&block.getattr("data")?, "meshio tetra cells")?;
            match tag_key {
                Some(k) => {
                    let data = cell_data
                        .get_item(k)?
                        .ok_or_else(|| PyValueError::new_err(format!("meshio cell data '{k}' disappeared")))?
                        .get_item(b)?;
                    let what = format!("meshio cell data '{k}' of block {b}");
                    let v = arrays::int32_tags(&data, &what, "cell", 0)?;
                    if v.len() != t.len() {
                        return Err(PyValueError::new_err(format!(
                            "meshio cell data '{k}' of block {b} has {} entries for {} tets",
                            v.len(),
                            t.len()
                        )));
                    }
                    tags.extend(v);
                }
                None => tags.extend(std::iter::repeat_n(0, t.len())),
            }
            tets.extend(t);
        }
        let data = MeshData {
            nodes,
            tets,
            tags,
            ..Default::default()
        };
        data.into_mesh().py().map(Mesh::wrap)
    }

    fn __repr__(&self) -> String {
        format!(
            "heml.Mesh({} nodes, {} tets, {} region(s))",
            self.inner.n_nodes(),
            self.inner.n_tets(),
            self.inner.distinct_tags().len()
        )
    }
}

fn import_meshio(py: Python<'_>) -> PyResult<Bound<'_, PyModule>> {
    py.import("meshio")
        .map_err(|_| PyImportError::new_err("meshio is not installed (pip install meshio)"))
}

/// Reads a mesh file, choosing the reader by extension (`.msh`, `.vtk`, `.vtu`,
/// `.node`/`.ele`, `.mesh`, `.ply`), and validates it. Errors (`HemlError`) name the file
/// and line. Non-tet elements are skipped.
#[pyfunction]
pub fn read_mesh(path: PathBuf) -> PyResult<Mesh> {
    heml::io::read_mesh(&path).py().map(|(m, _report)| Mesh::wrap(m))
}

/// Writes `mesh` in the format of `path`'s extension (`.msh` as Gmsh 4.1 ASCII,
/// `.vtu` zlib-compressed, `.vtk`, `.node`/`.ele`, `.mesh`, `.ply` as ASCII), atomically.
#[pyfunction]
pub fn write_mesh(path: PathBuf, mesh: &Mesh) -> PyResult<()> {
    heml::io::write_mesh(&path, &mesh.inner).py()
}

/// A box `size` (m, 3 numbers) cut into `cells` (3 integers >= 0; a negative one is
/// a `ValueError`) hexahedra, each split into tets: `split` is `"five"`, `"six"`
/// (default), `"ten"` (both five-tet cuttings, each tet weighted ½) or
/// `"twentyfour"`.
#[pyfunction]
#[pyo3(signature = (size, cells, split = "six"))]
pub fn box_mesh(size: [f64; 3], cells: [i64; 3], split: &str) -> PyResult<Mesh> {
    let mut counts = [0usize; 3];
    for (c, &v) in counts.iter_mut().zip(&cells) {
        *c = usize::try_from(v)
            .map_err(|_| PyValueError::new_err(format!("cells must be 3 integers >= 0, got {cells:?}")))?;
    }
    let split = match split {
        "five" => HexSplit::Five,
        "six" => HexSplit::Six,
        "ten" => HexSplit::Ten,
        "twentyfour" => HexSplit::TwentyFour,
        other => {
            return Err(PyValueError::new_err(format!(
                "split must be 'five', 'six', 'ten' or 'twentyfour', got {other:?}"
            )))
        }
    };
    heml::mesh::generate::box_mesh(size, counts, split).py().map(Mesh::wrap)
}
