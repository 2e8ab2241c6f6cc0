//! The zero-phase Butterworth filter that identification uses, for comparison with scipy.

use arash_core::signal::filter::Butterworth;
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::convert::{contiguous_copy, value_error, vector_out, NumpyArray};

/// Butterworth low-pass coefficients `(b, a)`, as `scipy.signal.butter(order, cutoff_hz,
/// fs=sample_rate_hz)`.
#[pyfunction]
#[pyo3(signature = (order, cutoff_hz, sample_rate_hz))]
pub(crate) fn butter<'py>(
    py: Python<'py>,
    order: usize,
    cutoff_hz: f64,
    sample_rate_hz: f64,
) -> PyResult<(NumpyArray<'py>, NumpyArray<'py>)> {
    let filter = Butterworth::lowpass(order, cutoff_hz, sample_rate_hz).map_err(value_error)?;
    let (b, a) = filter.coefficients();
    Ok((vector_out(py, b)?, vector_out(py, a)?))
}

/// Zero-phase Butterworth low-pass of each column of `x` (shape (N,) or (N, k)), as
/// `scipy.signal.filtfilt(*butter(order, cutoff_hz, fs=sample_rate_hz), x, axis=0)`.
#[pyfunction]
#[pyo3(signature = (x, cutoff_hz, sample_rate_hz, order=None))]
pub(crate) fn filtfilt<'py>(
    py: Python<'py>,
    x: PyReadonlyArrayDyn<'py, f64>,
    cutoff_hz: f64,
    sample_rate_hz: f64,
    order: Option<usize>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    // Identification's order unless told otherwise.
    let order = order.unwrap_or(arash_core::identify::PreprocessOptions::default().order);
    let filter = Butterworth::lowpass(order, cutoff_hz, sample_rate_hz).map_err(value_error)?;
    let view = x.as_array();
    let shape = view.shape().to_vec();
    let (n, k) = match shape.as_slice() {
        [n] => (*n, 1),
        [n, k] => (*n, *k),
        _ => return Err(PyValueError::new_err(format!("x must have shape (N,) or (N, k), got {shape:?}"))),
    };
    let values = contiguous_copy(&view);
    if values.iter().any(|v| !v.is_finite()) {
        return Err(PyValueError::new_err("x contains NaN or infinity"));
    }
    let mut out = vec![0.0; n * k];
    filter.filtfilt_rows(&values, k, &mut out).map_err(value_error)?;
    let array = ArrayD::from_shape_vec(IxDyn(&shape), out).map_err(value_error)?;
    Ok(array.into_pyarray(py))
}
