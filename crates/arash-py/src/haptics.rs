//! `fixture_bounds` and `render_fixtures`: the haptic mode's virtual fixtures
//! (`arash_core::haptics`), from a fixture file's TOML text.

use arash_core::haptics::{check_passivity, FixtureRenderer, Fixtures, RenderLoop};
use numpy::PyReadonlyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{batch, same_length, to_numpy, value_error, vector_out};
use crate::robot::Robot;

/// A fixture file's text, its fields checked by name.
fn parse(fixtures: &str) -> PyResult<Fixtures> {
    let parsed: Fixtures = toml::from_str(fixtures).map_err(|e| value_error(format!("fixtures: {e}")))?;
    parsed.validate().map_err(value_error)?;
    Ok(parsed)
}

/// Whether the fixtures in `fixtures` (a fixture file's TOML text, docs/haptics.md) can be
/// rendered passively by a loop of period `period_s` (s) whose commands act `latency_s` after
/// their measurement (default: one period, the daemon's), on a robot whose parameters are
/// `params` (default CAD), with the share `viscous_compensation` of its viscous friction
/// compensated. Returns each fixture's least damping met (`damping_left`), its stiffness bound
/// (`stiffness_bound`, None for a field) and its largest `share` of the damping, and the
/// fixtures' largest share `together`. Raises ValueError naming the field over its bound.
#[pyfunction]
#[pyo3(signature = (robot, fixtures, *, params=None, viscous_compensation=0.0, period_s=1e-3, latency_s=None))]
pub(crate) fn fixture_bounds<'py>(
    py: Python<'py>,
    robot: &Robot,
    fixtures: &str,
    params: Option<PyReadonlyArrayDyn<'py, f64>>,
    viscous_compensation: f64,
    period_s: f64,
    latency_s: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let model = &robot.model;
    let parsed = parse(fixtures)?;
    let params = robot.params_or_cad(params)?;
    let looped = RenderLoop::of_model(model, &params, viscous_compensation, period_s, latency_s.unwrap_or(period_s))
        .map_err(value_error)?;
    let found = check_passivity(model, &parsed, &looped).map_err(value_error)?;
    let out = PyDict::new(py);
    let each = PyDict::new(py);
    for b in &found.fixtures {
        let d = PyDict::new(py);
        d.set_item("damping_left", b.damping_left)?;
        d.set_item("stiffness_bound", b.stiffness_bound)?;
        d.set_item("share", b.share)?;
        each.set_item(&b.fixture, d)?;
    }
    out.set_item("fixtures", each)?;
    out.set_item("together", found.together)?;
    out.set_item("delay_s", looped.delay_s())?;
    Ok(out)
}

/// The fixtures of `fixtures` (TOML text) rendered at each sample of `q` and `qd` ((N, dof), or
/// (dof,) for one sample without the batch axis): the joint torque (`torque`, N·m or N), the force at the instrument's frame and its
/// moment about the entry point (`force`, `moment`, base frame), the energy the fixtures' springs
/// hold (`energy`, J) and whether a wall or a cone is engaged (`contact`).
#[pyfunction]
pub(crate) fn render_fixtures<'py>(
    py: Python<'py>,
    robot: &Robot,
    fixtures: &str,
    q: PyReadonlyArrayDyn<'py, f64>,
    qd: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let model = &robot.model;
    let n = model.dof();
    let (q, qd) = (batch("q", &q, n)?, batch("qd", &qd, n)?);
    let samples = same_length(&[("q", &q), ("qd", &qd)])?;
    let mut renderer = FixtureRenderer::new(model, &parse(fixtures)?).map_err(value_error)?;
    let (mut torque, mut force, mut moment) = (vec![0.0; samples * n], Vec::new(), Vec::new());
    let (mut energy, mut contact) = (Vec::new(), Vec::new());
    for i in 0..samples {
        let at = i * n..(i + 1) * n;
        let r =
            renderer.add_torque(&q.values[at.clone()], &qd.values[at.clone()], &mut torque[at]).map_err(value_error)?;
        force.extend(r.force);
        moment.extend(r.moment);
        energy.push(r.energy);
        contact.push(r.contact);
    }
    let single = q.single && qd.single;
    let out = PyDict::new(py);
    out.set_item("torque", to_numpy(py, torque, single, samples, &[n])?)?;
    out.set_item("force", to_numpy(py, force, single, samples, &[3])?)?;
    out.set_item("moment", to_numpy(py, moment, single, samples, &[3])?)?;
    match single {
        true => {
            out.set_item("energy", energy[0])?;
            out.set_item("contact", contact[0])?;
        }
        false => {
            out.set_item("energy", vector_out(py, &energy)?)?;
            out.set_item("contact", contact)?;
        }
    }
    Ok(out)
}
