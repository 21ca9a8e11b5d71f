//! numpy arrays in and out: what laspy, Open3D and PDAL hand out (float32 or float64, C or
//! Fortran order, views) in, float64 and int64 arrays out.

use numpy::ndarray::Ix2;
use numpy::{AllowTypeChange, PyArray1, PyArrayLikeDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;

use crate::errors::bad_value;

/// Rows of three coordinates, and whether the caller gave one bare `(3,)` row.
pub struct Rows {
    pub rows: Vec<[f64; 3]>,
    pub single: bool,
}

/// The `(N, 3)` array (or anything numpy turns into one) `obj` as f64 rows; with `single`, a
/// `(3,)` array is taken as one row. float32 widens to float64 exactly, so a float32 cloud
/// maps as its float64 copy would.
pub fn rows(obj: &Bound<'_, PyAny>, what: &str, single: bool) -> PyResult<Rows> {
    let array: PyArrayLikeDyn<'_, f64, AllowTypeChange> = obj.extract().map_err(|e| {
        PyTypeError::new_err(format!(
            "{what}: expected an (N, 3) array of numbers, as numpy.asarray would make: {e}"
        ))
    })?;
    let shape = array.shape().to_vec();
    let view = array.as_array();
    if single && shape == [3] {
        let row = [view[[0]], view[[1]], view[[2]]];
        return Ok(Rows {
            rows: vec![row],
            single: true,
        });
    }
    let view = match (shape.as_slice(), view.into_dimensionality::<Ix2>()) {
        ([_, 3], Ok(v)) => v,
        _ => {
            return Err(bad_value(
                what,
                format!("expected an (N, 3) array, got shape {shape:?}"),
            ));
        }
    };
    let rows = view
        .outer_iter()
        .map(|r| [r[0], r[1], r[2]])
        .collect::<Vec<_>>();
    Ok(Rows {
        rows,
        single: false,
    })
}

/// Rows that must all be finite (query points, ray origins and directions): `what` and the
/// first bad row in the error.
pub fn finite_rows(obj: &Bound<'_, PyAny>, what: &str, single: bool) -> PyResult<Rows> {
    let rows = rows(obj, what, single)?;
    if let Some(i) = rows
        .rows
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(bad_value(
            what,
            format!(
                "row {i} is {:?}; every coordinate must be finite",
                rows.rows[i]
            ),
        ));
    }
    Ok(rows)
}

/// An `(N, C)` float64 array of `rows` of `C` values.
pub fn array_n<'py, const C: usize>(
    py: Python<'py>,
    rows: &[[f64; C]],
) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([rows.len(), C])?
        .into_any())
}

/// A 1-D array of `values`.
pub fn array1<'py, T: numpy::Element>(py: Python<'py>, values: Vec<T>) -> Bound<'py, PyAny> {
    PyArray1::from_vec(py, values).into_any()
}

/// A 3x3 matrix of finite numbers (a rotation).
pub fn matrix3(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[[f64; 3]; 3]> {
    let Rows { rows, .. } = finite_rows(obj, what, false)?;
    match rows.as_slice() {
        [a, b, c] => Ok([*a, *b, *c]),
        _ => Err(bad_value(
            what,
            format!("expected a 3x3 matrix, got {} rows", rows.len()),
        )),
    }
}
