//! `arash._diagnose` and the `_Diagnosis` it returns; `arash.diagnose` (Python) wraps them into the
//! documented `Diagnosis`.

use std::sync::Arc;

use arash_core::diagnose::{
    consistent_with_effects, diagnose as core_diagnose, DiagnoseOptions, Diagnosis as CoreDiagnosis, EffectKind, Log,
};
use arash_core::identify::consistent::ConsistentOptions;
use numpy::PyReadonlyArrayDyn;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::identify::{log_arrays, Identification};
use crate::{to_numpy, value_error, NumpyArray, Robot};

/// What the diagnosis found (the Rust side; see `arash.Diagnosis`).
#[pyclass(module = "arash._arash", frozen)]
pub(crate) struct RawDiagnosis {
    model: Arc<arash_core::Model>,
    inner: CoreDiagnosis,
    consistent: Option<arash_core::identify::Identification>,
}

#[pymethods]
impl RawDiagnosis {
    fn report(&self) -> String {
        self.inner.report()
    }
    fn to_json(&self) -> String {
        self.inner.to_json()
    }
    /// The updated model (declared parameters plus the effects found).
    #[getter]
    fn model(&self) -> Identification {
        Identification::new(Arc::clone(&self.model), self.inner.model.clone())
    }
    /// The physically consistent model fitted together with the effects found (with
    /// `consistent=True`), else None.
    #[getter]
    fn model_consistent(&self) -> Option<Identification> {
        self.consistent.as_ref().map(|c| Identification::new(Arc::clone(&self.model), c.clone()))
    }
    /// The signals behind the residual plots: t (N,), and q, qd, qdd, tau, residual_before,
    /// residual_after (N, dof), and one (N, dof) contribution per accepted effect.
    #[getter]
    fn series<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        let s = &self.inner.series;
        let dof = self.model.dof();
        let d = pyo3::types::PyDict::new(py);
        let table = |v: &[f64]| to_numpy(py, v.to_vec(), false, v.len() / dof.max(1), &[dof]);
        d.set_item("t", to_numpy(py, s.t.clone(), false, s.t.len(), &[])?)?;
        for (name, v) in [
            ("q", &s.q),
            ("qd", &s.qd),
            ("qdd", &s.qdd),
            ("tau", &s.tau),
            ("residual_before", &s.residual_before),
            ("residual_after", &s.residual_after),
        ] {
            d.set_item(name, table(v)?)?;
        }
        let contributions: Vec<NumpyArray<'py>> = s.contributions.iter().map(|c| table(c)).collect::<PyResult<_>>()?;
        d.set_item("contributions", contributions)?;
        Ok(d)
    }
}

/// Diagnose a log against the robot's declared model (see `arash.diagnose`).
#[pyfunction]
#[pyo3(signature = (robot, t, q, tau, *, model=None, validation=None, transmission=None, cutoff_hz=20.0,
                    block_s=2.0, alpha=0.01, min_gain=0.2, effects=None, refit=false,
                    hold_friction=false, consistent=false, consistent_cutoff_hz=None))]
#[allow(clippy::too_many_arguments)]
fn _diagnose<'py>(
    py: Python<'py>,
    robot: &Robot,
    t: PyReadonlyArrayDyn<'py, f64>,
    q: PyReadonlyArrayDyn<'py, f64>,
    tau: PyReadonlyArrayDyn<'py, f64>,
    model: Option<&Identification>,
    validation: Option<(PyReadonlyArrayDyn<'py, f64>, PyReadonlyArrayDyn<'py, f64>, PyReadonlyArrayDyn<'py, f64>)>,
    transmission: Option<Vec<f64>>,
    cutoff_hz: f64,
    block_s: f64,
    alpha: f64,
    min_gain: f64,
    effects: Option<Vec<String>>,
    refit: bool,
    hold_friction: bool,
    consistent: bool,
    consistent_cutoff_hz: Option<f64>,
) -> PyResult<RawDiagnosis> {
    let dof = robot.model.dof();
    let (t, q, tau) = log_arrays(&t, &q, &tau, dof)?;
    let held = validation.as_ref().map(|(vt, vq, vtau)| log_arrays(vt, vq, vtau, dof)).transpose()?;
    if let Some(tr) = &transmission {
        if tr.len() != dof || tr.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(PyValueError::new_err(format!(
                "transmission needs {dof} positive values, one per joint; got {tr:?}"
            )));
        }
    }
    for (name, v) in
        [("cutoff_hz", cutoff_hz), ("block_s", block_s), ("consistent_cutoff_hz", consistent_cutoff_hz.unwrap_or(1.0))]
    {
        if !(v.is_finite() && v > 0.0) {
            return Err(PyValueError::new_err(format!("{name} must be positive, got {v}")));
        }
    }
    let valid = alpha > 0.0 && alpha < 1.0 && (0.0..1.0).contains(&min_gain);
    if !valid {
        return Err(PyValueError::new_err(format!(
            "alpha must lie in (0, 1) and min_gain in [0, 1); got {alpha}, {min_gain}"
        )));
    }
    let effects = match effects {
        None => EffectKind::ALL.to_vec(),
        Some(ids) => ids
            .iter()
            .map(|id| EffectKind::from_id(id).ok_or_else(|| PyValueError::new_err(format!("unknown effect `{id}`"))))
            .collect::<PyResult<_>>()?,
    };
    let options = DiagnoseOptions {
        cutoff_hz,
        block_s,
        alpha,
        min_gain,
        effects,
        transmission,
        refit,
        hold_friction,
        ..Default::default()
    };
    let base = robot.default_base()?;
    let robot_model = Arc::clone(&robot.model);
    let given = model.map(|m| m.inner().clone());
    let (inner, consistent) = py
        .detach(|| {
            let train = Log { t: &t, q: &q, tau: &tau };
            let held = held.as_ref().map(|(t, q, tau)| Log { t, q, tau });
            let inner = core_diagnose(&robot_model, base, &robot.urdf, train, held, given.as_ref(), &options)?;
            let consistent = consistent
                .then(|| {
                    let refit =
                        DiagnoseOptions { cutoff_hz: consistent_cutoff_hz.unwrap_or(cutoff_hz), ..options.clone() };
                    let solver = ConsistentOptions::default();
                    consistent_with_effects(&robot_model, base, train, &inner.model, &refit, &solver)
                })
                .transpose()?;
            Ok::<_, arash_core::diagnose::DiagnoseError>((inner, consistent))
        })
        .map_err(value_error)?;
    Ok(RawDiagnosis { model: robot_model, inner, consistent })
}

pub(crate) fn register(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_class::<RawDiagnosis>()?;
    module.add_function(wrap_pyfunction!(_diagnose, module)?)?;
    Ok(())
}
