//! numpy arrays in and out: any array-like argument as `float64`, checked for its shape.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArrayDyn};
use pyo3::prelude::*;

use crate::errors::argument;

/// `value` as a `float64` array (`numpy.asarray`).
fn as_f64<'py>(value: &Bound<'py, PyAny>) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    let np = value.py().import("numpy")?;
    let array = np.call_method1("asarray", (value, "float64"))?;
    array.extract::<PyReadonlyArrayDyn<'py, f64>>()
}

/// A one-dimensional argument.
pub fn vector(value: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f64>> {
    let array = as_f64(value)?;
    let view = array.as_array();
    if view.ndim() != 1 {
        return Err(argument(format!(
            "{name}: expected a one-dimensional array, got shape {:?}",
            view.shape()
        )));
    }
    Ok(view.iter().copied().collect())
}

/// A two-dimensional argument of `columns` columns, by column.
pub fn matrix(
    value: &Bound<'_, PyAny>,
    name: &str,
    columns: Option<usize>,
) -> PyResult<Vec<Vec<f64>>> {
    let array = as_f64(value)?;
    let view = array.as_array();
    let shape = view.shape();
    let width_ok = columns.is_none_or(|c| shape.get(1) == Some(&c));
    if view.ndim() != 2 || !width_ok {
        let want = columns.map_or("N, M".to_owned(), |c| format!("N, {c}"));
        return Err(argument(format!(
            "{name}: expected an array of shape ({want}), got shape {shape:?}"
        )));
    }
    Ok((0..shape[1])
        .map(|j| (0..shape[0]).map(|i| view[[i, j]]).collect())
        .collect())
}

/// Columns (each of `rows` values) as a `(rows, columns)` array.
pub fn from_columns<'py>(
    py: Python<'py>,
    columns: &[Vec<f64>],
    rows: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let mut flat = Vec::with_capacity(rows * columns.len());
    for i in 0..rows {
        flat.extend(
            columns
                .iter()
                .map(|c| c.get(i).copied().unwrap_or(f64::NAN)),
        );
    }
    let array =
        Array2::from_shape_vec((rows, columns.len()), flat).map_err(|e| argument(e.to_string()))?;
    Ok(array.into_pyarray(py))
}

/// A vector as a one-dimensional array.
pub fn from_vec(py: Python<'_>, values: Vec<f64>) -> Bound<'_, PyArray1<f64>> {
    values.into_pyarray(py)
}
