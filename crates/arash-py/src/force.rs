//! `external_force`: the hand's force over a whole log (`arash_core::force_log`).

use arash_core::force::{Level, TorqueTiming, COLLISION_SIGMAS, CONTACT_SIGMAS};
use arash_core::force_log::{
    estimate_force, Effort, ForceInput, ForceLogOptions, FrameChoice, Source, ThresholdChoice,
};
use numpy::PyReadonlyArrayDyn;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{batch, matrix_out, same_length, value_error, vector, vector_out};
use crate::identify::Identification;
use crate::robot::Robot;

/// The external joint torque by the generalized momentum observer over a log (`t` (N,), `q` and
/// `tau` (N, dof): the torque the drives applied, or with `currents=True` their currents, turned
/// into torques by the model's drive gains), on the model `model` (an `Identification`, effects
/// included) or on the parameters `params` (the CAD parameters when neither is given). `qd` is
/// the measured velocity, if any; without it, q is differentiated as the model was fitted.
///
/// Chosen from the model unless given (the result's "reasons" say how): the bandwidth (Hz, a
/// float or one per joint: a quarter of the band the model's σ holds in), `sigma` per joint (the
/// model's held-out residual RMS, or none) and `epsilon`, the Coulomb terms' tanh(q̇/ε) width
/// (the model's own law, or the robust controller's where the model's is sign(q̇)). `torque` says how `tau` acted between samples: "sampled" (a
/// measurement at its instant: a torque sensor, a current read back) or "held" (a command held
/// until the next sample: the daemon's and the simulator's logs).
///
/// With `frame` (a link or a fixed frame of the URDF), also the force at that frame's origin in
/// the base frame, its components in the frame's axes, its moment about `about` (default: the
/// base), its σ per axis and whether the joints resolve it (`singular`).
///
/// `thresholds` tells contact from collision: "sigma" (at `contact_sigmas` and
/// `collision_sigmas` times σ, by default arash's `CONTACT_SIGMAS` and `COLLISION_SIGMAS`, 4
/// and 8, docs/force.md) or a pair `(contact,
/// collision)` per joint in N·m and N; the result then holds each sample's `level` (0 free, 1
/// contact, 2 collision), the thresholds used and the `episodes` (start, end, level) found.
///
/// `zero_phase=True` (offline analysis): the estimate without the observer's lag and in a hand's
/// band (5 Hz), the forward observer's lag run backward and a zero-phase Butterworth after it;
/// `level` and the episodes stay the causal observer's, as the rig would have flagged them.
#[pyfunction]
#[pyo3(signature = (robot, t, q, tau, *, qd=None, model=None, params=None, bandwidth_hz=None, epsilon=None, sigma=None, frame=None, about=None, min_lever_m=None, torque="sampled", currents=false, thresholds=None, contact_sigmas=None, collision_sigmas=None, zero_phase=false))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn external_force<'py>(
    py: Python<'py>,
    robot: &Robot,
    t: PyReadonlyArrayDyn<'py, f64>,
    q: PyReadonlyArrayDyn<'py, f64>,
    tau: PyReadonlyArrayDyn<'py, f64>,
    qd: Option<PyReadonlyArrayDyn<'py, f64>>,
    model: Option<&Identification>,
    params: Option<PyReadonlyArrayDyn<'py, f64>>,
    bandwidth_hz: Option<Bound<'py, PyAny>>,
    epsilon: Option<Bound<'py, PyAny>>,
    sigma: Option<Bound<'py, PyAny>>,
    frame: Option<String>,
    about: Option<String>,
    min_lever_m: Option<f64>,
    torque: &str,
    currents: bool,
    thresholds: Option<Bound<'py, PyAny>>,
    contact_sigmas: Option<f64>,
    collision_sigmas: Option<f64>,
    zero_phase: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let core_model = &robot.model;
    let n = core_model.dof();
    let per_joint = |name: &str, v: &Bound<'py, PyAny>| -> PyResult<Vec<f64>> {
        let v = match v.extract::<f64>() {
            Ok(x) => vec![x],
            Err(_) => v.extract::<Vec<f64>>()?,
        };
        match v.len() {
            1 => Ok(vec![v[0]; n]),
            m if m == n => Ok(v),
            m => Err(PyValueError::new_err(format!("{name} has {m} entries; give one or one per joint ({n})"))),
        }
    };
    let optional = |name: &str, v: &Option<Bound<'py, PyAny>>| v.as_ref().map(|v| per_joint(name, v)).transpose();
    let timing = torque_timing(torque)?;
    let thresholds = match &thresholds {
        None => ThresholdChoice::None,
        Some(t) if t.extract::<String>().is_ok_and(|s| s == "sigma") => ThresholdChoice::Sigma {
            contact: contact_sigmas.unwrap_or(CONTACT_SIGMAS),
            collision: collision_sigmas.unwrap_or(COLLISION_SIGMAS),
        },
        Some(t) => {
            let (contact, collision) = t.extract::<(Bound<'py, PyAny>, Bound<'py, PyAny>)>().map_err(|_| {
                PyValueError::new_err("thresholds is \"sigma\" or a pair (contact, collision) of per-joint values")
            })?;
            ThresholdChoice::ByHand {
                contact: per_joint("contact", &contact)?,
                collision: per_joint("collision", &collision)?,
            }
        }
    };
    let defaults = ForceLogOptions::default();
    let options = ForceLogOptions {
        bandwidth_hz: optional("bandwidth_hz", &bandwidth_hz)?,
        epsilon: optional("epsilon", &epsilon)?,
        sigma: optional("sigma", &sigma)?,
        frame: frame.map(|frame| FrameChoice { frame, about }),
        min_lever_m: min_lever_m.unwrap_or(defaults.min_lever_m),
        timing,
        effort: if currents { Effort::Current } else { Effort::Torque },
        thresholds,
        zero_phase,
    };
    let params = params.as_ref().map(|p| vector("params", p)).transpose()?;
    let cad = core_model.cad_parameters();
    let source = match (model, &params) {
        (Some(_), Some(_)) => return Err(PyValueError::new_err("give model or params, not both")),
        (Some(m), None) => Source::File(m.inner()),
        (None, Some(p)) => Source::Params(p),
        (None, None) => Source::Params(&cad),
    };
    let times = vector("t", &t)?;
    let (q, tau) = (batch("q", &q, n)?, batch("tau", &tau, n)?);
    let qd = qd.as_ref().map(|v| batch("qd", v, n)).transpose()?;
    let mut named = vec![("q", &q), ("tau", &tau)];
    named.extend(qd.as_ref().map(|v| ("qd", v)));
    let samples = same_length(&named)?;
    if times.len() != samples {
        return Err(PyValueError::new_err(format!("t has {} samples but q has {samples}", times.len())));
    }
    let input =
        ForceInput { t: &times, q: &q.values, qd: qd.as_ref().map(|v| v.values.as_slice()), effort: &tau.values };
    let result = py.detach(|| estimate_force(core_model, source, input, &options)).map_err(value_error)?;
    let out = PyDict::new(py);
    out.set_item("tau_ext", matrix_out(py, &result.tau_ext, n)?)?;
    out.set_item("sigma_joint", vector_out(py, &result.sigma_joint)?)?;
    out.set_item("bandwidth_hz", vector_out(py, &result.bandwidth_hz)?)?;
    out.set_item("reasons", result.reasons.iter().map(ToString::to_string).collect::<Vec<_>>())?;
    out.set_item("choices", crate::convert::said_out(py, arash_core::choices::said::values(&result.reasons))?)?;
    if result.frame.is_some() {
        out.set_item("force", matrix_out(py, &result.force, 3)?)?;
        out.set_item("local", matrix_out(py, &result.local, 3)?)?;
        out.set_item("moment", matrix_out(py, &result.moment, 3)?)?;
        out.set_item("sigma", matrix_out(py, &result.sigma, 3)?)?;
        out.set_item("singular", numpy::PyArray1::from_vec(py, result.singular))?;
    }
    if let Some(t) = &result.thresholds {
        let code = |l: Level| l as u8;
        out.set_item("level", numpy::PyArray1::from_vec(py, result.levels.iter().map(|l| code(*l)).collect()))?;
        out.set_item("contact_threshold", vector_out(py, t.contact())?)?;
        out.set_item("collision_threshold", vector_out(py, t.collision())?)?;
        let found: Vec<(usize, usize, u8)> = result.episodes.iter().map(|e| (e.start, e.end, code(e.level))).collect();
        out.set_item("episodes", found)?;
    }
    Ok(out)
}

/// How a logged torque acted between samples, by name: "sampled" (a sensor at its instant),
/// "held" (a command held until the next sample) or "preceding" (a drive's report of the cycle
/// that ended at its sample: the daemon's logs).
pub(crate) fn torque_timing(torque: &str) -> PyResult<TorqueTiming> {
    match torque {
        "sampled" => Ok(TorqueTiming::Sampled),
        "held" => Ok(TorqueTiming::Held),
        "preceding" => Ok(TorqueTiming::Preceding),
        other => {
            Err(PyValueError::new_err(format!("torque is {other:?}; give \"sampled\", \"held\" or \"preceding\"")))
        }
    }
}
