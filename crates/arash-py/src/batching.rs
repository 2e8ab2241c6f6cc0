//! Batched evaluation of the model on numpy arrays: each sample's result written straight into
//! the output array, on all cores for large batches, with the GIL released.

use arash_core::{Data, Model};
use numpy::ndarray::IxDyn;
use numpy::{PyArrayDyn, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::convert::Batch;

/// Per-thread workspace: the model's `Data` and room for one full regressor.
pub(crate) struct Scratch {
    pub(crate) data: Data,
    pub(crate) regressor: Vec<f64>,
}

/// Evaluate `f(scratch, sample, out)` for every sample into a new array of shape `(N,) + tail`,
/// or `tail` for a single sample.
pub(crate) fn batched<'py, F>(
    py: Python<'py>,
    model: &Model,
    count: usize,
    single: bool,
    tail: &[usize],
    f: F,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>>
where
    F: Fn(&mut Scratch, usize, &mut [f64]) + Sync + Send,
{
    let mut shape = if single { vec![] } else { vec![count] };
    shape.extend_from_slice(tail);
    // numpy's zeros come from calloc: fresh pages, zeroed lazily, so this costs no extra pass.
    let array = PyArrayDyn::<f64>::zeros(py, IxDyn(&shape), false);
    fill(py, model, &array, tail.iter().product(), f)?;
    Ok(array)
}

/// Run `f` for every `width`-sized sample of a C-contiguous array, with the GIL released.
pub(crate) fn fill<F>(
    py: Python<'_>,
    model: &Model,
    array: &Bound<'_, PyArrayDyn<f64>>,
    width: usize,
    f: F,
) -> PyResult<()>
where
    F: Fn(&mut Scratch, usize, &mut [f64]) + Sync + Send,
{
    let mut writable = array.try_readwrite().map_err(|e| PyValueError::new_err(format!("out: {e}")))?;
    let slice = writable.as_slice_mut().map_err(|_| PyValueError::new_err("out must be C-contiguous float64"))?;
    py.detach(|| run_batched_into(model, width, slice, f));
    Ok(())
}

/// Evaluate `f(scratch, sample, out)` for every `width`-sized sample of `out`, on all cores when
/// the batch is large.
fn run_batched_into<F>(model: &Model, width: usize, out: &mut [f64], f: F)
where
    F: Fn(&mut Scratch, usize, &mut [f64]) + Sync,
{
    if width == 0 || out.is_empty() {
        return;
    }
    let n = out.len() / width;
    let threads = if n >= 2048 { std::thread::available_parallelism().map_or(1, |t| t.get()) } else { 1 };
    let per_thread = n.div_ceil(threads);
    std::thread::scope(|scope| {
        for (chunk_index, chunk) in out.chunks_mut(per_thread * width).enumerate() {
            let f = &f;
            scope.spawn(move || {
                let mut scratch =
                    Scratch { data: Data::new(model), regressor: vec![0.0; model.dof() * model.num_params()] };
                for (i, sample_out) in chunk.chunks_mut(width).enumerate() {
                    f(&mut scratch, chunk_index * per_thread + i, sample_out);
                }
            });
        }
    });
}

/// Sample `i` of a batch of `width`-sized rows.
pub(crate) fn row(b: &Batch, i: usize, width: usize) -> &[f64] {
    &b.values[i * width..(i + 1) * width]
}
