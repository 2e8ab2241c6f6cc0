//! `arash.identify`, `Identification`, `arash.load_model`, `arash.consistent_least_squares` and
//! the paper's validation trajectory.

use std::borrow::Cow;
use std::sync::Arc;

use arash_core::base_parameters::BaseParameters as CoreBase;
use arash_core::consistent::identify_consistent;
use arash_core::control::trajectory::paper_validation_state;
use arash_core::identify::closed_loop::{ClosedLoop, LoggedController};
use arash_core::identify::drive_gains::{Calibration, GainEstimator, KnownLoad};
use arash_core::identify::{
    cross_validate, held_out_residual, identify as core_identify, identify_in_closed_loop, identify_with_known_load,
    Declared, IdentifyOptions, Log,
};
use arash_core::identify::{ConsistentOptions, ExcitationOptions, PreprocessOptions};
use arash_core::model_file::{IdentifyMethod, ModelFile as CoreIdentification};
use arash_core::signal::repair::{repair, Signal};
use arash_core::Model;
use faer::Mat;
use numpy::{PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{
    batch, matrix_out, row_major, same_length, to_numpy, value_error, vector, vector_out, Batch, NumpyArray,
};
use crate::robot::{BaseParameters, Robot};

/// A log's arrays, borrowed from numpy where they are contiguous (a 300,000-sample log is 17 MB).
pub(crate) type LogArrays<'a> = (Cow<'a, [f64]>, Cow<'a, [f64]>, Cow<'a, [f64]>);

/// Log arrays checked for shape: t (N,), q and tau (N, dof). Finiteness and uniform time are
/// checked by the core's `validate_log`, which names the array and the sample.
pub(crate) fn log_arrays<'a>(
    t: &'a PyReadonlyArrayDyn<'_, f64>,
    q: &'a PyReadonlyArrayDyn<'_, f64>,
    tau: &'a PyReadonlyArrayDyn<'_, f64>,
    dof: usize,
) -> PyResult<LogArrays<'a>> {
    if t.ndim() != 1 {
        return Err(PyValueError::new_err(format!("t must be one-dimensional, got shape {:?}", t.shape())));
    }
    for (name, array) in [("q", q), ("tau", tau)] {
        if array.ndim() != 2 || array.shape()[1] != dof {
            return Err(PyValueError::new_err(format!("{name} must have shape (N, {dof}), got {:?}", array.shape())));
        }
    }
    let n = t.len();
    let (nq, ntau) = (q.shape()[0], tau.shape()[0]);
    if nq != n || ntau != n {
        return Err(PyValueError::new_err(format!("t has {n} samples, q has {nq} and tau has {ntau}")));
    }
    Ok((row_major(t), row_major(q), row_major(tau)))
}

/// An identified model. Arrays are numpy; `params` is None unless the method was "consistent".
#[pyclass(module = "arash._arash", frozen)]
pub(crate) struct Identification {
    model: Arc<Model>,
    inner: CoreIdentification,
}

impl Identification {
    /// `model` carries the Coulomb laws `inner` was fitted with (chosen from the data where the
    /// robot declared none), which its predictions and base must share.
    pub(crate) fn new(model: Arc<Model>, inner: CoreIdentification) -> Self {
        let model = match inner.with_its_law(&model) {
            std::borrow::Cow::Borrowed(_) => model,
            std::borrow::Cow::Owned(with_law) => Arc::new(with_law),
        };
        Self { model, inner }
    }

    pub(crate) fn inner(&self) -> &CoreIdentification {
        &self.inner
    }
}

#[pymethods]
impl Identification {
    #[getter]
    fn method(&self) -> String {
        self.inner.settings.method.name().to_string()
    }
    #[getter]
    fn beta<'py>(&self, py: Python<'py>) -> PyResult<NumpyArray<'py>> {
        vector_out(py, &self.inner.fitted.beta)
    }
    #[getter]
    fn sigma_percent<'py>(&self, py: Python<'py>) -> PyResult<NumpyArray<'py>> {
        vector_out(py, &self.inner.fitted.sigma_percent)
    }
    /// FP% per joint on the training data.
    #[getter]
    fn fp_percent<'py>(&self, py: Python<'py>) -> PyResult<NumpyArray<'py>> {
        vector_out(py, &self.inner.fitted.training.fp_percent)
    }
    /// FP% per joint of plain OLS on the same data.
    #[getter]
    fn fp_percent_ols<'py>(&self, py: Python<'py>) -> PyResult<NumpyArray<'py>> {
        vector_out(py, &self.inner.fitted.training_ols.fp_percent)
    }
    #[getter]
    fn relative_error<'py>(&self, py: Python<'py>) -> PyResult<NumpyArray<'py>> {
        vector_out(py, &self.inner.fitted.training.relative_error)
    }
    #[getter]
    fn rms<'py>(&self, py: Python<'py>) -> PyResult<NumpyArray<'py>> {
        vector_out(py, &self.inner.fitted.training.rms)
    }
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Option<NumpyArray<'py>>> {
        self.inner.fitted.params.as_ref().map(|p| vector_out(py, p)).transpose()
    }
    #[getter]
    fn min_pseudo_inertia_eigenvalue<'py>(&self, py: Python<'py>) -> PyResult<NumpyArray<'py>> {
        vector_out(py, &self.inner.fitted.min_pseudo_inertia_eigenvalue)
    }
    #[getter]
    fn cutoff_hz(&self) -> f64 {
        self.inner.settings.cutoff_hz
    }
    /// The preprocessing as used: periods averaged (None: not periodic), period_s, cutoff_hz,
    /// friction_cutoff_hz, order, decimate, and `reasons` (one line per choice: the user's, or
    /// what in the data made it) and `warnings` (choices the data support only weakly), with
    /// `choices` and `concerns` the same as data: dicts with a `code`, its figures and `text`.
    #[getter]
    fn settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.inner.settings;
        let d = PyDict::new(py);
        d.set_item("method", s.method.name())?;
        d.set_item("periods", s.periods)?;
        d.set_item("period_s", s.period_s)?;
        d.set_item("cutoff_hz", s.cutoff_hz)?;
        d.set_item("friction_cutoff_hz", s.friction_cutoff_hz)?;
        d.set_item("order", s.order)?;
        d.set_item("decimate", s.decimate)?;
        crate::convert::set_said(&d, &s.reasons, &s.warnings)?;
        Ok(d)
    }
    #[getter]
    fn condition_number(&self) -> f64 {
        self.inner.fitted.condition_number
    }
    /// The drive gains of a model identified from currents with a known load: "gains" and
    /// "sigma" (per joint, N·m/A or N/A), "covariance" (joints × joints, None in a file written
    /// before it was kept), "load_body", "load_mass", "load_estimate" (the load's
    /// unknowns estimated with them: name, value, σ), "condition_number", and per joint
    /// "load_share" (the load's share of its torque), "load_over_unexplained" (the load's torque
    /// over what the model leaves) and "fixed" (whether the load fixes the gain). None otherwise.
    #[getter]
    fn drive_gains<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(g) = &self.inner.drive_gains else { return Ok(None) };
        let d = PyDict::new(py);
        d.set_item("gains", vector_out(py, &g.gains)?)?;
        d.set_item("sigma", vector_out(py, &g.sigma)?)?;
        d.set_item("estimator", g.estimator.id())?;
        let dof = g.gains.len();
        let covariance = match g.covariance.is_empty() {
            true => None,
            false => Some(to_numpy(py, g.covariance.clone(), false, dof, &[dof])?),
        };
        d.set_item("covariance", covariance)?;
        d.set_item("load_body", &g.load_body)?;
        d.set_item("load_mass", g.load_mass)?;
        d.set_item("load_estimate", g.load_estimate.clone())?;
        d.set_item("condition_number", g.condition_number)?;
        d.set_item("load_share", vector_out(py, &g.load_share)?)?;
        d.set_item("load_over_unexplained", vector_out(py, &g.load_over_unexplained)?)?;
        d.set_item("fixed", g.fixed.clone())?;
        d.set_item("from_datasheet", g.from_datasheet.clone())?;
        Ok(Some(d))
    }
    /// What sets each σ% besides the noise, per base parameter: "apart" (the part of its unit
    /// column outside the others' span, 1/√VIF), "leans_on" (the index of the one it leans on
    /// most, or None), "column_over_torque" (its column's norm over the torque's on its largest
    /// joint), "torque_share" (that times the |β| whose σ% is reported) and "cause" (why a σ% is
    /// above 10 %, else None). None for a model file written without them.
    #[getter]
    fn determination<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let m = &self.inner;
        let Some(causes) = m.causes() else { return Ok(None) };
        let d = PyDict::new(py);
        let apart: Vec<f64> = m.fitted.determination.iter().map(|x| x.apart).collect();
        let column: Vec<f64> = m.fitted.determination.iter().map(|x| x.column_over_torque).collect();
        d.set_item("apart", vector_out(py, &apart)?)?;
        d.set_item("leans_on", m.fitted.determination.iter().map(|x| x.leans_on).collect::<Vec<_>>())?;
        d.set_item("column_over_torque", vector_out(py, &column)?)?;
        let share: Vec<f64> = m.fitted.determination.iter().map(|x| x.torque_share).collect();
        d.set_item("torque_share", vector_out(py, &share)?)?;
        d.set_item("cause", causes)?;
        Ok(Some(d))
    }
    /// The base parameters the β refer to.
    #[getter]
    fn base(&self) -> PyResult<BaseParameters> {
        let base = CoreBase::with_independent(&self.model, &self.inner.base_independent)
            .map_err(value_error)?
            .ok_or_else(|| PyValueError::new_err("the model's base parameters are not its robot's"))?;
        Ok(BaseParameters { model: Arc::clone(&self.model), base })
    }
    /// The robot the model belongs to.
    #[getter]
    fn robot(&self) -> PyResult<Robot> {
        Robot::of_file(&self.inner)
    }

    /// Predicted torques for (N, dof) states.
    fn predict<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        qd: PyReadonlyArrayDyn<'py, f64>,
        qdd: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<NumpyArray<'py>> {
        let n = self.model.dof();
        let (q, qd, qdd) = (batch("q", &q, n)?, batch("qd", &qd, n)?, batch("qdd", &qdd, n)?);
        let count = same_length(&[("q", &q), ("qd", &qd), ("qdd", &qdd)])?;
        let out = py.detach(|| self.inner.predict(&self.model, &q.values, &qd.values, &qdd.values));
        to_numpy(py, out, q.single, count, &[n])
    }

    /// FP%, relative error and RMS per joint on another log, preprocessed like the training data,
    /// of the declared part (`arash.heldout_errors` scores the effects a diagnosis added too).
    #[pyo3(signature = (t, q, tau, *, periods=None))]
    fn validate<'py>(
        &self,
        py: Python<'py>,
        t: PyReadonlyArrayDyn<'py, f64>,
        q: PyReadonlyArrayDyn<'py, f64>,
        tau: PyReadonlyArrayDyn<'py, f64>,
        periods: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (t, q, tau) = log_arrays(&t, &q, &tau, self.model.dof())?;
        let options = PreprocessOptions { periods, order: self.inner.settings.order, ..Default::default() };
        let v = py.detach(|| cross_validate(&self.model, &self.inner, &t, &q, &tau, &options)).map_err(value_error)?;
        let (m, dof) = (v.metrics, self.model.dof());
        let dict = PyDict::new(py);
        dict.set_item("cutoff_hz", v.cutoff_hz)?;
        dict.set_item("reasons", v.reasons.iter().map(ToString::to_string).collect::<Vec<_>>())?;
        dict.set_item("choices", crate::convert::said_out(py, arash_core::choices::said::values(&v.reasons))?)?;
        dict.set_item("fp_percent", to_numpy(py, m.fp_percent, false, dof, &[])?)?;
        dict.set_item("rel", to_numpy(py, m.relative_error, false, dof, &[])?)?;
        dict.set_item("rms", to_numpy(py, m.rms, false, dof, &[])?)?;
        Ok(dict)
    }

    /// The model's residual on data it was not fitted on, as its file records it: "rms" per
    /// joint (N·m or N), "samples", "cutoff_hz", "source" and "observer" (None, or the force
    /// observer run hand-free on the held-out runs: "bandwidth_hz" and "sigma" per joint, the
    /// force estimate's defaults, "grid_hz", "grid_sigma" (grid × dof), "reason" and "peak",
    /// the largest hand-free estimate, which the collision threshold keeps above); None when
    /// the file records none (`with_held_out` records it; a diagnosis records the residual).
    #[getter]
    fn held_out<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(h) = &self.inner.held_out else { return Ok(None) };
        let d = PyDict::new(py);
        d.set_item("rms", vector_out(py, &h.rms)?)?;
        d.set_item("samples", h.samples)?;
        d.set_item("cutoff_hz", h.cutoff_hz)?;
        d.set_item("source", &h.source)?;
        match &h.observer {
            None => d.set_item("observer", py.None())?,
            Some(o) => {
                let od = PyDict::new(py);
                od.set_item("bandwidth_hz", vector_out(py, &o.bandwidth_hz)?)?;
                od.set_item("sigma", vector_out(py, &o.sigma)?)?;
                od.set_item("grid_hz", vector_out(py, &o.grid_hz)?)?;
                od.set_item("grid_sigma", matrix_out(py, &o.grid_sigma, self.model.dof())?)?;
                od.set_item("reason", o.reason.to_string())?;
                let choice = arash_core::choices::said::values(std::slice::from_ref(&o.reason));
                od.set_item("choice", crate::convert::said_out(py, choice)?.pop())?;
                od.set_item("peak", vector_out(py, &o.peak)?)?;
                d.set_item("observer", od)?;
            }
        }
        Ok(Some(d))
    }

    /// The same model with its residual on the held-out `runs` recorded (each a tuple `(t, q,
    /// tau)`, as for `validate`): per joint, the RMS over all their samples, in the model's band,
    /// no periods averaged (a model with a diagnosis's effects keeps the diagnosis's), and the
    /// force observer run hand-free on them, which sets a force estimate's bandwidth and σ
    /// (`torque`: how the runs' torque acted between samples, as for `external_force`).
    #[pyo3(signature = (runs, *, torque="sampled"))]
    fn with_held_out(&self, py: Python<'_>, runs: Vec<Bound<'_, PyAny>>, torque: &str) -> PyResult<Identification> {
        let timing = crate::force::torque_timing(torque)?;
        if runs.is_empty() {
            return Err(PyValueError::new_err("runs is empty: give at least one (t, q, tau) held out from the fit"));
        }
        let mut arrays = Vec::with_capacity(runs.len());
        for (i, run) in runs.iter().enumerate() {
            let (t, q, tau) = run
                .extract::<(PyReadonlyArrayDyn<'_, f64>, PyReadonlyArrayDyn<'_, f64>, PyReadonlyArrayDyn<'_, f64>)>()
                .map_err(|_| PyValueError::new_err(format!("runs[{i}] is not a tuple (t, q, tau) of arrays")))?;
            arrays.push((t, q, tau));
        }
        let mut logs = Vec::with_capacity(arrays.len());
        for (t, q, tau) in &arrays {
            logs.push(log_arrays(t, q, tau, self.model.dof())?);
        }
        let names: Vec<String> = (0..logs.len()).map(|i| format!("runs[{i}]")).collect();
        let runs: Vec<(&str, Log)> =
            names.iter().zip(&logs).map(|(name, (t, q, tau))| (name.as_str(), Log { t, q, tau })).collect();
        let order = self.inner.settings.order;
        // A diagnosis's model keeps the residual its diagnosis measured (its effects are judged
        // there); the observer is run on it like on any other.
        let diagnosed = self.inner.held_out.clone().filter(|_| !self.inner.effects.is_empty());
        let held_out = py
            .detach(|| -> Result<_, String> {
                let mut h = match diagnosed {
                    Some(h) => h,
                    None => held_out_residual(&self.model, &self.inner, &runs, order).map_err(|e| e.to_string())?,
                };
                h.observer = Some(
                    arash_core::force_log::observer_held_out(&self.model, &self.inner, &runs, timing)
                        .map_err(|e| e.to_string())?,
                );
                Ok(h)
            })
            .map_err(PyValueError::new_err)?;
        let mut inner = self.inner.clone();
        inner.held_out = Some(held_out);
        Ok(Identification::new(Arc::clone(&self.model), inner))
    }

    /// The same model without the effects a diagnosis added (`which`: the indices of those to
    /// drop, in the file's order; default all, which leaves the declared part alone).
    #[pyo3(signature = (which=None))]
    fn without_effects(&self, which: Option<Vec<usize>>) -> PyResult<Identification> {
        let mut inner = self.inner.clone();
        let count = inner.effects.len();
        let drop = which.unwrap_or_else(|| (0..count).collect());
        if let Some(bad) = drop.iter().find(|&&i| i >= count) {
            return Err(PyValueError::new_err(format!("which: effect {bad} does not exist (the model has {count})")));
        }
        inner.effects =
            inner.effects.into_iter().enumerate().filter(|(i, _)| !drop.contains(i)).map(|(_, e)| e).collect();
        Ok(Identification::new(Arc::clone(&self.model), inner))
    }

    /// Text table in the shape of the paper's Table I.
    fn table(&self) -> String {
        self.inner.table()
    }

    fn to_json(&self) -> String {
        self.inner.to_json()
    }

    /// Write the model file (JSON, with the URDF embedded).
    fn save(&self, path: std::path::PathBuf) -> PyResult<()> {
        self.inner.save(&path).map_err(|e| PyValueError::new_err(format!("cannot write {}: {e}", path.display())))
    }

    fn __repr__(&self) -> String {
        format!(
            "Identification(method='{}', p={}, fp_percent={:?})",
            self.method(),
            self.inner.fitted.beta.len(),
            self.inner.fitted.training.fp_percent.iter().map(|v| (v * 100.0).round() / 100.0).collect::<Vec<_>>()
        )
    }
}

/// Identify the robot's parameters from the log `(t, q, tau)` (see `arash.identify`): `options`
/// holds only what the caller set; the rest are `arash_core`'s defaults.
#[pyfunction]
#[pyo3(signature = (robot, log, method, options))]
fn _identify<'py>(
    py: Python<'py>,
    robot: &Robot,
    log: (PyReadonlyArrayDyn<'py, f64>, PyReadonlyArrayDyn<'py, f64>, PyReadonlyArrayDyn<'py, f64>),
    method: Option<&str>,
    options: &Bound<'py, PyDict>,
) -> PyResult<Identification> {
    let method: IdentifyMethod =
        method.map_or(Ok(IdentifyMethod::default()), str::parse).map_err(PyValueError::new_err)?;
    let mut o = IdentifyOptions::default();
    let dof = robot.model.dof();
    let mut reference: Option<[Batch; 3]> = None;
    let mut controller: Option<String> = None;
    let mut keep_weak = false;
    let mut repair_report = Vec::new();
    crate::convert::each_option(options, |key, value| {
        match key {
            "keep_weak" => keep_weak = value.extract()?,
            "repair_report" => repair_report = crate::convert::choices_in(value)?,
            "reference" => {
                let (a, b, c): (PyReadonlyArrayDyn<f64>, PyReadonlyArrayDyn<f64>, PyReadonlyArrayDyn<f64>) =
                    value.extract()?;
                reference = Some([batch("q_des", &a, dof)?, batch("qd_des", &b, dof)?, batch("qdd_des", &c, dof)?]);
            }
            "controller" => controller = Some(value.extract()?),
            "iv_iterations" => o.iv.max_iterations = value.extract()?,
            "iv_tolerance" => o.iv.tolerance = value.extract()?,
            "stiffness_bounds" => o.consistent.stiffness_bounds = value.extract()?,
            _ => return fit_option(&mut o, key, value),
        }
        Ok(true)
    })?;
    check_settings(&o)?;
    let (t, q, tau) = log_arrays(&log.0, &log.1, &log.2, robot.model.dof())?;
    let model = Arc::clone(&robot.model);
    let base = robot.fitted_base(keep_weak)?;
    let declared = Declared { model: &model, base, urdf: &robot.urdf };
    let log = Log { t: &t, q: &q, tau: &tau };
    let inner = match closed_loop_arrays(reference, controller.as_deref(), model.dof(), t.len())? {
        Some((reference, controller)) => {
            let closed_loop = ClosedLoop::new(&reference, &controller);
            py.detach(|| identify_in_closed_loop(declared, log, closed_loop, method, &o))
        }
        None => py.detach(|| core_identify(declared, log, method, &o)),
    }
    .map_err(value_error)?;
    let mut inner = inner;
    inner.settings.reasons.splice(0..0, repair_report);
    Ok(Identification::new(model, inner))
}

/// The preprocessing and pull options both identifications take, set from the Python option
/// `key`; `false` for a key that is not one of them.
fn fit_option(o: &mut IdentifyOptions, key: &str, value: &Bound<'_, PyAny>) -> PyResult<bool> {
    match key {
        "periods" => o.preprocess.periods = value.extract()?,
        "period_s" => o.preprocess.period_s = value.extract()?,
        "cutoff_hz" => o.preprocess.cutoff_hz = value.extract()?,
        "order" => o.preprocess.order = value.extract()?,
        "decimate" => o.preprocess.decimate = value.extract()?,
        "friction_cutoff_hz" => o.preprocess.friction_cutoff_hz = value.extract()?,
        "pull" => o.consistent.pull = value.extract()?,
        _ => return Ok(false),
    }
    Ok(true)
}

/// The settings checked by their own `validate` before any work, so that a bad one raises
/// `ValueError` naming it, as the CLI's message does.
fn check_settings(o: &IdentifyOptions) -> PyResult<()> {
    o.preprocess.validate().and(o.consistent.validate()).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// A run of currents: `(t, q, i, loaded)`.
type CurrentRun<'py> = (PyReadonlyArrayDyn<'py, f64>, PyReadonlyArrayDyn<'py, f64>, PyReadonlyArrayDyn<'py, f64>, bool);

/// Identify from motor currents with a known load (see `arash.identify`'s `loaded`): `runs` are
/// `(t, q, i, loaded)`, `load` the known load's body, mass and, where known, centre of mass and
/// inertia about it; `gains` the datasheet's `(k, σ)` per joint and the gains fit, each or None.
#[pyfunction]
#[pyo3(signature = (robot, runs, load, method, options, gains))]
fn _identify_with_load<'py>(
    py: Python<'py>,
    robot: &Robot,
    runs: Vec<CurrentRun<'py>>,
    load: (String, f64, Option<[f64; 3]>, Option<[f64; 6]>),
    method: Option<&str>,
    options: &Bound<'py, PyDict>,
    gains: (Option<Vec<(f64, f64)>>, Option<String>),
) -> PyResult<Identification> {
    let (datasheet, gains_fit) = gains;
    let estimator: GainEstimator =
        gains_fit.as_deref().map_or(Ok(GainEstimator::default()), str::parse).map_err(PyValueError::new_err)?;
    let method: IdentifyMethod =
        method.map_or(Ok(IdentifyMethod::default()), str::parse).map_err(PyValueError::new_err)?;
    let mut o = IdentifyOptions::default();
    crate::convert::each_option(options, |key, value| fit_option(&mut o, key, value))?;
    check_settings(&o)?;
    let dof = robot.model.dof();
    let arrays = runs
        .iter()
        .enumerate()
        .map(|(k, (t, q, i, _))| {
            log_arrays(t, q, i, dof).map_err(|e| PyValueError::new_err(format!("run {k}: {}", e.value(py))))
        })
        .collect::<PyResult<Vec<_>>>()?;
    let logs: Vec<(Log, bool)> = arrays.iter().zip(&runs).map(|((t, q, i), r)| (Log { t, q, tau: i }, r.3)).collect();
    let (body, mass, com, inertia) = load;
    let load = KnownLoad { body, mass, com, inertia };
    let model = Arc::clone(&robot.model);
    let base = robot.fitted_base(false)?;
    let declared = Declared { model: &model, base, urdf: &robot.urdf };
    let calibration = Calibration { load: &load, datasheet: datasheet.as_deref(), estimator };
    let (inner, _) =
        py.detach(|| identify_with_known_load(declared, &logs, calibration, method, &o)).map_err(value_error)?;
    Ok(Identification::new(model, inner))
}

/// Repair a log (see `arash.repair_log`): `t` (N,) and `signals`, each (N, width) or (N,).
/// Returns `(t, signals, report)`, every signal in its input's shape.
#[pyfunction]
fn _repair_log<'py>(
    py: Python<'py>,
    t: PyReadonlyArrayDyn<'py, f64>,
    signals: Vec<(String, PyReadonlyArrayDyn<'py, f64>)>,
) -> PyResult<(NumpyArray<'py>, Vec<NumpyArray<'py>>, Vec<Bound<'py, PyAny>>)> {
    if t.ndim() != 1 {
        return Err(PyValueError::new_err(format!("t must be one-dimensional, got shape {:?}", t.shape())));
    }
    let n = t.len();
    let mut arrays = Vec::with_capacity(signals.len());
    for (name, array) in &signals {
        let width = match array.shape() {
            [rows] if *rows == n => 1,
            [rows, width] if *rows == n => *width,
            shape => {
                return Err(PyValueError::new_err(format!("{name} must have {n} rows, as t has, got shape {shape:?}")))
            }
        };
        arrays.push((name.as_str(), array.as_array().iter().copied().collect::<Vec<f64>>(), width));
    }
    let t_in: Vec<f64> = t.as_array().iter().copied().collect();
    let borrowed: Vec<Signal> = arrays.iter().map(|(name, v, w)| (*name, v.as_slice(), *w)).collect();
    let repaired = repair(&t_in, &borrowed).map_err(value_error)?;
    let out = repaired
        .signals
        .iter()
        .zip(&signals)
        .map(|(values, (_, array))| {
            let rows = repaired.t.len();
            let tail: Vec<usize> = array.shape()[1..].to_vec();
            to_numpy(py, values.clone(), false, rows, &tail)
        })
        .collect::<PyResult<Vec<_>>>()?;
    let report = crate::convert::said_out(py, arash_core::choices::said::values(&repaired.report))?;
    Ok((vector_out(py, &repaired.t)?, out, report))
}

/// The closed loop's reference `(q_des, qd_des, qdd_des)`, each `(N, dof)`, and its controller (JSON),
/// checked: both or neither.
fn closed_loop_arrays(
    reference: Option<[Batch; 3]>,
    controller: Option<&str>,
    dof: usize,
    samples: usize,
) -> PyResult<Option<([Vec<f64>; 3], LoggedController)>> {
    let (reference, controller) = match (reference, controller) {
        (None, None) => return Ok(None),
        (Some(r), Some(c)) => (r, c),
        (Some(_), None) => {
            return Err(PyValueError::new_err(
                "reference was given without controller: idim-iv and didim simulate the loop and need both",
            ))
        }
        (None, Some(_)) => {
            return Err(PyValueError::new_err(
                "controller was given without reference (q_des, qd_des, qdd_des): idim-iv and didim simulate the \
                 loop and need both",
            ))
        }
    };
    let controller = LoggedController::from_json(controller).map_err(value_error)?;
    for (name, b) in ["q_des", "qd_des", "qdd_des"].into_iter().zip(&reference) {
        if b.single || b.n != samples {
            return Err(PyValueError::new_err(format!(
                "reference {name} must have shape ({samples}, {dof}), one row per sample of the log"
            )));
        }
    }
    Ok(Some((reference.map(|b| b.values), controller)))
}

/// Read a model file written by `Identification.save` or `arash identify`.
#[pyfunction]
fn load_model(path: std::path::PathBuf) -> PyResult<Identification> {
    let text = std::fs::read_to_string(&path)
        .map_err(|e| PyValueError::new_err(format!("cannot read model file {}: {e}", path.display())))?;
    let inner = CoreIdentification::from_json(&text).map_err(value_error)?;
    let robot = Robot::of_file(&inner)?;
    Ok(Identification::new(robot.model, inner))
}

/// The physically consistent least-squares problem on a given stacked full regressor W (m, P)
/// and torque vector tau (m,): returns π.
#[pyfunction]
#[pyo3(signature = (robot, w, tau, *, pull=None, stiffness_bounds=None))]
fn consistent_least_squares<'py>(
    py: Python<'py>,
    robot: &Robot,
    w: PyReadonlyArrayDyn<'py, f64>,
    tau: PyReadonlyArrayDyn<'py, f64>,
    pull: Option<f64>,
    stiffness_bounds: Option<(f64, f64)>,
) -> PyResult<NumpyArray<'py>> {
    let p = robot.model.num_params();
    let w = batch("w", &w, p)?;
    let tau = vector("tau", &tau)?;
    if w.n != tau.len() {
        return Err(PyValueError::new_err(format!("w has {} rows but tau has {}", w.n, tau.len())));
    }
    let mat = Mat::<f64>::from_fn(w.n, p, |i, j| w.values[i * p + j]);
    let defaults = ConsistentOptions::default();
    let options = ConsistentOptions {
        pull: pull.unwrap_or(defaults.pull),
        stiffness_bounds: stiffness_bounds.unwrap_or(defaults.stiffness_bounds),
        ..defaults
    };
    let fit = py.detach(|| identify_consistent(&robot.model, &mat, &tau, &options)).map_err(value_error)?;
    to_numpy(py, fit.params, false, p, &[])
}

/// The paper's validation trajectory at ω (rad/s), sampled at times t: (q, qd, qdd), each (N, 3).
#[pyfunction]
fn paper_validation_trajectory<'py>(
    py: Python<'py>,
    omega: f64,
    t: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<(NumpyArray<'py>, NumpyArray<'py>, NumpyArray<'py>)> {
    let t = vector("t", &t)?;
    let (mut q, mut qd, mut qdd) = (Vec::new(), Vec::new(), Vec::new());
    for &ti in &t {
        let (a, b, c) = paper_validation_state(omega, ti);
        q.extend(a);
        qd.extend(b);
        qdd.extend(c);
    }
    let n = t.len();
    Ok((to_numpy(py, q, false, n, &[3])?, to_numpy(py, qd, false, n, &[3])?, to_numpy(py, qdd, false, n, &[3])?))
}

pub(crate) fn register(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_class::<Identification>()?;
    module.add_class::<Excitation>()?;
    module.add_function(wrap_pyfunction!(_design_excitation, module)?)?;
    module.add_function(wrap_pyfunction!(_identify, module)?)?;
    module.add_function(wrap_pyfunction!(_repair_log, module)?)?;
    module.add_function(wrap_pyfunction!(_identify_with_load, module)?)?;
    module.add_function(wrap_pyfunction!(load_model, module)?)?;
    module.add_function(wrap_pyfunction!(consistent_least_squares, module)?)?;
    module.add_function(wrap_pyfunction!(paper_validation_trajectory, module)?)?;
    Ok(())
}

/// A designed excitation trajectory (Fourier coefficients and the condition number achieved).
#[pyclass(module = "arash._arash", frozen)]
pub(crate) struct Excitation {
    inner: arash_core::control::fourier::Excitation,
}

#[pymethods]
impl Excitation {
    #[getter]
    fn condition_number(&self) -> f64 {
        self.inner.condition_number
    }
    /// κ with the weak base parameters kept (equal to `condition_number` when none was regrouped).
    #[getter]
    fn condition_number_with_weak(&self) -> f64 {
        self.inner.condition_number_with_weak
    }
    #[getter]
    fn period_s(&self) -> f64 {
        self.inner.period_s
    }
    #[getter]
    fn harmonics(&self) -> usize {
        self.inner.harmonics
    }
    /// (t, q, qd, qdd) over `periods` periods at `rate_hz`; q and its rates are (N, dof).
    /// `rate_hz` defaults to the rig's control rate.
    #[pyo3(signature = (rate_hz=None, periods=1))]
    fn sample<'py>(
        &self,
        py: Python<'py>,
        rate_hz: Option<f64>,
        periods: usize,
    ) -> PyResult<(NumpyArray<'py>, NumpyArray<'py>, NumpyArray<'py>, NumpyArray<'py>)> {
        let rate_hz = rate_hz.unwrap_or(arash_core::control::fourier::DEFAULT_SAMPLE_RATE_HZ);
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(PyValueError::new_err(format!("rate_hz must be positive, got {rate_hz}")));
        }
        let (t, q, qd, qdd) = self.inner.sample(rate_hz, periods);
        let (n, dof) = (t.len(), self.inner.q0.len());
        Ok((
            to_numpy(py, t, false, n, &[])?,
            to_numpy(py, q, false, n, &[dof])?,
            to_numpy(py, qd, false, n, &[dof])?,
            to_numpy(py, qdd, false, n, &[dof])?,
        ))
    }
    /// The coefficients as JSON.
    fn to_json(&self) -> String {
        serde_json::to_string_pretty(&self.inner).expect("serialisable")
    }
    fn __repr__(&self) -> String {
        format!(
            "Excitation(L={}, T={} s, κ={:.3})",
            self.inner.harmonics, self.inner.period_s, self.inner.condition_number
        )
    }
}

/// Design a persistently exciting Fourier trajectory (minimum normalised condition number within
/// the limits, at rest at both ends); `options` holds only what the caller set. Progress goes to
/// stderr unless `quiet`.
#[pyfunction]
#[pyo3(signature = (robot, options, quiet))]
fn _design_excitation(py: Python<'_>, robot: &Robot, options: &Bound<'_, PyDict>, quiet: bool) -> PyResult<Excitation> {
    use arash_core::identify::excitation::design_excitation as design;
    let mut o = ExcitationOptions::default();
    let mut keep_weak = false;
    let mut repair_report = Vec::new();
    crate::convert::each_option(options, |key, value| {
        match key {
            "keep_weak" => keep_weak = value.extract()?,
            "repair_report" => repair_report = crate::convert::choices_in(value)?,
            "harmonics" => o.harmonics = value.extract()?,
            "period_s" => o.period_s = value.extract()?,
            "restarts" => o.restarts = value.extract()?,
            "seed" => o.seed = value.extract()?,
            "iterations" => o.iterations = value.extract()?,
            "acceleration_limits" => o.acceleration_limits = value.extract()?,
            "min_range_fraction" => o.min_range_fraction = value.extract()?,
            "min_speed_fraction" => o.min_speed_fraction = value.extract()?,
            _ => return Ok(false),
        }
        Ok(true)
    })?;
    let options = o;
    let base = robot.fitted_base(keep_weak)?;
    let model = Arc::clone(&robot.model);
    let inner = py
        .detach(|| {
            design(&model, base, &options, &mut |p| {
                if !quiet {
                    eprintln!(
                        "excitation restart {}/{}: best κ = {:.3}",
                        p.restart, p.restarts, p.best_condition_number
                    );
                }
            })
        })
        .map_err(value_error)?;
    Ok(Excitation { inner })
}
