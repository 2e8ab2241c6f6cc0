//! `arash.DiagnoseOptions`, `arash._diagnose` and the `Diagnosis` and `Effect` it returns.
//! `arash.diagnose` (Python) takes typed keywords and passes only those the caller set; every
//! default is `arash_core::diagnose::DiagnoseOptions::default()`.

use std::sync::Arc;

use arash_core::diagnose::{
    consistent_with_effects, diagnose as core_diagnose, DiagnoseOptions as CoreOptions, Diagnosis as CoreDiagnosis,
    Finding, Reversion, Runs, Start, StartedFrom,
};
use arash_core::effects::EffectKind;
use arash_core::identify::{ConsistentOptions, PreprocessOptions};
use arash_core::identify::{Declared, Log};
use arash_core::model_file::{Metrics, ModelFile};
use numpy::PyReadonlyArrayDyn;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{matrix_out, value_error, vector_out, NumpyArray};
use crate::identify::{log_arrays, Identification};
use crate::robot::Robot;

/// The diagnosis's settings. `DiagnoseOptions()` holds the defaults; `DiagnoseOptions(alpha=0.05)`
/// changes one. `consistent` and `consistent_cutoff_hz` ask for the physically consistent refit
/// with the effects found (its cut-off defaults to the diagnosis's).
#[pyclass(module = "arash._arash", name = "DiagnoseOptions")]
#[derive(Clone)]
pub(crate) struct DiagnoseOptions {
    inner: CoreOptions,
    consistent: bool,
    consistent_cutoff_hz: Option<f64>,
}

#[pymethods]
impl DiagnoseOptions {
    #[new]
    #[pyo3(signature = (**kwargs))]
    fn new(kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut options = Self { inner: CoreOptions::default(), consistent: false, consistent_cutoff_hz: None };
        for (key, value) in kwargs.into_iter().flatten() {
            let key: String = key.extract()?;
            options.set(&key, &value)?;
        }
        Ok(options)
    }
    /// The cut-off set, or None: the diagnosis's own (20 Hz, at most a fifth of the rate,
    /// narrower where the encoder's noise would bias q̈; `settings["reasons"]` says why).
    #[getter]
    fn cutoff_hz(&self) -> Option<f64> {
        self.inner.preprocess.cutoff_hz
    }
    /// The friction velocity's cut-off set, or None: the diagnosis's cut-off, slower where the
    /// encoder's steps would make up more than 0.25 % of a joint's RMS speed.
    #[getter]
    fn friction_cutoff_hz(&self) -> Option<f64> {
        self.inner.preprocess.friction_cutoff_hz
    }
    #[getter]
    fn order(&self) -> usize {
        self.inner.preprocess.order
    }
    #[getter]
    fn block_s(&self) -> f64 {
        self.inner.block_s
    }
    /// The Wald test's batch length set (s), or None: each test chooses from its scores.
    #[getter]
    fn batch_s(&self) -> Option<f64> {
        self.inner.batch_s
    }
    #[getter]
    fn alpha(&self) -> f64 {
        self.inner.alpha
    }
    #[getter]
    fn min_gain(&self) -> f64 {
        self.inner.min_gain
    }
    #[getter]
    fn max_effects(&self) -> usize {
        self.inner.max_effects
    }
    #[getter]
    fn max_delay_s(&self) -> f64 {
        self.inner.max_delay_s
    }
    #[getter]
    fn max_vif(&self) -> f64 {
        self.inner.max_vif
    }
    #[getter]
    fn transmission(&self) -> Option<Vec<f64>> {
        self.inner.transmission.clone()
    }
    #[getter]
    fn effects(&self) -> Vec<&'static str> {
        self.inner.effects.iter().map(|k| k.id()).collect()
    }
    #[getter]
    fn torque_from_currents(&self) -> bool {
        self.inner.torque_from_currents
    }
    #[getter]
    fn refit(&self) -> bool {
        self.inner.refit
    }
    #[getter]
    fn hold_friction(&self) -> bool {
        self.inner.hold_friction
    }
    /// Without a model, what the diagnosis starts from: `"identified"` or `"declared"`.
    #[getter]
    fn start(&self) -> &'static str {
        match self.inner.start {
            Start::Identified => "identified",
            Start::Declared => "declared",
        }
    }
    #[getter]
    fn consistent(&self) -> bool {
        self.consistent
    }
    #[getter]
    fn consistent_cutoff_hz(&self) -> Option<f64> {
        self.consistent_cutoff_hz
    }
    fn __repr__(&self) -> String {
        format!(
            "DiagnoseOptions(cutoff_hz={:?}, block_s={}, alpha={}, min_gain={}, effects={:?})",
            self.inner.preprocess.cutoff_hz,
            self.inner.block_s,
            self.inner.alpha,
            self.inner.min_gain,
            self.effects()
        )
    }
}

impl DiagnoseOptions {
    /// Set the option `key`; a name that is not an option is a `TypeError`, as a wrong keyword
    /// argument is.
    fn set(&mut self, key: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let o = &mut self.inner;
        match key {
            "cutoff_hz" => o.preprocess.cutoff_hz = value.extract()?,
            "friction_cutoff_hz" => o.preprocess.friction_cutoff_hz = value.extract()?,
            "order" => o.preprocess.order = value.extract()?,
            "block_s" => o.block_s = value.extract()?,
            "batch_s" => o.batch_s = value.extract()?,
            "alpha" => o.alpha = value.extract()?,
            "min_gain" => o.min_gain = value.extract()?,
            "max_effects" => o.max_effects = value.extract()?,
            "max_delay_s" => o.max_delay_s = value.extract()?,
            "max_vif" => o.max_vif = value.extract()?,
            "transmission" => o.transmission = value.extract()?,
            "motor_side" => {
                let t: Option<PyRef<'_, crate::transmission::Transmission>> = value.extract()?;
                o.motors = t.map(|t| t.core().clone());
            }
            "effects" => {
                let ids: Vec<String> = value.extract()?;
                o.effects = EffectKind::parse_list(&ids).map_err(value_error)?;
            }
            "torque_from_currents" => o.torque_from_currents = value.extract()?,
            "refit" => o.refit = value.extract()?,
            "hold_friction" => o.hold_friction = value.extract()?,
            "start" => {
                let start: String = value.extract()?;
                o.start = match start.as_str() {
                    "identified" => Start::Identified,
                    "declared" => Start::Declared,
                    other => return Err(value_error(format!("start: `identified` or `declared`, not `{other}`"))),
                };
            }
            "consistent" => self.consistent = value.extract()?,
            "consistent_cutoff_hz" => self.consistent_cutoff_hz = value.extract()?,
            other => return Err(PyTypeError::new_err(format!("DiagnoseOptions has no option `{other}`"))),
        }
        Ok(())
    }
}

/// An effect the diagnosis accepted, with its evidence.
#[pyclass(module = "arash._arash", frozen)]
pub(crate) struct Effect {
    finding: Finding,
}

#[pymethods]
impl Effect {
    /// The effect's identifier (docs/diagnosis.md).
    #[getter]
    fn name(&self) -> &str {
        &self.finding.name
    }
    #[getter]
    fn joints(&self) -> Vec<usize> {
        self.finding.joints.clone()
    }
    #[getter]
    fn label(&self) -> &str {
        &self.finding.label
    }
    #[getter]
    fn columns(&self) -> Vec<String> {
        self.finding.term.columns.clone()
    }
    #[getter]
    fn coefficients<'py>(&self, py: Python<'py>) -> PyResult<NumpyArray<'py>> {
        let c = &self.finding.term.coefficients;
        vector_out(py, c)
    }
    #[getter]
    fn sigma<'py>(&self, py: Python<'py>) -> PyResult<NumpyArray<'py>> {
        let s = &self.finding.term.sigma;
        vector_out(py, s)
    }
    #[getter]
    fn statistic(&self) -> f64 {
        self.finding.statistic
    }
    /// B, the batches its Wald test summed over (the statistic is F(k, B − k)).
    #[getter]
    fn batches(&self) -> usize {
        self.finding.batches
    }
    #[getter]
    fn p_value(&self) -> f64 {
        self.finding.p_value
    }
    #[getter]
    fn threshold(&self) -> f64 {
        self.finding.threshold
    }
    #[getter]
    fn heldout_gain(&self) -> f64 {
        self.finding.heldout_gain
    }
    #[getter]
    fn aliases(&self) -> Vec<String> {
        self.finding.aliases.clone()
    }
    #[getter]
    fn mass_kg(&self) -> Option<f64> {
        self.finding.mass_kg
    }
    /// A payload's mass σ (kg); on torque from currents, it counts the drive gains' σ.
    #[getter]
    fn mass_sigma_kg(&self) -> Option<f64> {
        self.finding.mass_sigma_kg
    }
    /// Per coefficient, the part of `sigma` the calibrated drive gains give (None unless the
    /// torque came from currents through them).
    #[getter]
    fn sigma_from_gains<'py>(&self, py: Python<'py>) -> PyResult<Option<NumpyArray<'py>>> {
        let s = &self.finding.sigma_from_gains;
        if s.is_empty() {
            return Ok(None);
        }
        vector_out(py, s).map(Some)
    }
    #[getter]
    fn body(&self) -> Option<String> {
        self.finding.body.clone()
    }
    /// A payload's centre of mass in its body's frame (m), `None` along a direction the data
    /// cannot see.
    #[getter]
    fn centre_of_mass_m(&self) -> Option<Vec<Option<f64>>> {
        self.finding.centre_of_mass_m.map(|c| c.to_vec())
    }
    #[getter]
    fn round(&self) -> usize {
        self.finding.round
    }
    /// The term's constant (a Stribeck or friction velocity, a travel, a cogging count, a
    /// delay in samples), `None` for a term without one.
    #[getter]
    fn scale(&self) -> Option<f64> {
        self.finding.term.scale
    }
    /// Where the scale was refined between the grid's points: `grid` (the grid's scale),
    /// `bracket` (its neighbours) and `residual_drop` (the share of the training residual's sum
    /// of squares the refined scale removes beyond the grid's). `None` otherwise.
    #[getter]
    fn refined<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(r) = &self.finding.refined else { return Ok(None) };
        let d = PyDict::new(py);
        d.set_item("grid", r.grid)?;
        d.set_item("bracket", r.bracket.to_vec())?;
        d.set_item("residual_drop", r.residual_drop)?;
        Ok(Some(d))
    }
    fn __repr__(&self) -> String {
        format!(
            "Effect({:?}, p={:.2e}, heldout_gain={:.3})",
            self.finding.label, self.finding.p_value, self.finding.heldout_gain
        )
    }
}

/// What `arash.diagnose` found (docs/diagnosis.md).
#[pyclass(module = "arash._arash", frozen)]
pub(crate) struct Diagnosis {
    robot: Arc<arash_core::Model>,
    inner: CoreDiagnosis,
    consistent: Option<ModelFile>,
}

#[pymethods]
impl Diagnosis {
    /// The effects accepted, in the order they were added.
    #[getter]
    fn accepted(&self) -> Vec<Effect> {
        self.inner.accepted.iter().map(|f| Effect { finding: f.clone() }).collect()
    }
    /// Set when the search stopped because the model is heavier than the data (a payload of
    /// negative mass explained the residual best): `body`, `mass_kg` (the mass the data lack,
    /// positive), `mass_sigma_kg` (with the drive gains' σ on torque from currents, whose part is
    /// `mass_sigma_from_gains_kg`), `p_value`, `heldout_gain`, `round`. None otherwise.
    #[getter]
    fn too_heavy<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(h) = &self.inner.too_heavy else { return Ok(None) };
        let d = PyDict::new(py);
        d.set_item("body", &h.body)?;
        d.set_item("mass_kg", h.mass_kg)?;
        d.set_item("mass_sigma_kg", h.mass_sigma_kg)?;
        d.set_item("mass_sigma_from_gains_kg", h.mass_sigma_from_gains_kg)?;
        d.set_item("p_value", h.p_value)?;
        d.set_item("heldout_gain", h.heldout_gain)?;
        d.set_item("round", h.round)?;
        Ok(Some(d))
    }
    /// What was put back so that no joint predicts the held-out data worse than the model the
    /// diagnosis started from, in order: one dict per step with `joint` (its name), `code`
    /// (`hold_friction`, `drop_effect`, or `unshifted`: the delay taken off the joint's torque),
    /// for a dropped effect its `label`, for the delay its `samples`, for either the joints it
    /// `helped` (names) and `sigmas` (how far it harmed the joint), and the joint's held-out RMS
    /// `start_rms` (the starting model's), `rms_before` and `rms_after` (N·m or N).
    #[getter]
    fn reverted<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let names = &self.inner.joint_names;
        self.inner
            .reverted
            .iter()
            .map(|r| {
                let d = PyDict::new(py);
                d.set_item("joint", &names[r.joint])?;
                match &r.action {
                    Reversion::HoldFriction => d.set_item("code", "hold_friction")?,
                    Reversion::DropEffect { label, helped, sigmas } => {
                        d.set_item("code", "drop_effect")?;
                        d.set_item("label", label)?;
                        d.set_item("helped", helped.iter().map(|&j| names[j].as_str()).collect::<Vec<_>>())?;
                        d.set_item("sigmas", sigmas)?;
                    }
                    Reversion::Unshifted { samples, helped, sigmas } => {
                        d.set_item("code", "unshifted")?;
                        d.set_item("samples", samples)?;
                        d.set_item("helped", helped.iter().map(|&j| names[j].as_str()).collect::<Vec<_>>())?;
                        d.set_item("sigmas", sigmas)?;
                    }
                }
                d.set_item("start_rms", r.start_rms)?;
                d.set_item("rms_before", r.rms_before)?;
                d.set_item("rms_after", r.rms_after)?;
                Ok(d)
            })
            .collect()
    }
    /// Joints the final model still predicts worse than the starting model beyond the
    /// comparison's noise, where no accepted effect causes it: one dict each with `joint` (its
    /// name), `start_rms`, `rms` (N·m or N), `sigmas`, and `band_hz`, the starting model's own
    /// cut-off where the loss was found there (both RMS filtered in it), else None (the
    /// diagnosis's band).
    #[getter]
    fn still_worse<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.inner
            .still_worse
            .iter()
            .map(|w| {
                let d = PyDict::new(py);
                d.set_item("joint", &self.inner.joint_names[w.joint])?;
                d.set_item("start_rms", w.start_rms)?;
                d.set_item("rms", w.rms)?;
                d.set_item("sigmas", w.sigmas)?;
                d.set_item("band_hz", w.band_hz)?;
                Ok(d)
            })
            .collect()
    }
    /// One dict per candidate not accepted: `name`, `joints`, `label`, `reason` (text), `code`
    /// (the reason's identifier), `p_value` and `heldout_gain` (None where not reached).
    #[getter]
    fn rejected<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.inner
            .rejected
            .iter()
            .map(|r| {
                let d = PyDict::new(py);
                d.set_item("name", &r.name)?;
                d.set_item("joints", r.joints.clone())?;
                d.set_item("label", &r.label)?;
                d.set_item("reason", r.reason.to_string())?;
                d.set_item("code", r.reason.code())?;
                d.set_item("p_value", r.p_value)?;
                d.set_item("heldout_gain", r.heldout_gain)?;
                Ok(d)
            })
            .collect()
    }
    /// The settings it ran with, as a dict.
    #[getter]
    fn settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.inner.settings;
        let d = PyDict::new(py);
        d.set_item("cutoff_hz", s.cutoff_hz)?;
        d.set_item("friction_cutoff_hz", s.friction_cutoff_hz)?;
        d.set_item("coulomb_epsilon", s.coulomb_epsilon)?;
        d.set_item("friction_velocities", s.friction_velocities.clone())?;
        crate::convert::set_said(&d, &s.reasons, &s.warnings)?;
        d.set_item("decimate", s.decimate)?;
        d.set_item("block_s", s.block_s)?;
        d.set_item("blocks", s.blocks)?;
        d.set_item("batch_s", s.batch_s)?;
        d.set_item("alpha", s.alpha)?;
        d.set_item("min_gain", s.min_gain)?;
        d.set_item("max_vif", s.max_vif)?;
        d.set_item("max_delay_s", s.max_delay_s)?;
        d.set_item("refit", s.refit)?;
        let started_from = match s.started_from {
            StartedFrom::Declared => "declared",
            StartedFrom::Given => "given",
            StartedFrom::Identified => "identified",
        };
        d.set_item("started_from", started_from)?;
        d.set_item("heldout", &s.heldout)?;
        d.set_item("candidates", s.candidates)?;
        Ok(d)
    }
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.inner.joint_names.clone()
    }
    /// Per-joint errors of the declared model on the held-out data: `rms`, `fp_percent`, `rel`
    /// (‖e‖/‖τ‖), numpy arrays.
    #[getter]
    fn error_before<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        errors(py, &self.inner.before.heldout)
    }
    /// The same after the effects were added.
    #[getter]
    fn error_after<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        errors(py, &self.inner.after.heldout)
    }
    /// The held-out error no model of the motion removes, RMS per joint (numpy array): the
    /// torque's noise in the band, or what the band holds above the narrowest that predicts as
    /// well, if larger. Held-out gains are judged against the error above it, as far as that
    /// stands clear of it.
    #[getter]
    fn noise_floor<'py>(&self, py: Python<'py>) -> PyResult<NumpyArray<'py>> {
        let floor = &self.inner.noise_floor;
        vector_out(py, floor)
    }
    /// The torque's white noise in the band, RMS per joint (numpy array), read above a quarter
    /// of the sample rate.
    #[getter]
    fn sensor_noise<'py>(&self, py: Python<'py>) -> PyResult<NumpyArray<'py>> {
        let noise = &self.inner.sensor_noise;
        vector_out(py, noise)
    }
    /// `error_before` on the training data.
    #[getter]
    fn error_before_training<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        errors(py, &self.inner.before.training)
    }
    /// `error_after` on the training data.
    #[getter]
    fn error_after_training<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        errors(py, &self.inner.after.training)
    }
    /// The updated model (declared parameters plus the effects found).
    #[getter]
    fn model(&self) -> Identification {
        Identification::new(Arc::clone(&self.robot), self.inner.model.clone())
    }
    /// The physically consistent model fitted together with the effects found (with
    /// `consistent=True`), else None.
    #[getter]
    fn model_consistent(&self) -> Option<Identification> {
        self.consistent.as_ref().map(|c| Identification::new(Arc::clone(&self.robot), c.clone()))
    }
    /// The signals behind the residual plots: t (N,), and q, qd, qdd, tau, residual_before,
    /// residual_after (N, dof), and one (N, dof) contribution per accepted effect.
    #[getter]
    fn series<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.inner.series;
        let dof = self.robot.dof();
        let d = PyDict::new(py);
        let table = |v: &[f64]| matrix_out(py, v, dof);
        d.set_item("t", vector_out(py, &s.t)?)?;
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
    /// The report as text: effects with evidence, errors before and after, rejections.
    fn report(&self) -> String {
        self.inner.report()
    }
    fn to_json(&self) -> String {
        self.inner.to_json()
    }
    fn __repr__(&self) -> String {
        let labels: Vec<&str> = self.inner.accepted.iter().map(|f| f.label.as_str()).collect();
        format!("Diagnosis(accepted={labels:?})")
    }
}

/// Per-joint errors as numpy arrays: `rms`, `fp_percent`, `rel` (‖e‖/‖τ‖).
fn errors<'py>(py: Python<'py>, m: &Metrics) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (name, v) in [("rms", &m.rms), ("fp_percent", &m.fp_percent), ("rel", &m.relative_error)] {
        d.set_item(name, vector_out(py, v)?)?;
    }
    Ok(d)
}

type Arrays<'py> = (PyReadonlyArrayDyn<'py, f64>, PyReadonlyArrayDyn<'py, f64>, PyReadonlyArrayDyn<'py, f64>);

/// Diagnose the log `(t, q, tau)` against the robot's declared model (see `arash.diagnose`);
/// `validation_starts`: where each concatenated held-out run after the first begins;
/// `repair_report`: what `arash.repair_log` did to the logs, put first among the reasons.
#[pyfunction]
#[pyo3(signature = (robot, log, options, model=None, validation=None, validation_starts=Vec::new(), repair_report=None))]
#[allow(clippy::too_many_arguments)]
fn _diagnose<'py>(
    py: Python<'py>,
    robot: &Robot,
    log: Arrays<'py>,
    options: &DiagnoseOptions,
    model: Option<&Identification>,
    validation: Option<Arrays<'py>>,
    validation_starts: Vec<usize>,
    repair_report: Option<Bound<'_, PyAny>>,
) -> PyResult<Diagnosis> {
    let dof = robot.model.dof();
    let (t, q, tau) = log_arrays(&log.0, &log.1, &log.2, dof)?;
    let held = validation
        .as_ref()
        .map(|(vt, vq, vtau)| log_arrays(vt, vq, vtau, dof))
        .transpose()
        .map_err(|e| PyValueError::new_err(format!("validation log: {}", e.value(py))))?;
    options.inner.validate(dof).map_err(value_error)?;
    // Against a model, in its base parameters; without one, in the exact ones. Both are the
    // diagnosed model's, which the consistent refit takes. From the identification the
    // diagnosis also identifies, in the base parameters identification fits, cached here.
    let base = match model {
        Some(m) => robot.base_of(&m.inner().base_independent)?,
        None => robot.diagnosed_base()?,
    };
    let start_base = match (model, options.inner.start) {
        (None, Start::Identified) => robot.fitted_base(false)?,
        _ => base,
    };
    let robot_model = Arc::clone(&robot.model);
    let given = model.map(|m| m.inner().clone());
    let (inner, consistent) = py
        .detach(|| {
            let train = Log { t: &t, q: &q, tau: &tau };
            let held = held.as_ref().map(|(t, q, tau)| Runs { log: Log { t, q, tau }, starts: &validation_starts });
            let declared = Declared { model: &robot_model, base: start_base, urdf: &robot.urdf };
            let inner = core_diagnose(declared, train, held, given.as_ref(), &options.inner)?;
            let consistent = options
                .consistent
                .then(|| {
                    let cutoff_hz = options.consistent_cutoff_hz.unwrap_or(inner.settings.cutoff_hz);
                    let preprocess =
                        PreprocessOptions { cutoff_hz: Some(cutoff_hz), ..options.inner.preprocess.clone() };
                    let refit = CoreOptions { preprocess, ..options.inner.clone() };
                    let solver = ConsistentOptions::default();
                    consistent_with_effects(&robot_model, base, train, &inner.model, &refit, &solver)
                })
                .transpose()?;
            Ok::<_, arash_core::diagnose::DiagnoseError>((inner, consistent))
        })
        .map_err(value_error)?;
    let mut inner = inner;
    let repair_report = repair_report.map(|r| crate::convert::choices_in(&r)).transpose()?.unwrap_or_default();
    inner.settings.reasons.splice(0..0, repair_report);
    Ok(Diagnosis { robot: robot_model, inner, consistent })
}

pub(crate) fn register(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_class::<DiagnoseOptions>()?;
    module.add_class::<Diagnosis>()?;
    module.add_class::<Effect>()?;
    module.add_function(wrap_pyfunction!(_diagnose, module)?)?;
    Ok(())
}
