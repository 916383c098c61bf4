//! NumPy arrays in and out: the checks (dtype → `TypeError`, shape → `ValueError`)
//! and the conversions, in one place so that every function copies (or not) alike.
//!
//! * Positions and other (n, 3) float64 inputs are **viewed without a copy** when
//!   they are C-contiguous, aligned `numpy.float64` arrays; other float64 layouts
//!   (strided, Fortran order, a buffer at an odd offset) are copied once, by NumPy.
//!   An ndarray of another dtype is a `TypeError` (no silent precision change);
//!   nested lists are converted by `numpy.asarray`.
//! * Index arrays (tets, node ids) are converted to the library's integer type: a
//!   copy (they are read once, when a mesh or a system is built).
//! * Outputs are fresh NumPy arrays over buffers the bindings allocated (NumPy keeps
//!   them alive); the forces are written by the library straight into the array
//!   returned.
//! * Every copy made here is reserved first: an allocation that fails raises
//!   `MemoryError` instead of aborting the interpreter.

use heml::Vec3;
use numpy::prelude::*;
use numpy::{PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArray};
use pyo3::exceptions::{PyMemoryError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyAny;

use crate::errors::HemlError;

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

/// An (n, 3) float64 input read in place: the caller's array when it is C-contiguous
/// and aligned, else a C-ordered copy NumPy made once.
pub struct Points<'py>(PyReadonlyArray2<'py, f64>);

impl Points<'_> {
    /// The points as the library's vectors.
    pub fn as_slice(&self) -> &[Vec3] {
        as_vec3s(self.0.as_slice().expect("checked C-contiguous"))
    }

    /// The points copied into a vector the library can own; `MemoryError` when the
    /// copy cannot be allocated (rather than the allocator aborting the process).
    pub fn to_vec(&self, what: &str) -> PyResult<Vec<Vec3>> {
        let src = self.as_slice();
        let mut v = Vec::new();
        reserve(&mut v, src.len(), what)?;
        v.extend_from_slice(src);
        Ok(v)
    }

    /// The NumPy array read (the caller's, or the copy), for the tests' zero-copy check.
    pub fn array_ptr(&self) -> *const pyo3::ffi::PyObject {
        self.0.as_ptr()
    }

    /// Errors (`HemlError`) naming the first node with a non-finite coordinate.
    pub fn check_finite(&self, what: &str) -> PyResult<()> {
        check_finite(what, self.as_slice())
    }
}

/// Whether every value is finite, in one branch-free pass that vectorises: x − x is
/// 0 for a finite x and NaN for NaN and ±∞, and NaN stays NaN through the sums (8
/// independent lanes, so that no reassociation is needed to use SIMD registers).
// x − x is meant: it is what tells a finite x from NaN and ±∞
#[allow(clippy::eq_op)]
fn all_finite(flat: &[f64]) -> bool {
    let mut lanes = [0.0_f64; 8];
    let mut chunks = flat.chunks_exact(8);
    for c in &mut chunks {
        for (l, x) in lanes.iter_mut().zip(c) {
            *l += x - x;
        }
    }
    let rest: f64 = chunks.remainder().iter().map(|x| x - x).sum();
    lanes.iter().sum::<f64>() + rest == 0.0
}

/// The first vector of `v` with a NaN or ∞ component: [`all_finite`] (a fraction
/// of a nanosecond per value: negligible next to a force evaluation), then the
/// search only when something is found.
pub fn first_non_finite(v: &[Vec3]) -> Option<usize> {
    if all_finite(as_f64s(v)) {
        return None;
    }
    v.iter().position(|p| !p.iter().all(|c| c.is_finite()))
}

/// `HemlError` naming the first entry of `v` (a node) with a non-finite coordinate.
pub fn check_finite(what: &str, v: &[Vec3]) -> PyResult<()> {
    match first_non_finite(v) {
        None => Ok(()),
        Some(i) => Err(HemlError::new_err(format!(
            "{what}: node {i} has a non-finite coordinate {:?}",
            v[i].as_slice()
        ))),
    }
}

/// Reserves room for `n` more items in `v`, or raises `MemoryError` naming `what`.
pub fn reserve<T>(v: &mut Vec<T>, n: usize, what: &str) -> PyResult<()> {
    v.try_reserve_exact(n).map_err(|_| {
        let bytes = n.saturating_mul(std::mem::size_of::<T>());
        PyMemoryError::new_err(format!("{what}: cannot allocate {bytes} bytes for {n} entries"))
    })
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
/// it is copied. Its values are not checked: see [`Points::check_finite`].
pub fn points<'py>(obj: &Bound<'py, PyAny>, what: &str, rows: Option<usize>) -> PyResult<Points<'py>> {
    let a = as_ndarray(obj, Some("float64"))?;
    if !a.dtype().is_equiv_to(&numpy::dtype::<f64>(obj.py())) {
        return Err(PyTypeError::new_err(format!(
            "{what} must be a float64 array, got dtype {} (convert with .astype(numpy.float64))",
            dtype_name(&a)
        )));
    }
    check_shape(what, a.shape(), rows, 3)?;
    let typed = a.cast::<PyArray2<f64>>()?;
    // Read in place only a C-contiguous (`as_slice` also accepts Fortran order, whose
    // rows are not contiguous triples) and aligned array: a slice of f64 at an
    // address that is not a multiple of 8 (`numpy.frombuffer` at an odd offset) may
    // not be formed at all. NumPy's copy is C-ordered and aligned. Looking at the
    // address reads nothing.
    if a.is_c_contiguous() && typed.data().cast_const().is_aligned() {
        return Ok(Points(typed.readonly()));
    }
    let copy = a.call_method1("copy", ("C",))?;
    Ok(Points(copy.cast_into::<PyArray2<f64>>()?.readonly()))
}

/// Converts an integer array (any signed or unsigned NumPy integer dtype) to
/// indices, refusing negative entries (the message shows the value as given).
/// Returns the flat indices and the shape. The conversion is a fresh, aligned
/// C-ordered array made by NumPy (`astype` copies), read once.
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
    let mut out = Vec::new();
    reserve(&mut out, a.len(), what)?;
    if kind == b'u' {
        // unsigned: read as u64, so that values above i64::MAX keep their value
        let flat = a.call_method1("astype", ("uint64",))?.call_method1("reshape", (-1,))?;
        let flat = flat.cast_into::<PyArray1<u64>>()?.readonly();
        for (k, &i) in flat.as_slice().expect("astype is contiguous").iter().enumerate() {
            let i = usize::try_from(i).map_err(|_| {
                PyValueError::new_err(format!(
                    "{what}: entry {k} (flat index) is {i}, beyond this platform's indices"
                ))
            })?;
            out.push(i);
        }
    } else {
        let flat = a.call_method1("astype", ("int64",))?.call_method1("reshape", (-1,))?;
        let flat = flat.cast_into::<PyArray1<i64>>()?.readonly();
        for (k, &i) in flat.as_slice().expect("astype is contiguous").iter().enumerate() {
            let i = usize::try_from(i).map_err(|_| {
                PyValueError::new_err(format!("{what}: entry {k} (flat index) is {i}; indices must be >= 0"))
            })?;
            out.push(i);
        }
    }
    Ok((out, shape))
}

/// An (m, `N`) integer array as rows of indices (tets: N = 4).
pub fn index_rows<const N: usize>(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[usize; N]>> {
    let (flat, shape) = indices(obj, what)?;
    check_shape(what, &shape, None, N)?;
    let mut rows = Vec::new();
    reserve(&mut rows, flat.len() / N, what)?;
    rows.extend(flat.chunks_exact(N).map(|c| std::array::from_fn(|j| c[j])));
    Ok(rows)
}

/// A selection of `n` items (`noun`: "node" or "tet"): a boolean mask of length `n`
/// or a 1-d array/sequence of ids. Ids are not checked against `n` here (the
/// library names an id out of range); see [`id_set`] for duplicates.
pub fn selection(obj: &Bound<'_, PyAny>, what: &str, n: usize, noun: &str) -> PyResult<Vec<usize>> {
    let a = as_ndarray(obj, None)?;
    if a.dtype().kind() == b'b' {
        if a.shape() != [n] {
            return Err(PyValueError::new_err(format!(
                "{what}: a boolean mask must have shape ({n},) (one entry per {noun}), got {:?}",
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
            "{what}: {noun} ids must be a 1-d array, got shape {shape:?}"
        )));
    }
    Ok(ids)
}

/// [`selection`] that refuses an id listed twice (`HemlError`, as the library's
/// runtime control does): an integer 0/1 array passed where a mask was meant lists
/// ids 0 and 1 again and again, so the message says how a mask is given.
pub fn id_set(obj: &Bound<'_, PyAny>, what: &str, n: usize, noun: &str) -> PyResult<Vec<usize>> {
    let ids = selection(obj, what, n, noun)?;
    let mut seen = vec![false; n];
    for &i in &ids {
        // ids out of range are left to the library, which names them
        if let Some(s) = seen.get_mut(i) {
            if std::mem::replace(s, true) {
                return Err(HemlError::new_err(format!(
                    "{what}: {noun} {i} is listed twice (integers are taken as {noun} ids; a boolean mask \
                     must have dtype bool, e.g. `x == 0` rather than `(x == 0).astype(int)`)"
                )));
            }
        }
    }
    Ok(ids)
}

/// A non-negative integer argument as `u64`: `ValueError` naming the argument and
/// the value otherwise (rather than PyO3's nameless `OverflowError`).
pub fn non_negative(what: &str, v: i64) -> PyResult<u64> {
    u64::try_from(v).map_err(|_| PyValueError::new_err(format!("{what} must be >= 0, got {v}")))
}

/// Per-item integer tags (region tags: int32) from any sequence or array: integers,
/// or floats with integral values, within the int32 range. `ValueError` naming the
/// first bad entry (`noun` and its index) otherwise; no value is truncated or wrapped.
pub fn int32_tags(obj: &Bound<'_, PyAny>, what: &str, noun: &str, first: usize) -> PyResult<Vec<i32>> {
    let a = as_ndarray(obj, None)?;
    let kind = a.dtype().kind();
    let bad = |k: usize, v: String| {
        PyValueError::new_err(format!(
            "{what}: {noun} {} has tag {v}; tags must be integers in the int32 range [{}, {}]",
            first + k,
            i32::MIN,
            i32::MAX
        ))
    };
    let mut out = Vec::new();
    reserve(&mut out, a.len(), what)?;
    match kind {
        // unsigned read as u64 and signed as i64: every value as given
        b'u' => {
            let flat = a.call_method1("astype", ("uint64",))?.call_method1("reshape", (-1,))?;
            let flat = flat.cast_into::<PyArray1<u64>>()?.readonly();
            for (k, &v) in flat.as_slice().expect("astype is contiguous").iter().enumerate() {
                out.push(i32::try_from(v).map_err(|_| bad(k, v.to_string()))?);
            }
        }
        b'i' => {
            let flat = a.call_method1("astype", ("int64",))?.call_method1("reshape", (-1,))?;
            let flat = flat.cast_into::<PyArray1<i64>>()?.readonly();
            for (k, &v) in flat.as_slice().expect("astype is contiguous").iter().enumerate() {
                out.push(i32::try_from(v).map_err(|_| bad(k, v.to_string()))?);
            }
        }
        b'f' => {
            let flat = a.call_method1("astype", ("float64",))?.call_method1("reshape", (-1,))?;
            let flat = flat.cast_into::<PyArray1<f64>>()?.readonly();
            for (k, &v) in flat.as_slice().expect("astype is contiguous").iter().enumerate() {
                let ok = v.fract() == 0.0 && v >= f64::from(i32::MIN) && v <= f64::from(i32::MAX);
                if !ok {
                    return Err(bad(k, format!("{v:?}")));
                }
                out.push(v as i32);
            }
        }
        _ => {
            return Err(PyTypeError::new_err(format!(
                "{what} must be integers (int32 tags, one per {noun}), got dtype {}",
                dtype_name(&a)
            )))
        }
    }
    Ok(out)
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

/// A buffer of `3n` f64 as a fresh (n, 3) float64 array, without a copy (NumPy
/// keeps the buffer alive).
fn flat_to_py(py: Python<'_>, n: usize, flat: Vec<f64>) -> PyResult<Bound<'_, PyArray2<f64>>> {
    let a = numpy::ndarray::Array2::from_shape_vec((n, 3), flat).map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(PyArray2::from_owned_array(py, a))
}

/// A fresh (n, 3) float64 array holding a copy of `v` (`MemoryError` when it cannot
/// be allocated).
pub fn vec3s_to_py<'py>(py: Python<'py>, v: &[Vec3]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let mut flat = Vec::new();
    reserve(&mut flat, 3 * v.len(), "output array")?;
    flat.extend_from_slice(as_f64s(v));
    flat_to_py(py, v.len(), flat)
}

/// A fresh zeroed (n, 3) float64 array, and `fill` run on it as `&mut [Vec3]`: the
/// library writes its output straight into the array returned (no copy).
/// `MemoryError` when it cannot be allocated.
pub fn fill_vec3s<'py, T>(
    py: Python<'py>,
    n: usize,
    fill: impl FnOnce(&mut [Vec3]) -> T,
) -> PyResult<(Bound<'py, PyArray2<f64>>, T)> {
    // Not zeroed memory from calloc (as `vec![0.0; m]` or `numpy.zeros` take), which
    // for arrays over glibc's mmap threshold maps fresh pages on every call and pays
    // a page fault per 4 KiB on first touch (about 5 % of a 100k-tet evaluation):
    // malloc reuses freed memory, zeroed here before anything reads it.
    let mut flat = Vec::new();
    reserve(&mut flat, 3 * n, "output array")?;
    flat.resize(3 * n, 0.0);
    let t = fill(as_vec3s_mut(&mut flat));
    Ok((flat_to_py(py, n, flat)?, t))
}
