//! `arash.simulate` and `arash.read_log`: the simulated rig and the flight log, as dicts of
//! numpy arrays. The Python wrapper in `arash/__init__.py` turns paths and dicts into the text
//! these functions take.

use std::path::PathBuf;

use arash_core::control::gains::PaperUnits;
use arash_core::control::{RobustGains, Trajectory};
use arash_core::diagnose::EffectTerm;
use arash_core::flightlog::{on_uniform_grid, read_log as core_read_log, FlightLog, LogWriter};
use arash_core::identify::closed_loop::LoggedController;
use arash_core::record::{Columns, TruthColumns};
use arash_core::sim::{named_parameters, true_parameters, ControllerChoice, RunSpec, Scenario};
use numpy::PyReadonlyArrayDyn;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use crate::convert::{batch, matrix_out, value_error, vector_out};
use crate::identify::Identification;
use crate::robot::Robot;

fn matrix<'py>(py: Python<'py>, values: &[f64], dof: usize) -> PyResult<Bound<'py, PyAny>> {
    Ok(matrix_out(py, values, dof)?.into_any())
}

fn vector<'py>(py: Python<'py>, values: &[f64]) -> PyResult<Bound<'py, PyAny>> {
    Ok(vector_out(py, values)?.into_any())
}

fn integers<'py, T: numpy::Element + Copy>(py: Python<'py>, values: &[T]) -> Bound<'py, PyAny> {
    numpy::PyArray1::from_slice(py, values).into_any()
}

fn cycles_dict<'py>(py: Python<'py>, c: &Columns, dof: usize) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("cycle", integers(py, &c.cycle))?;
    d.set_item("t", vector(py, &c.t)?)?;
    for (name, values) in c.joint_vectors() {
        d.set_item(name, matrix(py, values, dof)?)?;
    }
    for (name, values, width) in c.optional_vectors(dof) {
        match values.is_empty() {
            true => d.set_item(name, py.None())?,
            false => d.set_item(name, matrix(py, values, width)?)?,
        }
    }
    for (name, codes) in c.codes() {
        d.set_item(name, integers(py, codes))?;
    }
    Ok(d)
}

fn truth_dict<'py>(py: Python<'py>, c: &TruthColumns, dof: usize) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("cycle", integers(py, &c.cycle))?;
    d.set_item("t", vector(py, &c.t)?)?;
    for (name, values) in c.joint_vectors() {
        d.set_item(name, matrix(py, values, dof)?)?;
    }
    for (name, values, width) in c.optional_vectors(dof) {
        d.set_item(name, matrix(py, values, width)?)?;
    }
    Ok(d)
}

/// The measured and reference channels on a uniform time grid (`flightlog::on_uniform_grid`):
/// what `arash.identify` and `arash.diagnose` take from a daemon log, as the CLI reads it.
fn uniform_dict<'py>(py: Python<'py>, c: &Columns, dof: usize) -> PyResult<Bound<'py, PyDict>> {
    const NAMES: [&str; 5] = ["q", "tau_meas", "q_des", "qd_des", "qdd_des"];
    let channels = [&c.q, &c.tau_meas, &c.q_des, &c.qd_des, &c.qdd_des].map(|v| v.as_slice());
    let uniform = on_uniform_grid(&c.t, &channels, dof);
    let d = PyDict::new(py);
    // A log already uniform is its own grid.
    let (t, repaired) = uniform.as_ref().map_or((&c.t, 0), |u| (&u.t, u.repaired));
    d.set_item("t", vector(py, t)?)?;
    for (k, name) in NAMES.iter().enumerate() {
        let values = uniform.as_ref().map_or(channels[k], |u| &u.channels[k]);
        d.set_item(*name, matrix(py, values, dof)?)?;
    }
    d.set_item("repaired", repaired)?;
    Ok(d)
}

fn log_dict<'py>(py: Python<'py>, log: &FlightLog) -> PyResult<Bound<'py, PyDict>> {
    let d = cycles_dict(py, &log.cycles, log.dof())?;
    d.set_item("uniform", uniform_dict(py, &log.cycles, log.dof())?)?;
    match &log.truth {
        Some(truth) => d.set_item("truth", truth_dict(py, truth, log.dof())?)?,
        None => d.set_item("truth", py.None())?,
    }
    d.set_item("joint_names", log.joint_names.clone())?;
    d.set_item("metadata", log.metadata.clone())?;
    let attachments = PyDict::new(py);
    for (name, _, data) in &log.attachments {
        attachments.set_item(name, PyBytes::new(py, data))?;
    }
    d.set_item("attachments", attachments)?;
    d.set_item("urdf", log.attachment_text("robot.urdf"))?;
    // A log whose controller cannot be read is still a log: the key is None, and identify's
    // closed-loop methods then ask for the controller.
    let controller = log.logged_controller().and_then(Result::ok);
    d.set_item("logged_controller", controller.map(|c| c.to_json()))?;
    d.set_item("truncated", log.truncated)?;
    // JSON channels (the daemon's /arash/timing and /arash/event): topic → [(t_ns, document)].
    let json = PyDict::new(py);
    for (topic, messages) in &log.json {
        json.set_item(topic, messages.clone())?;
    }
    d.set_item("json", json)?;
    Ok(d)
}

/// Read a flight log (MCAP) into a dict of numpy arrays; see `arash.read_log`.
#[pyfunction]
fn read_log<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let log = py.detach(|| core_read_log(&path)).map_err(value_error)?;
    log_dict(py, &log)
}

/// The controller's parameters: None (the choice's default), "cad", "truth", an Identification
/// or a (P,) array. Returns the source's label and the vector.
fn controller_params(
    robot: &Robot,
    scenario: &Scenario,
    choice: ControllerChoice,
    params: Option<&Bound<'_, PyAny>>,
) -> PyResult<(String, Vec<f64>, Vec<EffectTerm>)> {
    let model = &robot.model;
    let named = match params {
        None => Some(choice.default_params().map(str::to_string).ok_or_else(|| {
            PyValueError::new_err("controller \"idc\" needs params: \"cad\", \"truth\", an Identification or an array")
        })?),
        Some(p) => p.extract::<String>().ok(),
    };
    if let Some(name) = named {
        choice.check_params(&name).map_err(PyValueError::new_err)?;
        let values = named_parameters(model, scenario, &name).ok_or_else(|| {
            PyValueError::new_err(format!(
                "params must be \"cad\", \"truth\", an Identification or an array, not {name:?}"
            ))
        })?;
        return Ok((name, values, vec![]));
    }
    let params = params.expect("None is named above");
    if let Ok(identification) = params.cast::<Identification>() {
        choice.check_params("an identified model").map_err(PyValueError::new_err)?;
        let inner = identification.get().inner();
        let values = inner.controller_parameters(model).map_err(value_error)?;
        return Ok(("identified".into(), values, inner.effects.clone()));
    }
    choice.check_params("an array").map_err(PyValueError::new_err)?;
    let array: PyReadonlyArrayDyn<'_, f64> = params
        .extract()
        .map_err(|_| PyValueError::new_err("params must be \"cad\", \"truth\", an Identification or a float array"))?;
    let b = batch("params", &array, model.num_params())?;
    if !b.single {
        return Err(PyValueError::new_err(format!("params must have shape ({},)", model.num_params())));
    }
    Ok(("array".into(), b.values, vec![]))
}

/// Run the simulated rig; see `arash.simulate`. `scenario` is its TOML and the name it gets when
/// the TOML has none; `control` the controller, its parameters and the gains' units; `run` the
/// duration and seed (None: the trajectory's and the scenario's); `output` the flight log's path
/// and whether it records the true state too.
#[pyfunction]
#[pyo3(signature = (robot, scenario, trajectory_json, control, run, output))]
fn _simulate<'py>(
    py: Python<'py>,
    robot: &Robot,
    scenario: (String, String),
    trajectory_json: &str,
    control: (String, Option<Bound<'py, PyAny>>, String),
    run: (Option<f64>, Option<u64>),
    output: (Option<PathBuf>, bool),
) -> PyResult<Bound<'py, PyDict>> {
    let ((scenario_toml, scenario_name), (controller, params, gain_units)) = (scenario, control);
    let ((duration, seed), (log, log_truth)) = (run, output);
    let (scenario_toml, scenario_name, controller, gain_units) =
        (scenario_toml.as_str(), scenario_name.as_str(), controller.as_str(), gain_units.as_str());
    let params = params.as_ref();
    let model = &robot.model;
    let mut scenario = Scenario::from_toml(scenario_toml).map_err(value_error)?;
    if scenario.name.is_empty() {
        scenario.name = scenario_name.into();
    }
    if let Some(seed) = seed {
        scenario.seed = seed;
    }
    scenario.validate(model.dof()).map_err(value_error)?;
    let trajectory = Trajectory::from_json(trajectory_json, model.dof()).map_err(value_error)?;
    let units: PaperUnits = gain_units.parse().map_err(PyValueError::new_err)?;
    let choice: ControllerChoice = controller.parse().map_err(PyValueError::new_err)?;
    let (params_source, values, effects) = controller_params(robot, &scenario, choice, params)?;
    let spec = RunSpec {
        duration_s: duration.unwrap_or_else(|| trajectory.default_duration()),
        scenario,
        trajectory,
        controller: choice.kind(),
        params_source,
        params: values,
        effects,
        gains: RobustGains::from_paper(model, units).ok(),
    };
    let mut rig = spec.rig(model).map_err(value_error)?;
    let (columns, truth, true_params) = py
        .detach(|| -> Result<_, String> {
            let mut writer = match &log {
                Some(path) => Some(
                    LogWriter::create(
                        path,
                        &spec.log_header(model, &robot.urdf, log_truth),
                        spec.scenario.physics.rate_hz,
                    )
                    .map_err(|e| e.to_string())?,
                ),
                None => None,
            };
            let (mut columns, mut truth) = (Columns::default(), TruthColumns::default());
            for i in 0..spec.cycles() {
                rig.step().map_err(|e| format!("cycle {i}: {e}"))?;
                columns.push(rig.record());
                truth.push(rig.truth());
                if let Some(w) = writer.as_mut() {
                    w.write_cycle(rig.record()).map_err(|e| e.to_string())?;
                    if log_truth {
                        w.write_truth(rig.truth()).map_err(|e| e.to_string())?;
                    }
                }
            }
            if let Some(w) = writer {
                w.finish().map_err(|e| e.to_string())?;
            }
            Ok((columns, truth, true_parameters(model, &spec.scenario)))
        })
        .map_err(PyValueError::new_err)?;
    let dof = model.dof();
    let d = cycles_dict(py, &columns, dof)?;
    d.set_item("truth", truth_dict(py, &truth, dof)?)?;
    d.set_item("true_params", vector(py, &true_params)?)?;
    d.set_item("joint_names", model.joint_names())?;
    d.set_item("scenario", spec.scenario.to_toml())?;
    let controller = LoggedController::from_run_json(&spec.to_json()).map_err(value_error)?;
    d.set_item("logged_controller", controller.to_json())?;
    Ok(d)
}

pub(crate) fn register(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_function(wrap_pyfunction!(read_log, module)?)?;
    module.add_function(wrap_pyfunction!(_simulate, module)?)?;
    Ok(())
}
