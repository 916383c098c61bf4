//! NumPy arrays in and out: the checks (dtype → `TypeError`, shape → `ValueError`)
//! and the conversions, in one place so that every function copies (or not) alike.
//!
//! * Positions and other (n, 3) float64 inputs are **viewed without a copy** when
//!   they are C-contiguous `numpy.float64` arrays; other float64 layouts (strided,
//!   Fortran order) are copied once. An ndarray of another dtype is a `TypeError`
//!   (no silent precision change); nested lists are converted by `numpy.asarray`.
//! * Index arrays (tets, node ids) are converted to the library's integer type: a
//!   copy (they are read once, when a mesh or a system is built).
//! * Outputs are fresh NumPy arrays that own their data; the forces are written by
//!   the library straight into the array returned.

use heml::Vec3;
use numpy::prelude::*;
use numpy::{PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArray};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyAny;

// `Vec3` (nalgebra's `Vector3<f64>`) is a `#[repr(C)]` `Matrix` over an
// `ArrayStorage`, `#[repr(transparent)]` over `[[f64; 3]; 1]`: three f64 in a row,
// no padding, every bit pattern valid. Checked here at compile time.
const _: () = assert!(std::mem::size_of::<Vec3>() == 24 && std::mem::align_of::<Vec3>() == 8);

/// A flat `[x0, y0, z0, x1, …]` buffer as vectors, without a copy.
fn as_vec3s(flat: &[f64]) -> &[Vec3] {
    assert!(flat.len().is_multiple_of(3));
    // SAFETY: `Vec3` has the layout of `[f64; 3]` (asserted above): the pointer is
    // aligned for f64, hence for `Vec3`, and covers `len / 3` whole vectors; the
    // borrow of `flat` bounds the lifetime.
    unsafe { std::slice::from_raw_parts(flat.as_ptr().cast::<Vec3>(), flat.len() / 3) }
}

/// [`as_vec3s`] for a buffer the library writes into.
fn as_vec3s_mut(flat: &mut [f64]) -> &mut [Vec3] {
    assert!(flat.len().is_multiple_of(3));
    // SAFETY: as in `as_vec3s`; the exclusive borrow of `flat` passes to the result.
    unsafe { std::slice::from_raw_parts_mut(flat.as_mut_ptr().cast::<Vec3>(), flat.len() / 3) }
}

/// Vectors as their flat coordinates, without a copy.
fn as_f64s(v: &[Vec3]) -> &[f64] {
    // SAFETY: `Vec3` has the layout of `[f64; 3]` (asserted above).
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<f64>(), 3 * v.len()) }
}

/// An (n, 3) float64 input, borrowed from NumPy (zero-copy) or copied.
pub enum Points<'py> {
    /// A C-contiguous float64 array, read in place.
    View(PyReadonlyArray2<'py, f64>),
    /// Any other layout, copied.
    Owned(Vec<Vec3>),
}

impl Points<'_> {
    /// The points as the library's vectors.
    pub fn as_slice(&self) -> &[Vec3] {
        match self {
            Points::View(a) => as_vec3s(a.as_slice().expect("checked C-contiguous")),
            Points::Owned(v) => v,
        }
    }
}

/// `numpy.asarray(obj)` for inputs that are not ndarrays (lists, tuples…).
fn as_ndarray<'py>(obj: &Bound<'py, PyAny>, dtype: Option<&str>) -> PyResult<Bound<'py, PyUntypedArray>> {
    if let Ok(a) = obj.cast::<PyUntypedArray>() {
        return Ok(a.clone());
    }
    let np = obj.py().import("numpy")?;
    let a = match dtype {
        Some(d) => np.call_method1("asarray", (obj, d))?,
        None => np.call_method1("asarray", (obj,))?,
    };
    Ok(a.cast_into::<PyUntypedArray>()?)
}

fn dtype_name(a: &Bound<'_, PyUntypedArray>) -> String {
    a.dtype().str().map(|s| s.to_string()).unwrap_or_else(|_| "?".into())
}

/// Checks `shape` against the expected number of columns (and rows when known).
fn check_shape(what: &str, shape: &[usize], rows: Option<usize>, cols: usize) -> PyResult<()> {
    let ok = shape.len() == 2 && shape[1] == cols && rows.is_none_or(|n| shape[0] == n);
    if ok {
        return Ok(());
    }
    let rows = rows.map_or("n".to_string(), |n| n.to_string());
    Err(PyValueError::new_err(format!(
        "{what} must have shape ({rows}, {cols}), got {shape:?}"
    )))
}

/// An (n, 3) float64 input (n = `rows` when given); see the module docs for when
/// it is copied.
pub fn points<'py>(obj: &Bound<'py, PyAny>, what: &str, rows: Option<usize>) -> PyResult<Points<'py>> {
    let a = as_ndarray(obj, Some("float64"))?;
    if !a.dtype().is_equiv_to(&numpy::dtype::<f64>(obj.py())) {
        return Err(PyTypeError::new_err(format!(
            "{what} must be a float64 array, got dtype {} (convert with .astype(numpy.float64))",
            dtype_name(&a)
        )));
    }
    check_shape(what, a.shape(), rows, 3)?;
    // `as_slice` also accepts Fortran order, whose rows are not contiguous triples
    let c_order = a.is_c_contiguous();
    let a = a.cast::<PyArray2<f64>>()?.readonly();
    if c_order {
        return Ok(Points::View(a));
    }
    let v = a.as_array();
    Ok(Points::Owned(
        v.rows().into_iter().map(|r| Vec3::new(r[0], r[1], r[2])).collect(),
    ))
}

/// Converts an integer array (any signed or unsigned NumPy integer dtype) to
/// indices, refusing negative entries. Returns the flat indices and the shape.
fn indices(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<(Vec<usize>, Vec<usize>)> {
    let a = as_ndarray(obj, None)?;
    let kind = a.dtype().kind();
    // an empty list converts to float64: take it as no index
    if !(kind == b'i' || kind == b'u' || (a.len() == 0 && kind == b'f')) {
        return Err(PyTypeError::new_err(format!(
            "{what} must be an integer array, got dtype {}",
            dtype_name(&a)
        )));
    }
    let shape = a.shape().to_vec();
    let np = obj.py().import("numpy")?;
    let flat = np
        .call_method1("ascontiguousarray", (&a, "int64"))?
        .call_method1("reshape", (-1,))?;
    let flat = flat.cast::<PyArray1<i64>>()?.readonly();
    let ids = flat.as_slice().expect("ascontiguousarray is contiguous");
    let mut out = Vec::with_capacity(ids.len());
    for (k, &i) in ids.iter().enumerate() {
        match usize::try_from(i) {
            Ok(i) => out.push(i),
            Err(_) => {
                return Err(PyValueError::new_err(format!(
                    "{what}: entry {k} (flat index) is {i}; indices must be >= 0"
                )))
            }
        }
    }
    Ok((out, shape))
}

/// An (m, `N`) integer array as rows of indices (tets: N = 4).
pub fn index_rows<const N: usize>(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[usize; N]>> {
    let (flat, shape) = indices(obj, what)?;
    check_shape(what, &shape, None, N)?;
    Ok(flat.chunks_exact(N).map(|c| std::array::from_fn(|j| c[j])).collect())
}

/// A node selection: a boolean mask of length `n` or a 1-d array/sequence of ids.
pub fn selection(obj: &Bound<'_, PyAny>, what: &str, n: usize) -> PyResult<Vec<usize>> {
    let a = as_ndarray(obj, None)?;
    if a.dtype().kind() == b'b' {
        if a.shape() != [n] {
            return Err(PyValueError::new_err(format!(
                "{what}: a boolean mask must have shape ({n},) (one entry per node), got {:?}",
                a.shape()
            )));
        }
        let mask = obj
            .py()
            .import("numpy")?
            .call_method1("flatnonzero", (&a,))?
            .call_method1("astype", ("int64",))?;
        return Ok(indices(&mask, what)?.0);
    }
    let (ids, shape) = indices(&a, what)?;
    if shape.len() != 1 {
        return Err(PyValueError::new_err(format!(
            "{what}: node ids must be a 1-d array, got shape {shape:?}"
        )));
    }
    Ok(ids)
}

/// A 3-vector from any sequence of three numbers.
pub fn vec3(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec3> {
    let v: Vec<f64> = obj
        .extract()
        .map_err(|_| PyTypeError::new_err(format!("{what} must be a sequence of 3 numbers")))?;
    match v.as_slice() {
        [x, y, z] => Ok(Vec3::new(*x, *y, *z)),
        _ => Err(PyValueError::new_err(format!(
            "{what} must have 3 components, got {}",
            v.len()
        ))),
    }
}

/// A fresh (n, 3) float64 array holding a copy of `v`.
pub fn vec3s_to_py<'py>(py: Python<'py>, v: &[Vec3]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    PyArray1::from_slice(py, as_f64s(v)).reshape([v.len(), 3])
}

/// A fresh zeroed (n, 3) float64 array, and `fill` run on it as `&mut [Vec3]`: the
/// library writes its output straight into the array returned (no copy).
pub fn fill_vec3s<'py, T>(
    py: Python<'py>,
    n: usize,
    fill: impl FnOnce(&mut [Vec3]) -> T,
) -> (Bound<'py, PyArray2<f64>>, T) {
    // Not `PyArray2::zeros`: NumPy takes zeroed memory from calloc, which for
    // arrays over glibc's mmap threshold maps fresh pages on every call and pays a
    // page fault per 4 KiB on first touch (about 5 % of a 100k-tet evaluation).
    // An uninitialised array comes from malloc, which reuses freed memory; it is
    // zeroed here before anything reads it.
    // SAFETY: `new` leaves the elements uninitialised; `write_bytes` zeroes all
    // 3n of them (an all-zero f64 is 0.0) before the array is read or returned.
    let out = unsafe {
        let out = PyArray2::<f64>::new(py, [n, 3], false);
        std::ptr::write_bytes(out.data(), 0, 3 * n);
        out
    };
    let t = {
        let mut rw = out.readwrite();
        let flat = rw.as_slice_mut().expect("a fresh C-order array is contiguous");
        fill(as_vec3s_mut(flat))
    };
    (out, t)
}
