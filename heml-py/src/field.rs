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
use crate::errors::{HemlError, IntoPyResult};

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

    /// The positions `x` as an (n, 3) input with finite coordinates (`HemlError`
    /// naming the first node with a NaN or ∞ otherwise).
    fn positions<'py>(&self, x: &Bound<'py, PyAny>) -> PyResult<arrays::Points<'py>> {
        let x = arrays::points(x, "x", Some(self.field.n_nodes()))?;
        x.check_finite("x")?;
        Ok(x)
    }

    /// `HemlError` for a non-finite `result` (e.g. "energy inf") from finite
    /// positions `x`, naming the first tet whose J or w is not finite (looked up only
    /// on this error path, by one more evaluation).
    fn not_finite(&self, what: &str, result: String, x: &[Vec3]) -> PyErr {
        let tet = self.field.tet_states(x).ok().and_then(|s| {
            let k = s.iter().position(|(j, w)| !(j.is_finite() && w.is_finite()))?;
            Some(format!(
                "; first tet with a non-finite state: tet {} (J = {}, w = {})",
                self.field.tet_ids()[k],
                s[k].0,
                s[k].1
            ))
        });
        HemlError::new_err(format!(
            "{what}: the result is not finite at these finite positions: {result} (coordinates too large, or \
             the law undefined there){}",
            tet.unwrap_or_default()
        ))
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

    /// Total elastic energy W (J) at positions `x` ((n, 3) float64). A NaN or ∞
    /// coordinate raises `HemlError` naming the node; so does a non-finite energy
    /// from finite positions (naming the first tet concerned).
    fn energy(&self, x: &Bound<'_, PyAny>) -> PyResult<f64> {
        let x = self.positions(x)?;
        let e = self.field.energy(x.as_slice()).py()?;
        if !e.is_finite() {
            return Err(self.not_finite("energy", format!("energy {e}"), x.as_slice()));
        }
        Ok(e)
    }

    /// `(energy, forces)` at positions `x`: the total energy (J) and the internal
    /// forces, a new (n, 3) float64 array written by the library in place. A NaN or
    /// ∞ coordinate raises `HemlError` naming the node; so does a non-finite energy
    /// or force from finite positions (naming the node and the first tet concerned).
    fn forces<'py>(&self, py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<(f64, Bound<'py, PyArray2<f64>>)> {
        let x = self.positions(x)?;
        let (f, e) = arrays::fill_vec3s(py, self.field.n_nodes(), |f| {
            let e = self.field.add_forces(x.as_slice(), f)?;
            let bad = arrays::first_non_finite(f);
            Ok::<_, heml::HemlError>((e, bad.map(|i| (i, f[i]))))
        })?;
        let (e, bad) = e.py()?;
        if let Some((i, fi)) = bad {
            let result = format!("force {:?} at node {i}, energy {e}", fi.as_slice());
            return Err(self.not_finite("forces", result, x.as_slice()));
        }
        if !e.is_finite() {
            return Err(self.not_finite("forces", format!("energy {e}"), x.as_slice()));
        }
        Ok((e, f))
    }

    /// Per tet of the field (in its order): `(J, w)` arrays, the volume ratio and
    /// the energy per unit rest volume (Pa). A NaN or ∞ coordinate raises
    /// `HemlError` naming the node; a non-finite J or w from finite positions names
    /// the tet.
    fn tet_states<'py>(&self, py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<ArrayPair<'py>> {
        let x = self.positions(x)?;
        let s = self.field.tet_states(x.as_slice()).py()?;
        if let Some(k) = s.iter().position(|(j, w)| !(j.is_finite() && w.is_finite())) {
            let (j, w) = s[k];
            let tet = self.field.tet_ids()[k];
            return Err(HemlError::new_err(format!(
                "tet_states: J = {j}, w = {w} of tet {tet} is not finite at these finite positions"
            )));
        }
        let (j, w): (Vec<f64>, Vec<f64>) = s.into_iter().unzip();
        Ok((PyArray1::from_vec(py, j), PyArray1::from_vec(py, w)))
    }

    /// The tangent stiffness K = ∂²W/∂x² at `x`, exact (from the law's generated
    /// second derivatives, the inversion extension included); with
    /// `project_psd=True` each tet's 12×12 matrix is projected to positive
    /// semi-definite, as the implicit integrators do. A NaN or ∞ coordinate raises
    /// `HemlError` naming the node, a non-finite stiffness names the tet.
    #[pyo3(signature = (x, project_psd = false))]
    fn tangent(&self, x: &Bound<'_, PyAny>, project_psd: bool) -> PyResult<Tangent> {
        let x = self.positions(x)?;
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

    /// K·dx for `dx` of shape (n, 3), a new (n, 3) float64 array. A NaN or ∞ in
    /// `dx` raises `HemlError` naming the node, as does a product that overflows.
    fn dot<'py>(&self, py: Python<'py>, dx: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let dx = arrays::points(dx, "dx", Some(self.op.n_nodes()))?;
        dx.check_finite("dx")?;
        let (y, r) = arrays::fill_vec3s(py, self.op.n_nodes(), |y| {
            self.op.add_product(dx.as_slice(), y)?;
            Ok::<_, heml::HemlError>(arrays::first_non_finite(y).map(|i| (i, y[i])))
        })?;
        if let Some((i, yi)) = r.py()? {
            return Err(HemlError::new_err(format!(
                "dot: K·dx = {:?} at node {i} is not finite (the product of finite values overflowed)",
                yi.as_slice()
            )));
        }
        Ok(y)
    }

    /// `K @ dx`, as `dot`.
    fn __matmul__<'py>(&self, py: Python<'py>, dx: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.dot(py, dx)
    }

    /// `dx @ K`: K is symmetric, so dxᵀ·K = (K·dx)ᵀ, returned as `dot` returns K·dx,
    /// (n, 3). (`__array_ufunc__ = None` makes a NumPy array on the left defer to it.)
    fn __rmatmul__<'py>(&self, py: Python<'py>, dx: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.dot(py, dx)
    }

    /// `None`: NumPy operators with a `Tangent` operand (`dx @ K`) return
    /// `NotImplemented`, so that Python calls `Tangent.__rmatmul__`.
    #[classattr]
    fn __array_ufunc__() -> Option<()> {
        None
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
