//! The registry from Python: `heml.materials()`, `heml.material(name, **params)`,
//! `heml.integrators()`, and the `Material` class (a law with its parameters).

use std::sync::Arc;

use heml::law::LawKind;
use heml::prelude::{ForceOptions, Params};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyInt, PyList};

use crate::arrays;
use crate::errors::IntoPyResult;
use crate::field::ForceField;
use crate::mesh::Mesh;

fn kind_name(kind: LawKind) -> &'static str {
    match kind {
        LawKind::Invariant => "invariant",
        LawKind::Link => "link",
        LawKind::Stretch => "stretch",
        LawKind::Fibre => "fibre",
    }
}

/// Every registered law, sorted by name, as a list of dicts with keys `name`,
/// `parameters` (list of names, in declaration order), `parameter_docs`,
/// `energy` (the expression as declared), `kind` (`"invariant"`, `"link"`, `"stretch"` or `"fibre"`),
/// `young_poisson` (whether `E` and `nu` are accepted) and `doc`.
#[pyfunction]
pub fn materials(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let out = PyList::empty(py);
    for e in heml::materials_list() {
        let d = PyDict::new(py);
        d.set_item("name", e.name)?;
        d.set_item("parameters", e.params.iter().map(|p| p.name).collect::<Vec<_>>())?;
        d.set_item("parameter_docs", e.params.iter().map(|p| p.doc).collect::<Vec<_>>())?;
        d.set_item("energy", e.energy)?;
        d.set_item("kind", kind_name(e.kind))?;
        d.set_item("young_poisson", e.small_strain.is_some())?;
        d.set_item("doc", e.doc)?;
        out.append(d)?;
    }
    Ok(out)
}

/// Every registered integrator as `(name, doc)` pairs, sorted by name.
#[pyfunction]
pub fn integrators() -> Vec<(&'static str, &'static str)> {
    heml::integrators_list().iter().map(|e| (e.name, e.doc)).collect()
}

/// Builds the law `name` from keyword parameters, checked exactly as in Rust and in
/// scene files: unknown, missing, NaN or negative values raise `HemlError` listing
/// the expected parameters; laws with a small-strain mapping also take `E` and `nu`
/// (e.g. `heml.material("neo_hookean", E=3e3, nu=0.45)`).
#[pyfunction]
#[pyo3(signature = (name, **params))]
pub fn material(name: &str, params: Option<&Bound<'_, PyDict>>) -> PyResult<Material> {
    Ok(Material {
        law: Arc::from(build_law(name, params)?),
        energy: None,
        volumetric_energy: None,
    })
}

/// A law declared at run time by its strain energy, in the language of the Rust
/// `#[energy(...)]` (variables `I1`, `I2`, `J`, `I1bar`, `I2bar`; `ln`, `exp`,
/// `sqrt`, `powi`, `powf`, `max`, …) over the keyword parameters, e.g.
/// `heml.material_from_energy("mu/2*(I1-3) - mu*ln(J) + lam/2*ln(J).powi(2)", mu=1e3, lam=4e3)`.
/// Its derivatives are exact (differentiated once, symbolically) and its forces
/// equal those of a built-in law with the same energy. A mistake in the text raises
/// `HemlError` with the column and what is allowed there; every parameter must be
/// used by the energy. `inversion_fix=False` drops the J0 extension (for energies
/// finite at J <= 0). `volumetric_energy="kappa/2*(J-1).powi(2)"` declares the law's
/// volumetric energy U(J) (J and the parameters; U(1) = U'(1) = 0 and U''(1) = the
/// law's bulk modulus, checked), which the anti-locking formulations
/// (`Material.with_volumetric("patch")`) evaluate at averaged volume ratios instead
/// of the law along pure dilations.
#[pyfunction]
#[pyo3(signature = (energy, *, volumetric_energy = None, inversion_fix = true, **params))]
pub fn material_from_energy(
    energy: &str,
    volumetric_energy: Option<&str>,
    inversion_fix: bool,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<Material> {
    let p = to_params("energy", params)?;
    let mut law = heml::RuntimeLaw::with_inversion_fix(energy, &p, inversion_fix).py()?;
    if let Some(u) = volumetric_energy {
        law = law.with_volumetric_energy(u).py()?;
    }
    Ok(Material {
        law: Arc::new(law),
        energy: Some(energy.to_string()),
        volumetric_energy: volumetric_energy.map(str::to_string),
    })
}

/// The law `name` with the parameters of a Python dict (values: numbers).
pub(crate) fn build_law(name: &str, params: Option<&Bound<'_, PyDict>>) -> PyResult<Box<dyn heml::prelude::Material>> {
    heml::material(name, &to_params(name, params)?).py()
}

/// The parameters of a Python dict (values: numbers) of law `name`.
fn to_params(name: &str, params: Option<&Bound<'_, PyDict>>) -> PyResult<Params> {
    let mut p = Params::new();
    for (k, v) in params.iter().flat_map(|d| d.iter()) {
        let key: String = k.extract()?;
        let value: f64 = v.extract().map_err(|_| {
            if v.is_instance_of::<PyInt>() {
                // an int beyond the float64 range (1e308)
                let digits = v
                    .str()
                    .map(|s| s.to_string().trim_start_matches('-').len())
                    .unwrap_or(0);
                return PyValueError::new_err(format!(
                    "material '{name}': parameter {key} is out of range: an integer of {digits} digits, beyond \
                     the float64 range (about 1.8e308)"
                ));
            }
            PyTypeError::new_err(format!(
                "material '{name}': parameter {key} must be a number, got {}",
                v.get_type().name().map(|n| n.to_string()).unwrap_or_default()
            ))
        })?;
        p.set(&key, value);
    }
    Ok(p)
}

/// Python's keywords, which cannot be keyword-argument names.
const PYTHON_KEYWORDS: &[&str] = &[
    "False", "None", "True", "and", "as", "assert", "async", "await", "break", "class", "continue", "def", "del",
    "elif", "else", "except", "finally", "for", "from", "global", "if", "import", "in", "is", "lambda", "nonlocal",
    "not", "or", "pass", "raise", "return", "try", "while", "with", "yield",
];

/// A hyperelastic law with its parameter values (from `heml.material`).
#[pyclass(frozen, module = "heml")]
pub struct Material {
    pub(crate) law: Arc<dyn heml::prelude::Material>,
    /// The energy text of a law from `heml.material_from_energy`.
    pub(crate) energy: Option<String>,
    /// Its declared volumetric energy (`volumetric_energy=`), for the repr.
    pub(crate) volumetric_energy: Option<String>,
}

#[pymethods]
impl Material {
    /// The energy text of a law from `heml.material_from_energy`, else `None`.
    #[getter]
    fn energy(&self) -> Option<&str> {
        self.energy.as_deref()
    }

    /// Registry name of the law (`"energy"` for one from `heml.material_from_energy`).
    #[getter]
    fn name(&self) -> &'static str {
        self.law.name()
    }

    /// `"invariant"` (w(I1, I2, J)), `"link"` (per-edge energy), `"stretch"` (principal
    /// stretches) or `"fibre"` (fibre invariants I4, I5).
    #[getter]
    fn kind(&self) -> &'static str {
        kind_name(self.law.kind())
    }

    /// The resolved parameter values by name (E/ν already converted).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (info, v) in self.law.param_info().iter().zip(self.law.param_values()) {
            d.set_item(info.name, v)?;
        }
        Ok(d)
    }

    /// How the law's volumetric energy is discretised: `"element"` (as written, per
    /// tet), or `"nodal (stabilization s)"` / `"patch (k tets, stabilization s)"`.
    #[getter]
    fn volumetric(&self) -> String {
        self.law.volumetric().to_string()
    }

    /// This law with its volumetric energy discretised by `formulation`:
    /// `"element"`, or the anti-locking `"nodal"` (average nodal volume ratios) or
    /// `"patch"` (one volume per compact patch of 6 tets), for nearly incompressible
    /// tissue, where linear tets lock; `stabilization` is the factor s of the kept
    /// element fraction β = min(1, s·μ0/K0) (default 0.1). Its force fields and
    /// systems use it.
    #[pyo3(signature = (formulation, stabilization = None))]
    fn with_volumetric(&self, formulation: &str, stabilization: Option<f64>) -> PyResult<Material> {
        let v = heml::law::Volumetric::parse(formulation, stabilization).py()?;
        Ok(Material {
            law: Arc::from(self.law.with_volumetric(v).py()?),
            energy: self.energy.clone(),
            volumetric_energy: self.volumetric_energy.clone(),
        })
    }

    /// The HEML force field of this law over `mesh` (over the tets `tets` only when
    /// given: tet ids, each at most once, or a boolean mask with one entry per tet;
    /// a negative id is a `ValueError`, a repeated one a `HemlError`). `j0` and
    /// `inversion_fix` are the inversion extension's options (DESIGN §1): below
    /// J = j0 the law is replaced by its Taylor extension.
    #[pyo3(signature = (mesh, tets = None, *, j0 = 0.4, inversion_fix = true))]
    fn force_field(
        &self,
        mesh: &Mesh,
        tets: Option<&Bound<'_, PyAny>>,
        j0: f64,
        inversion_fix: bool,
    ) -> PyResult<ForceField> {
        let tets = match tets {
            Some(t) => Some(arrays::id_set(t, "tets", mesh.inner.n_tets(), "tet")?),
            None => None,
        };
        let opts = ForceOptions { j0, inversion_fix };
        ForceField::new(self.law.clone(), mesh.inner.clone(), tets, opts)
    }

    /// Python that builds this law again: the parameters as keyword arguments,
    /// those named like a Python keyword (`lambda`) in a `**{...}` dict.
    fn __repr__(&self) -> String {
        let (mut params, mut keywords) = (Vec::new(), Vec::new());
        for (info, v) in self.law.param_info().iter().zip(self.law.param_values()) {
            if PYTHON_KEYWORDS.contains(&info.name) {
                keywords.push(format!("{:?}: {v:?}", info.name));
            } else {
                params.push(format!("{}={v:?}", info.name));
            }
        }
        if !keywords.is_empty() {
            params.push(format!("**{{{}}}", keywords.join(", ")));
        }
        let law = match (&self.energy, &self.volumetric_energy) {
            (Some(energy), Some(u)) => format!(
                "heml.material_from_energy({energy:?}, volumetric_energy={u:?}, {})",
                params.join(", ")
            ),
            (Some(energy), None) => format!("heml.material_from_energy({energy:?}, {})", params.join(", ")),
            _ => format!("heml.material({:?}, {})", self.law.name(), params.join(", ")),
        };
        match self.law.volumetric() {
            heml::law::Volumetric::Element => law,
            heml::law::Volumetric::Nodal { stabilization } => {
                format!("{law}.with_volumetric(\"nodal\", {stabilization:?})")
            }
            heml::law::Volumetric::Patch { stabilization, .. } => {
                format!("{law}.with_volumetric(\"patch\", {stabilization:?})")
            }
        }
    }
}
