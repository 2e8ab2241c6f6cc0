//! `external_force`: the momentum observer and the force at a frame over a whole log.

use arash_core::control::gains::{compensation_epsilon, model_epsilon};
use arash_core::control::RobustGains;
use arash_core::force::{FrameForce, MomentumObserver, TorqueTiming};
use numpy::PyReadonlyArrayDyn;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{batch, matrix_out, same_length, value_error, vector};
use crate::identify::Identification;
use crate::robot::Robot;

/// The external joint torque by the generalized momentum observer over a log (`t` (N,), `q`,
/// `qd`, `tau` (N, dof): the torque the drives applied), at `bandwidth_hz` per joint (a float
/// or one per joint), on the model `model` (an `Identification`, effects included) or on the
/// parameters `params` (the CAD parameters when neither is given). The Coulomb terms switch as
/// tanh(q̇/ε), `epsilon` per joint (default: the robust controller's, or the joint kinds' default
/// for a robot without the paper's gains). `torque` says how `tau`
/// acted between samples: "sampled" (a measurement at its instant: a torque sensor, a current
/// read back) or "held" (a command held until the next sample: the daemon's and the
/// simulator's logs).
///
/// With `frame` (a link or a fixed frame of the URDF), also the force at that frame's origin in
/// the base frame, its components in the frame's axes, its moment about `about` (default: the
/// base), its σ per axis from `sigma` (per joint, default zeros) and whether the joints resolve
/// it (`singular`). Returns a dict of numpy arrays.
#[pyfunction]
#[pyo3(signature = (robot, t, q, qd, tau, *, bandwidth_hz, model=None, params=None, epsilon=None, frame=None, about=None, sigma=None, min_lever_m=1e-3, torque="sampled"))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn external_force<'py>(
    py: Python<'py>,
    robot: &Robot,
    t: PyReadonlyArrayDyn<'py, f64>,
    q: PyReadonlyArrayDyn<'py, f64>,
    qd: PyReadonlyArrayDyn<'py, f64>,
    tau: PyReadonlyArrayDyn<'py, f64>,
    bandwidth_hz: &Bound<'py, PyAny>,
    model: Option<&Identification>,
    params: Option<PyReadonlyArrayDyn<'py, f64>>,
    epsilon: Option<Bound<'py, PyAny>>,
    frame: Option<String>,
    about: Option<String>,
    sigma: Option<Bound<'py, PyAny>>,
    min_lever_m: f64,
    torque: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let timing = match torque {
        "sampled" => TorqueTiming::Sampled,
        "held" => TorqueTiming::Held,
        other => return Err(PyValueError::new_err(format!("torque is {other:?}; give \"sampled\" or \"held\""))),
    };
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
    let bandwidth = per_joint("bandwidth_hz", bandwidth_hz)?;
    let epsilon = match &epsilon {
        Some(e) => per_joint("epsilon", e)?,
        // The robust controller's ε as it compensates friction: the paper's where it has gains
        // for the robot, the joint kinds' default elsewhere, widened to the model's own law.
        None => {
            let paper = RobustGains::paper(core_model).map(|g| g.epsilon);
            compensation_epsilon(core_model, &paper.unwrap_or_else(|_| model_epsilon(core_model)))
        }
    };
    let sigma = match &sigma {
        Some(s) => per_joint("sigma", s)?,
        None => vec![0.0; n],
    };
    let (pi, effects) = match (model, params) {
        (Some(_), Some(_)) => return Err(PyValueError::new_err("give model or params, not both")),
        (Some(m), None) => (m.inner().full_or_base_vector(), m.inner().effects.clone()),
        (None, Some(p)) => (vector("params", &p)?, Vec::new()),
        (None, None) => (core_model.cad_parameters(), Vec::new()),
    };
    let times = vector("t", &t)?;
    let (q, qd, tau) = (batch("q", &q, n)?, batch("qd", &qd, n)?, batch("tau", &tau, n)?);
    let samples = same_length(&[("q", &q), ("qd", &qd), ("tau", &tau)])?;
    if times.len() != samples {
        return Err(PyValueError::new_err(format!("t has {} samples but q has {samples}", times.len())));
    }
    if let Some(i) = times.windows(2).position(|w| w[1] <= w[0]) {
        return Err(PyValueError::new_err(format!("t does not increase at sample {}", i + 1)));
    }
    let mut observer =
        MomentumObserver::new(core_model, &pi, &effects, &bandwidth, &epsilon, timing).map_err(value_error)?;
    let mut map = match &frame {
        Some(f) => Some(
            FrameForce::new(core_model, f, about.as_deref().unwrap_or(&core_model.frames[0].name), min_lever_m)
                .map_err(value_error)?,
        ),
        None => None,
    };
    let mut external = vec![0.0; samples * n];
    let (mut force, mut local, mut moment, mut force_sigma) =
        (vec![0.0; samples * 3], vec![0.0; samples * 3], vec![0.0; samples * 3], vec![0.0; samples * 3]);
    let mut singular = vec![false; samples];
    for i in 0..samples {
        let rows = i * n..(i + 1) * n;
        let (qi, qdi, taui) = (&q.values[rows.clone()], &qd.values[rows.clone()], &tau.values[rows.clone()]);
        // The first sample primes the observer; its step length is never used.
        let dt = if i == 0 { 1.0 } else { times[i] - times[i - 1] };
        let estimate = observer.step(dt, qi, qdi, taui).map_err(value_error)?;
        external[rows].copy_from_slice(estimate);
        if let Some(map) = map.as_mut() {
            let s = map.map(qi, estimate, &sigma);
            force[i * 3..i * 3 + 3].copy_from_slice(&s.force);
            local[i * 3..i * 3 + 3].copy_from_slice(&s.local);
            moment[i * 3..i * 3 + 3].copy_from_slice(&s.moment);
            force_sigma[i * 3..i * 3 + 3].copy_from_slice(&s.sigma);
            singular[i] = s.singular;
        }
    }
    let out = PyDict::new(py);
    out.set_item("tau_ext", matrix_out(py, &external, n)?)?;
    if map.is_some() {
        out.set_item("force", matrix_out(py, &force, 3)?)?;
        out.set_item("local", matrix_out(py, &local, 3)?)?;
        out.set_item("moment", matrix_out(py, &moment, 3)?)?;
        out.set_item("sigma", matrix_out(py, &force_sigma, 3)?)?;
        out.set_item("singular", numpy::PyArray1::from_vec(py, singular))?;
    }
    Ok(out)
}
