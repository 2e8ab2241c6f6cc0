//! Python bindings: `import arash`. Arrays are numpy float64 in SI units; a batch is an `(N, dof)`
//! array (or a single `(dof,)` vector, in which case the batch axis is dropped from the result).
//! Every bad input raises `ValueError` naming the argument; nothing panics across the FFI.
//!
//! - `convert`: numpy in and out, the one converter;
//! - `batching`: evaluation over a batch on all cores;
//! - `robot`: `Robot` and `BaseParameters`;
//! - `filters`: `butter` and `filtfilt`;
//! - `motors`: `SimulatedMotors`, the simulated rig a cycle at a time;
//! - `force`: `external_force`, the momentum observer and the force at a frame over a log;
//! - `haptics`: `fixture_bounds` and `render_fixtures`, the haptic mode's virtual fixtures;
//! - `identify`, `diagnose`, `simulate`, `transmission`: the rest of the API.

// The BLAS and LAPACK that identification's SDP calls under their Fortran names: named here so
// that the crate is linked (arash-core leaves the choice of BLAS to the binary), and exported by
// the extension (tests/python/test_blas_lapack.py calls them).
use arash_blas_lapack as _;
use pyo3::prelude::*;

mod batching;
mod convert;
mod diagnose;
mod filters;
mod force;
mod haptics;
mod identify;
mod motors;
mod robot;
mod simulate;
mod transmission;

#[pymodule]
fn _arash(module: &Bound<'_, PyModule>) -> PyResult<()> {
    identify::register(module)?;
    diagnose::register(module)?;
    simulate::register(module)?;
    transmission::register(module)?;
    module.add_function(wrap_pyfunction!(filters::butter, module)?)?;
    module.add_function(wrap_pyfunction!(filters::filtfilt, module)?)?;
    module.add_function(wrap_pyfunction!(force::external_force, module)?)?;
    module.add_function(wrap_pyfunction!(haptics::fixture_bounds, module)?)?;
    module.add_function(wrap_pyfunction!(haptics::render_fixtures, module)?)?;
    module.add_class::<robot::Robot>()?;
    module.add_class::<robot::BaseParameters>()?;
    module.add_class::<motors::SimulatedMotors>()?;
    module.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
