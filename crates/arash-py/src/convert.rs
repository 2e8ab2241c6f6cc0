//! The one converter between numpy and Rust: arrays in, checked for shape and finiteness with
//! errors that name the argument, and arrays out. Every binding goes through it.

use std::borrow::Cow;

use arash_core::choices::{said, Choice, Concern};
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// A float64 numpy array owned by Python.
pub(crate) type NumpyArray<'py> = Bound<'py, PyArrayDyn<f64>>;

/// A validated batch of vectors, copied row-major into `values` (`n × width`).
pub(crate) struct Batch {
    pub(crate) n: usize,
    pub(crate) single: bool,
    pub(crate) values: Vec<f64>,
}

pub(crate) fn batch(name: &str, array: &PyReadonlyArrayDyn<'_, f64>, width: usize) -> PyResult<Batch> {
    let view = array.as_array();
    let shape = view.shape().to_vec();
    let (n, single) = match shape.as_slice() {
        [w] if *w == width => (1, true),
        [n, w] if *w == width => (*n, false),
        _ => {
            return Err(PyValueError::new_err(format!(
                "{name} must have shape (N, {width}) or ({width},), got {shape:?}"
            )))
        }
    };
    let values = contiguous_copy(&view);
    if let Some(i) = values.iter().position(|x| !x.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{name} is not finite at sample {}, entry {}: {}",
            i / width,
            i % width,
            values[i]
        )));
    }
    Ok(Batch { n, single, values })
}

/// A finite 1-D array of any length.
pub(crate) fn vector(name: &str, array: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<Vec<f64>> {
    let view = array.as_array();
    if view.ndim() != 1 {
        return Err(PyValueError::new_err(format!("{name} must be one-dimensional, got shape {:?}", view.shape())));
    }
    let values = contiguous_copy(&view);
    if let Some(i) = values.iter().position(|x| !x.is_finite()) {
        return Err(PyValueError::new_err(format!("{name} is not finite at sample {i}: {}", values[i])));
    }
    Ok(values)
}

/// The array's values in row-major order: one memory copy when numpy holds them contiguously,
/// element by element otherwise.
pub(crate) fn contiguous_copy(view: &numpy::ndarray::ArrayViewD<'_, f64>) -> Vec<f64> {
    view.as_slice().map_or_else(|| view.iter().copied().collect(), <[f64]>::to_vec)
}

pub(crate) fn same_length(batches: &[(&str, &Batch)]) -> PyResult<usize> {
    let (first_name, first) = batches[0];
    for (name, b) in &batches[1..] {
        if b.n != first.n || b.single != first.single {
            return Err(PyValueError::new_err(format!("{first_name} has {} samples but {name} has {}", first.n, b.n)));
        }
    }
    Ok(first.n)
}

/// The array's values in row-major order, borrowed where numpy holds them so (a 300,000-sample
/// log is 17 MB), copied otherwise. numpy's `as_slice` also accepts Fortran order, whose memory
/// order is not row-major.
pub(crate) fn row_major<'a>(array: &'a PyReadonlyArrayDyn<'_, f64>) -> Cow<'a, [f64]> {
    match array.as_slice() {
        Ok(slice) if array.is_c_contiguous() => Cow::Borrowed(slice),
        _ => Cow::Owned(array.as_array().iter().copied().collect()),
    }
}

/// `values` as a numpy array of shape `(n,) + tail`, or `tail` alone for a single sample.
pub(crate) fn to_numpy<'py>(
    py: Python<'py>,
    values: Vec<f64>,
    single: bool,
    n: usize,
    tail: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let mut shape = if single { vec![] } else { vec![n] };
    shape.extend_from_slice(tail);
    let array = ArrayD::from_shape_vec(IxDyn(&shape), values).map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(array.into_pyarray(py))
}

/// A 1-D numpy copy of `values`.
pub(crate) fn vector_out<'py>(py: Python<'py>, values: &[f64]) -> PyResult<NumpyArray<'py>> {
    to_numpy(py, values.to_vec(), false, values.len(), &[])
}

/// A numpy copy of row-major `values` with `width` columns: shape `(len / width, width)`.
pub(crate) fn matrix_out<'py>(py: Python<'py>, values: &[f64], width: usize) -> PyResult<NumpyArray<'py>> {
    let n = values.len().checked_div(width).unwrap_or(0);
    to_numpy(py, values.to_vec(), false, n, &[width])
}

/// Call `set` on each (key, value) of a front end's options; a key `set` does not know (it
/// returns `false`) is a `TypeError`, as a wrong keyword argument is.
pub(crate) fn each_option(
    options: &Bound<'_, pyo3::types::PyDict>,
    mut set: impl FnMut(&str, &Bound<'_, PyAny>) -> PyResult<bool>,
) -> PyResult<()> {
    for (key, value) in options.iter() {
        let key: String = key.extract()?;
        if !set(&key, &value)? {
            return Err(pyo3::exceptions::PyTypeError::new_err(format!("unexpected option `{key}`")));
        }
    }
    Ok(())
}

pub(crate) fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// Choices or concerns ([`arash_core::choices`]) as Python dicts: each its `code`, its figures
/// and its `text`, as a model file holds them (`said::values`).
pub(crate) fn said_out(py: Python<'_>, values: Vec<serde_json::Value>) -> PyResult<Vec<Bound<'_, PyAny>>> {
    let loads = py.import("json")?.getattr("loads")?;
    values.iter().map(|value| loads.call1((value.to_string(),))).collect()
}

/// Dicts given back from Python as [`said_out`] made them (a repair's, labelled with its log),
/// as JSON values for `said::read`.
pub(crate) fn said_in(value: &Bound<'_, PyAny>) -> PyResult<Vec<serde_json::Value>> {
    let dumps = value.py().import("json")?.getattr("dumps")?;
    let text: String = dumps.call1((value,))?.extract()?;
    serde_json::from_str(&text).map_err(value_error)
}

/// A run's choices and concerns in a settings dict: `reasons` and `warnings` as the sentences a
/// user reads, `choices` and `concerns` as data (`code`, figures, `text`) a program asks.
pub(crate) fn set_said(d: &Bound<'_, pyo3::types::PyDict>, reasons: &[Choice], warnings: &[Concern]) -> PyResult<()> {
    let py = d.py();
    d.set_item("reasons", reasons.iter().map(ToString::to_string).collect::<Vec<_>>())?;
    d.set_item("warnings", warnings.iter().map(ToString::to_string).collect::<Vec<_>>())?;
    d.set_item("choices", said_out(py, said::values(reasons))?)?;
    d.set_item("concerns", said_out(py, said::values(warnings))?)
}

/// Choices given back from Python (a repair's), dicts or plain text.
pub(crate) fn choices_in(value: &Bound<'_, PyAny>) -> PyResult<Vec<Choice>> {
    Ok(said_in(value)?.into_iter().map(said::read).collect())
}
