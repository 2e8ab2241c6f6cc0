//! `arash.Transmission`: motor-side logs mapped to joint space (arash_core::transmission).

use arash_core::transmission::Transmission as Core;
use numpy::ndarray::{Array2, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::prelude::*;

use crate::convert::{batch, same_length, value_error};

type Array<'py> = Bound<'py, PyArrayDyn<f64>>;

/// How motor angles θ and motor torques τ_m become joint angles and torques: θ = R (q − q₀),
/// τ = Rᵀ τ_m. ``gear_ratios``: motor radians per joint radian, one per joint (negative for a
/// reversed motor). ``coupling``: ``(motor, joint, ratio)`` triples, 1-based, for a motor that
/// another joint turns too (the TX40 wrist: ``(6, 5, 32.0)``). ``offsets``: q₀ (rad). A singular
/// R is refused.
#[pyclass(module = "arash", frozen)]
pub struct Transmission {
    inner: Core,
}

impl Transmission {
    pub(crate) fn core(&self) -> &Core {
        &self.inner
    }
}

#[pymethods]
impl Transmission {
    #[new]
    #[pyo3(signature = (gear_ratios, coupling=None, offsets=None))]
    fn new(
        gear_ratios: Vec<f64>,
        coupling: Option<Vec<(usize, usize, f64)>>,
        offsets: Option<Vec<f64>>,
    ) -> PyResult<Self> {
        let dof = gear_ratios.len();
        let inner =
            Core::new(dof, &gear_ratios, &coupling.unwrap_or_default(), offsets.as_deref()).map_err(value_error)?;
        Ok(Self { inner })
    }

    /// R, motor radians per joint radian, shape (dof, dof).
    #[getter]
    fn matrix<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        let r = self.inner.matrix();
        Array2::from_shape_fn((r.nrows(), r.ncols()), |(i, j)| r[(i, j)]).into_dyn().into_pyarray(py)
    }

    /// ``(q, tau)``, each (N, dof), from motor angles and motor torques, each (N, dof).
    fn to_joints<'py>(
        &self,
        py: Python<'py>,
        theta: PyReadonlyArrayDyn<'py, f64>,
        tau_motor: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<(Array<'py>, Array<'py>)> {
        let dof = self.inner.dof();
        let theta = batch("theta", &theta, dof)?;
        let tau_motor = batch("tau_motor", &tau_motor, dof)?;
        let n = same_length(&[("theta", &theta), ("tau_motor", &tau_motor)])?;
        let (q, tau) = self.inner.to_joints(&theta.values, &tau_motor.values).map_err(value_error)?;
        let shape = if theta.single { vec![dof] } else { vec![n, dof] };
        let array = |x: Vec<f64>| numpy::ndarray::ArrayD::from_shape_vec(IxDyn(&shape), x).map(|a| a.into_pyarray(py));
        Ok((array(q).map_err(value_error)?, array(tau).map_err(value_error)?))
    }

    fn __repr__(&self) -> String {
        format!("Transmission(dof={})", self.inner.dof())
    }
}

pub fn register(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_class::<Transmission>()
}
