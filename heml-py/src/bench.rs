//! Support for heml-py's own scripts and tests, underscored: not part of the
//! package's API. Timing for `heml-py/bench/forces_overhead.py` (the same force
//! evaluation as `ForceField.forces`, timed inside Rust, so that the script can
//! quote the cost of the Python call — argument checks, the output array — against
//! the Rust call), and whether an input array is read in place.

use std::time::Instant;

use heml::Vec3;
use pyo3::prelude::*;

use crate::arrays;
use crate::errors::IntoPyResult;
use crate::field::ForceField;

/// Seconds taken by each of `repeats` Rust calls of the field's forces at `x`, each
/// into a freshly allocated zeroed buffer as `ForceField.forces` does.
#[pyfunction]
pub fn _time_forces(field: &ForceField, x: &Bound<'_, PyAny>, repeats: usize) -> PyResult<Vec<f64>> {
    let field = field.elastic();
    let x = arrays::points(x, "x", Some(field.n_nodes()))?;
    let mut times = Vec::with_capacity(repeats);
    for _ in 0..repeats {
        let start = Instant::now();
        let mut f = vec![Vec3::zeros(); field.n_nodes()];
        std::hint::black_box(field.add_forces(x.as_slice(), &mut f).py()?);
        std::hint::black_box(&f);
        times.push(start.elapsed().as_secs_f64());
    }
    Ok(times)
}

/// Whether `x`, an (n, 3) float64 input, is read in place (C-contiguous and aligned)
/// rather than copied: what `heml-py/tests` check of the zero-copy rule.
#[pyfunction]
pub fn _reads_in_place(x: &Bound<'_, PyAny>) -> PyResult<bool> {
    let p = arrays::points(x, "x", None)?;
    let a = x.cast::<numpy::PyUntypedArray>().ok();
    Ok(a.is_some_and(|a| std::ptr::eq(a.as_ptr(), p.array_ptr())))
}
