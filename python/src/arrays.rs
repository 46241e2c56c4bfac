//! numpy arrays in and out: SI values, one row per configuration, sample or target.

use numpy::ndarray::Array2;
use numpy::{AllowTypeChange, IntoPyArray, PyArray2, PyArrayLike1, PyArrayLike2};
use pyo3::prelude::*;

use crate::errors::input_error;

/// A 2-D float64 array handed to Python.
pub type Matrix<'py> = Bound<'py, PyArray2<f64>>;

/// A 1-D array (or sequence) of floats as a vector.
pub fn vector(a: &PyArrayLike1<'_, f64, AllowTypeChange>) -> Vec<f64> {
    a.as_array().iter().copied().collect()
}

/// The argument `what`, a 1-D array (or sequence) of floats, as a vector; anything else (a
/// 2-D array, strings) is an `InputError` naming the argument and the shape it has, with
/// `hint` (where a batch goes instead).
pub fn vector_arg(a: &Bound<'_, PyAny>, what: &str, hint: &str) -> PyResult<Vec<f64>> {
    if let Ok(v) = a.extract::<PyArrayLike1<'_, f64, AllowTypeChange>>() {
        return Ok(vector(&v));
    }
    Err(input_error(
        &format!("{what}: expected a 1-D array of floats, got {}; {hint}", shape_of(a)),
        None,
        None,
        Some(what),
    ))
}

/// The argument `what` as a 2-D array of floats (one row per configuration, target, ...);
/// anything else (a 1-D array, strings) is an `InputError` naming the argument and the shape
/// it has, with `hint`, rather than numpy's bare `TypeError`.
pub fn matrix_arg<'py>(
    a: &Bound<'py, PyAny>,
    what: &str,
    hint: &str,
) -> PyResult<PyArrayLike2<'py, f64, AllowTypeChange>> {
    a.extract().map_err(|_| {
        input_error(
            &format!("{what}: expected a 2-D array of floats, got {}; {hint}", shape_of(a)),
            None,
            None,
            Some(what),
        )
    })
}

/// `shape [32] (1-D)`, or `no array shape` for what numpy cannot shape.
fn shape_of(a: &Bound<'_, PyAny>) -> String {
    a.py()
        .import("numpy")
        .and_then(|np| np.call_method1("shape", (a,)))
        .and_then(|s| s.extract::<Vec<usize>>())
        .map_or_else(
            |_| "no array shape".to_string(),
            |s| format!("shape {s:?} ({}-D)", s.len()),
        )
}

/// A 2-D array (or nested sequence) as rows, checking the row width when `width` is given.
pub fn rows(a: &PyArrayLike2<'_, f64, AllowTypeChange>, what: &str, width: Option<usize>) -> PyResult<Vec<Vec<f64>>> {
    let view = a.as_array();
    if let Some(w) = width
        && view.ncols() != w
    {
        return Err(input_error(
            &format!("{what}: expected {w} columns, got {}", view.ncols()),
            None,
            None,
            Some(what),
        ));
    }
    Ok(view.rows().into_iter().map(|r| r.to_vec()).collect())
}

/// Rows of equal width as an `n × width` array.
pub fn matrix<'py>(py: Python<'py>, rows: &[Vec<f64>], width: usize) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    Array2::from_shape_vec((rows.len(), width), flat)
        .expect("every row has the width")
        .into_pyarray(py)
}

/// 3-vectors as an `n × 3` array.
pub fn points<'py>(py: Python<'py>, v: &[nalgebra::Vector3<f64>]) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = v.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    Array2::from_shape_vec((v.len(), 3), flat)
        .expect("three values per point")
        .into_pyarray(py)
}

/// A parameter covariance handed to Python: the free parameters' names and their matrix.
pub type Covariance<'py> = (Vec<String>, Bound<'py, PyArray2<f64>>);

/// `covariance` as names and an `n × n` array (SI units).
pub fn covariance<'py>(py: Python<'py>, covariance: &armcomp_core::calibrate::ParameterCovariance) -> Covariance<'py> {
    let m = &covariance.matrix;
    let matrix = Array2::from_shape_fn((m.nrows(), m.ncols()), |(r, c)| m[(r, c)]).into_pyarray(py);
    (covariance.names.clone(), matrix)
}
