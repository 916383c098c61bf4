//! The library's errors as Python exceptions: [`HemlError`] carries the library's
//! message (file, line, key, node or tet id) unchanged.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::PyErr;

create_exception!(
    heml,
    HemlError,
    PyException,
    "An error reported by the HEML library: bad mesh, unknown law or integrator, bad \
     parameters, a malformed file, a step that produced NaN… The message is the \
     library's, naming the file, line, key, node or tet concerned."
);

/// Converts a library error into a `heml.HemlError` with the library's message.
pub fn to_py(e: heml::HemlError) -> PyErr {
    HemlError::new_err(e.to_string())
}

/// `.map_err(to_py)` in one call.
pub trait IntoPyResult<T> {
    /// The library result as a Python result.
    fn py(self) -> pyo3::PyResult<T>;
}

impl<T> IntoPyResult<T> for heml::Result<T> {
    fn py(self) -> pyo3::PyResult<T> {
        self.map_err(to_py)
    }
}
