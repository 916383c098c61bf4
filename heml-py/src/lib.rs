//! Python bindings of HEML: the extension module `heml._heml`, re-exported by the
//! Python package `heml` (`heml-py/python/heml`). Arrays cross the boundary as NumPy
//! arrays, never as per-node Python objects; each function's doc says whether it
//! copies. Built by maturin (`pip install ./heml-py`), tested with pytest
//! (`heml-py/tests`).

mod arrays;
mod bench;
mod control;
mod errors;
mod field;
mod materials;
mod mesh;
mod scene;
mod system;

use pyo3::prelude::*;

/// The extension module; `heml/__init__.py` re-exports everything.
#[pymodule]
fn _heml(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("HemlError", m.py().get_type::<errors::HemlError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(materials::materials, m)?)?;
    m.add_function(wrap_pyfunction!(materials::material, m)?)?;
    m.add_function(wrap_pyfunction!(materials::material_from_energy, m)?)?;
    m.add_function(wrap_pyfunction!(materials::integrators, m)?)?;
    m.add_class::<materials::Material>()?;
    m.add_function(wrap_pyfunction!(mesh::read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::write_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::box_mesh, m)?)?;
    m.add_class::<mesh::Mesh>()?;
    m.add_class::<field::ForceField>()?;
    m.add_class::<field::Tangent>()?;
    m.add_class::<system::Ramp>()?;
    m.add_class::<system::System>()?;
    m.add_class::<scene::Scene>()?;
    m.add_function(wrap_pyfunction!(bench::_time_forces, m)?)?;
    m.add_function(wrap_pyfunction!(bench::_reads_in_place, m)?)?;
    Ok(())
}
