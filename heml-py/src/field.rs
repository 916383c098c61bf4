//! `heml.ForceField` (energy and forces of a law over a mesh) and `heml.Tangent`
//! (its stiffness at a configuration: products, 12×12 tet matrices, scipy.sparse).

use std::sync::Arc;

use heml::force::tangent::TangentOperator;
use heml::prelude::{ElasticForces, ForceOptions, Material};
use heml::{TetMesh, Vec3};
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods};
use pyo3::exceptions::{PyImportError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays;
use crate::errors::IntoPyResult;

/// Two float64 arrays (per-tet J and w).
type ArrayPair<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// The internal forces of one law over (a selection of tets of) a mesh, from
/// `Material.force_field(mesh)`.
///
/// Positions `x` are (n, 3) float64 arrays with one row per mesh node; a
/// C-contiguous float64 array is read in place (no copy). `forces` are the
/// internal forces −∂W/∂x (N), summed per node, bit-for-bit those of the Rust
/// `ElasticForces::forces` on the same mesh and positions.
#[pyclass(frozen, module = "heml")]
pub struct ForceField {
    field: Box<dyn ElasticForces>,
    law: Arc<dyn Material>,
    mesh: Arc<TetMesh>,
    tets: Option<Vec<usize>>,
    opts: ForceOptions,
}

impl ForceField {
    pub(crate) fn new(
        law: Arc<dyn Material>,
        mesh: Arc<TetMesh>,
        tets: Option<Vec<usize>>,
        opts: ForceOptions,
    ) -> PyResult<ForceField> {
        let field = law.force_field(&mesh, tets.as_deref(), &opts).py()?;
        Ok(ForceField {
            field,
            law,
            mesh,
            tets,
            opts,
        })
    }

    /// The library's field (for the timing helper).
    pub(crate) fn elastic(&self) -> &dyn ElasticForces {
        self.field.as_ref()
    }

    fn tangent_at(&self, x: &[Vec3], project_psd: bool) -> PyResult<Box<dyn TangentOperator>> {
        let mut k = self
            .law
            .tangent(&self.mesh, self.tets.as_deref(), &self.opts, project_psd)
            .py()?
            .ok_or_else(|| PyValueError::new_err(format!("law '{}' has no tangent", self.law.name())))?;
        k.update(x).py()?;
        Ok(k)
    }
}

#[pymethods]
impl ForceField {
    /// Number of nodes positions must have.
    #[getter]
    fn n_nodes(&self) -> usize {
        self.field.n_nodes()
    }

    /// Number of tets the field sums over.
    #[getter]
    fn n_tets(&self) -> usize {
        self.field.n_tets()
    }

    /// Total elastic energy W (J) at positions `x` ((n, 3) float64).
    fn energy(&self, x: &Bound<'_, PyAny>) -> PyResult<f64> {
        let x = arrays::points(x, "x", Some(self.field.n_nodes()))?;
        self.field.energy(x.as_slice()).py()
    }

    /// `(energy, forces)` at positions `x`: the total energy (J) and the internal
    /// forces, a new (n, 3) float64 array written by the library in place.
    fn forces<'py>(&self, py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<(f64, Bound<'py, PyArray2<f64>>)> {
        let x = arrays::points(x, "x", Some(self.field.n_nodes()))?;
        let (f, e) = arrays::fill_vec3s(py, self.field.n_nodes(), |f| self.field.add_forces(x.as_slice(), f));
        Ok((e.py()?, f))
    }

    /// Per tet of the field (in its order): `(J, w)` arrays, the volume ratio and
    /// the energy per unit rest volume (Pa).
    fn tet_states<'py>(&self, py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<ArrayPair<'py>> {
        let x = arrays::points(x, "x", Some(self.field.n_nodes()))?;
        let s = self.field.tet_states(x.as_slice()).py()?;
        let (j, w): (Vec<f64>, Vec<f64>) = s.into_iter().unzip();
        Ok((PyArray1::from_vec(py, j), PyArray1::from_vec(py, w)))
    }

    /// The tangent stiffness K = ∂²W/∂x² at `x`, exact (from the law's generated
    /// second derivatives, the inversion extension included); with
    /// `project_psd=True` each tet's 12×12 matrix is projected to positive
    /// semi-definite, as the implicit integrators do.
    #[pyo3(signature = (x, project_psd = false))]
    fn tangent(&self, x: &Bound<'_, PyAny>, project_psd: bool) -> PyResult<Tangent> {
        let x = arrays::points(x, "x", Some(self.field.n_nodes()))?;
        Ok(Tangent {
            op: self.tangent_at(x.as_slice(), project_psd)?,
            mesh: self.mesh.clone(),
        })
    }

    /// K(x)·dx, (n, 3) float64: the Hessian-vector product (the change of the
    /// forces is −K·dx). Builds the tangent at `x` each call; keep a `Tangent`
    /// (`field.tangent(x)`) for repeated products at one `x`.
    #[pyo3(signature = (x, dx, project_psd = false))]
    fn hessian_product<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        dx: &Bound<'py, PyAny>,
        project_psd: bool,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.tangent(x, project_psd)?.dot(py, dx)
    }

    /// The stiffness K(x) as a `scipy.sparse` matrix of shape (3n, 3n), rows and
    /// columns ordered (node 0 x, y, z, node 1 x, …); `format` is any scipy sparse
    /// format name (default `"csr"`). Needs scipy.
    #[pyo3(signature = (x, project_psd = false, format = "csr"))]
    fn stiffness<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        project_psd: bool,
        format: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.tangent(x, project_psd)?.to_scipy(py, format)
    }

    fn __repr__(&self) -> String {
        format!(
            "heml.ForceField({}, {} nodes, {} tets)",
            self.law.name(),
            self.field.n_nodes(),
            self.field.n_tets()
        )
    }
}

/// The stiffness of a force field at one configuration (from
/// `ForceField.tangent(x)`): 144 numbers per tet, computed once, used by every
/// product.
#[pyclass(frozen, module = "heml")]
pub struct Tangent {
    op: Box<dyn TangentOperator>,
    mesh: Arc<TetMesh>,
}

#[pymethods]
impl Tangent {
    /// `(3n, 3n)`.
    #[getter]
    fn shape(&self) -> (usize, usize) {
        (3 * self.op.n_nodes(), 3 * self.op.n_nodes())
    }

    /// Whether each tet's matrix was projected to positive semi-definite.
    #[getter]
    fn projected(&self) -> bool {
        self.op.projects()
    }

    /// K·dx for `dx` of shape (n, 3), a new (n, 3) float64 array.
    fn dot<'py>(&self, py: Python<'py>, dx: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let dx = arrays::points(dx, "dx", Some(self.op.n_nodes()))?;
        let (y, r) = arrays::fill_vec3s(py, self.op.n_nodes(), |y| self.op.add_product(dx.as_slice(), y));
        r.py()?;
        Ok(y)
    }

    /// `K @ dx`, as `dot`.
    fn __matmul__<'py>(&self, py: Python<'py>, dx: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.dot(py, dx)
    }

    /// The 12×12 matrix of every tet, (m, 12, 12) float64 (a copy), rows and
    /// columns ordered (vertex 0 x, y, z, vertex 1 x, …) over `tet_ids`.
    fn tet_matrices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let m = self.op.tet_ids().len();
        let mut flat = Vec::with_capacity(144 * m);
        for k in 0..m {
            // symmetric: column-major storage read as rows is the same matrix
            flat.extend_from_slice(self.op.tet_stiffness(k).as_slice());
        }
        PyArray1::from_vec(py, flat).reshape([m, 12, 12])
    }

    /// Global ids of the tets, in the order of `tet_matrices`.
    #[getter]
    fn tet_ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<usize>> {
        PyArray1::from_slice(py, self.op.tet_ids())
    }

    /// K as a `scipy.sparse` matrix (3n, 3n) in `format` (default `"csr"`;
    /// duplicate entries of shared nodes summed). Needs scipy.
    #[pyo3(signature = (format = "csr"))]
    fn to_scipy<'py>(&self, py: Python<'py>, format: &str) -> PyResult<Bound<'py, PyAny>> {
        let sparse = py
            .import("scipy.sparse")
            .map_err(|_| PyImportError::new_err("scipy is not installed (pip install scipy)"))?;
        let ids = self.op.tet_ids();
        let n = 144 * ids.len();
        let (mut rows, mut cols, mut vals) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
        for (k, &t) in ids.iter().enumerate() {
            let tet = self.mesh.tets()[t];
            let m = self.op.tet_stiffness(k);
            for a in 0..12 {
                for b in 0..12 {
                    rows.push(3 * tet[a / 3] as i64 + (a % 3) as i64);
                    cols.push(3 * tet[b / 3] as i64 + (b % 3) as i64);
                    vals.push(m[(a, b)]);
                }
            }
        }
        let dim = 3 * self.op.n_nodes();
        let kwargs = PyDict::new(py);
        kwargs.set_item("shape", (dim, dim))?;
        let coo = sparse.call_method(
            "coo_matrix",
            ((
                PyArray1::from_vec(py, vals),
                (PyArray1::from_vec(py, rows), PyArray1::from_vec(py, cols)),
            ),),
            Some(&kwargs),
        )?;
        coo.call_method1("asformat", (format,))
    }

    fn __repr__(&self) -> String {
        format!(
            "heml.Tangent(shape={:?}, {} tets)",
            self.shape(),
            self.op.tet_ids().len()
        )
    }
}
