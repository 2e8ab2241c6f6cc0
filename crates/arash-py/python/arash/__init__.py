"""arash: dynamics, calibration and control of the ARASH:ASiST haptic robot.

Arrays are numpy float64 in SI units (rad, m, s, N·m, N). A batch of states is an ``(N, dof)``
array; a single ``(dof,)`` vector gives a result without the batch axis.

>>> import arash
>>> robot = arash.Robot.arash_asist()
>>> robot.base_parameters().p
23
"""

from __future__ import annotations

import json as _json
import os as _os
import warnings as _warnings
from pathlib import Path as _Path
from typing import Any, NamedTuple, Optional, Sequence, Union

import numpy as _np

from ._arash import _design_excitation, _diagnose, _identify, _identify_with_load, _repair_log, _simulate
from ._arash import (
    BaseParameters,
    DiagnoseOptions,
    Diagnosis,
    Effect,
    Excitation,
    Identification,
    Robot,
    SimulatedMotors,
    Transmission,
    __version__,
    butter,
    consistent_least_squares,
    external_force,
    filtfilt,
    fixture_bounds,
    load_model,
    paper_validation_trajectory,
    read_log,
    render_fixtures,
)

__all__ = [
    "BaseParameters",
    "DiagnoseOptions",
    "Diagnosis",
    "Effect",
    "Excitation",
    "Identification",
    "Robot",
    "SimulatedMotors",
    "Transmission",
    "__version__",
    "butter",
    "consistent_least_squares",
    "design_excitation",
    "diagnose",
    "external_force",
    "filtfilt",
    "fixture_bounds",
    "heldout_errors",
    "identify",
    "load_model",
    "paper_validation_trajectory",
    "read_log",
    "render_fixtures",
    "repair_log",
    "RepairedLog",
    "simulate",
]


def _given(**options: Any) -> dict[str, Any]:
    """The options the caller set: the rest keep arash's own defaults, which live in one place
    (``arash_core``; ``DiagnoseOptions()`` shows the diagnosis's)."""
    return {k: v for k, v in options.items() if v is not None}


def simulate(
    scenario: Optional[Union[str, "_os.PathLike[str]"]] = None,
    trajectory: Optional[Union[str, "_os.PathLike[str]", dict[str, Any]]] = None,
    *,
    controller: str = "robust",
    params: Any = None,
    duration: Optional[float] = None,
    seed: Optional[int] = None,
    robot: Optional[Robot] = None,
    gain_units: str = "si",
    log: Optional[Union[str, "_os.PathLike[str]"]] = None,
    log_truth: bool = False,
) -> dict[str, Any]:
    """Run the simulated rig and return the cycles as a dict of numpy arrays.

    scenario: a scenario TOML file (``scenarios/*.toml``), or None for the nominal rig.
    trajectory: an ``arash-trajectory/1`` JSON file, or the same as a dict, e.g.
        ``{"kind": "paper-validation", "omega": 0.5}``.
    controller: "pd", "idc-cad" (the paper's baseline), "idc" or "robust" (eq. 22).
    params: the controller's parameters: "cad", "truth" (the simulated robot's own), an
        ``Identification`` or a (P,) array. Default: "cad" for pd and idc-cad, "truth" for robust.
    duration: seconds of rig time; default 20 periods of an excitation, one of a validation run.
    seed: overrides the scenario's seed. robot: a ``Robot`` (default: ARASH:ASiST).
    gain_units: reading of the paper's K_d, "si", "deg-mm" or "deg-cm" (docs/simulator.md).
    log: also write the flight log (MCAP) to this path; log_truth adds the ground truth to it.

    The dict holds "t" (N,), "cycle", "q", "qd", "tau_cmd", "tau_meas", "q_des", "qd_des",
    "qdd_des" (N, dof), "controller", "mode", "faults" (N,), "truth" (a dict with "q", "qd",
    "qdd", "tau_motor", "motor_q"), "true_params" (P,), "joint_names", "scenario" (TOML) and
    "logged_controller" (the controller as ``identify(..., method="idim-iv")`` takes it).
    """
    if robot is None:
        robot = Robot.arash_asist()
    if scenario is None:
        scenario_text, scenario_name = "", "nominal"
    else:
        path = _Path(_os.fspath(scenario))
        scenario_text, scenario_name = path.read_text(), path.stem
    if trajectory is None:
        raise ValueError("simulate needs a trajectory: a JSON file or a dict such as "
                         '{"kind": "paper-validation", "omega": 0.5}')
    if isinstance(trajectory, dict):
        trajectory_text = _json.dumps({"format": "arash-trajectory/1", **trajectory})
    else:
        trajectory_text = _Path(_os.fspath(trajectory)).read_text()
    log = None if log is None else _os.fspath(log)
    return _simulate(robot, (scenario_text, scenario_name), trajectory_text, (controller, params, gain_units),
                     (duration, seed), (log, log_truth))


def _as_list(value: Any) -> Any:
    """numpy arrays and scalars in a controller dict, as JSON takes them."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"controller holds a {type(value).__name__}, which is not a number or an array")


class RepairedLog(NamedTuple):
    """A log after ``repair_log``: ``t``, ``q``, ``tau``, the ``extra`` arrays in the order given,
    ``report``, one line per change (empty when the log needed none), and ``choices``, the same
    changes as data: each a dict with its ``code`` (``trimmed``, ``resampled``), its rows and
    figures, and its ``text``."""

    t: Any
    q: Any
    tau: Any
    extra: tuple[Any, ...]
    report: list[str]
    choices: list[dict[str, Any]]


def repair_log(t: Any, q: Any, tau: Any, *extra: Any) -> RepairedLog:
    """Repair a log as real controllers write it, for ``identify`` and ``diagnose`` (which do it
    themselves with ``repair=True``): t (N,), q and tau (N, dof), and any other arrays of N rows
    (a closed loop's reference) repaired alike.

    A block at either end that is not finite, steps back in time or follows a gap of more than
    three steps is trimmed (at most a quarter of the rows; a break elsewhere is refused, naming its
    rows). Stamps that lie within half a step of one uniform line are a uniform stream's and are
    kept; otherwise (a sample stamped early, a missed one, a loop that drifts) every array is
    resampled at the median step by linear interpolation. ``report`` says what was done
    (docs/identification.md, "Logs as controllers write them")."""
    names = ["q", "tau"] + [f"extra[{k}]" for k in range(len(extra))]
    arrays = [_np.asarray(a, dtype=float) for a in (q, tau, *extra)]
    t, out, choices = _repair_log(_np.asarray(t, dtype=float), list(zip(names, arrays)))
    return RepairedLog(t, out[0], out[1], tuple(out[2:]), [c["text"] for c in choices], choices)


def identify(
    robot: Robot,
    t: Any,
    q: Any,
    tau: Any,
    *,
    method: Optional[str] = None,
    periods: Optional[int] = None,
    period_s: Optional[float] = None,
    cutoff_hz: Optional[float] = None,
    order: Optional[int] = None,
    decimate: Optional[int] = None,
    friction_cutoff_hz: Optional[float] = None,
    pull: Optional[float] = None,
    stiffness_bounds: Optional[tuple[float, float]] = None,
    motor_side: Optional[Transmission] = None,
    reference: Optional[tuple[Any, Any, Any]] = None,
    controller: Optional[Union[str, dict[str, Any]]] = None,
    iv_iterations: Optional[int] = None,
    iv_tolerance: Optional[float] = None,
    keep_weak: bool = False,
    repair: bool = False,
    loaded: Optional[Union[tuple[Any, Any, Any], Sequence[tuple[Any, Any, Any]]]] = None,
    load: Optional[dict[str, Any]] = None,
    unloaded: Optional[Sequence[tuple[Any, Any, Any]]] = None,
    datasheet_gains: Optional[Sequence[tuple[float, float]]] = None,
    gains_fit: Optional[str] = None,
) -> Identification:
    """Identify the robot's parameters from a log: t (N,), q and tau (N, dof), SI units.

    method: "ols" (the default), "wls", "consistent", or for a log recorded in closed loop
    "idim-iv", "didim", "idim-iv-consistent" and "didim-consistent" (docs/identification.md). periods: whole
    excitation periods in the log, averaged (None: found from the data; 1: not periodic).
    period_s: the period, when it is known but not how many the log holds.
    cutoff_hz: the low-pass cut-off (None: chosen from the data: among the cut-offs whose fitted
    model predicts the unfiltered torque as well as the best, the one that fits best).
    order: Butterworth order. decimate: keep every k-th filtered sample. friction_cutoff_hz: the
    cut-off of the velocity that switches Coulomb friction (None: the one that fits best).
    pull: the consistent fit's pull toward CAD.
    stiffness_bounds: the cable stiffness's (lower, upper). None keeps arash's default for each (docs/identification.md).
    motor_side: a ``Transmission`` when q and tau are motor angles and motor torques.
    reference: the closed loop's (q_des, qd_des, qdd_des), each (N, dof), and controller: the
    controller that ran it, as a dict or its JSON: ``{"law": "pd", "params": π_c, "kp": [...],
    "kd": [...]}`` (PD with gravity compensation) or ``{"law": "standard", "kind": "robust",
    "params": π_c, "gains": {...}}`` (an arash controller; ``read_log`` and ``simulate`` give it as
    ``"logged_controller"``). Both are needed by the idim-iv and didim methods, which simulate
    the loop. iv_iterations, iv_tolerance: their most iterations, and the move of β̂ (in σ) they
    stop at. keep_weak: fit every exact base parameter; by default those no trajectory within the
    limits separates are regrouped into the others (``robot.base_parameters(regroup_weak=True).weak``
    lists them, and ``Identification.base`` is the set fitted).
    repair: repair the log first (``repair_log``: trim a corrupt end block, resample irregular
    stamps; the reference alike); what it did heads ``settings["reasons"]``. Off, such a log is
    refused with an error that names the sample.
    loaded, load, unloaded: calibrate from motor currents (docs/currents.md). ``tau`` (and every
    run's third array) then holds currents in amperes; ``loaded`` is one run ``(t, q, i)`` or a list
    of runs carrying a known load, ``unloaded`` more runs without it, and ``load`` the load:
    ``{"body": link name, "mass": kg}``, with ``"com"`` (m, in the body's frame) and ``"inertia"``
    (``[Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`` about the centre of mass, kg·m²) where known. Each joint's
    drive gain is fitted with the base parameters and the load's unknowns (Gautier and Briot
    2014); the model is in physical units and ``Identification.drive_gains`` holds the gains.
    datasheet_gains: ``(k, σ)`` per joint from a datasheet, checked against the load's (a warning
    beyond 3σ) and used where the load does not fix a gain. gains_fit: "current" (the default:
    least squares of the residual in amperes, the currents being what is measured with noise) or
    "tls" (total least squares of the stacked system, every column scaled to unit norm).

    ``Identification.settings`` says what was chosen and why; a choice the data support only
    weakly is also raised as a ``UserWarning``.
    """
    if loaded is not None:
        return _identify_from_currents(robot, (t, q, tau), loaded, load, unloaded, method, repair, _given(
            periods=periods, period_s=period_s, cutoff_hz=cutoff_hz, order=order, decimate=decimate,
            friction_cutoff_hz=friction_cutoff_hz, pull=pull), datasheet_gains, gains_fit)
    if load is not None or unloaded is not None or datasheet_gains is not None or gains_fit is not None:
        raise ValueError("load, unloaded, datasheet_gains and gains_fit calibrate from currents and need the loaded "
                         "run(s): loaded=(t, q, i)")
    if isinstance(controller, dict):
        controller = _json.dumps(controller, default=_as_list)
    report: Optional[list[dict[str, Any]]] = None
    if repair:
        repaired = repair_log(t, q, tau, *(reference or ()))
        t, q, tau, report = repaired.t, repaired.q, repaired.tau, repaired.choices
        reference = repaired.extra if reference is not None else None
    options = _given(periods=periods, period_s=period_s, cutoff_hz=cutoff_hz, order=order, decimate=decimate,
                     friction_cutoff_hz=friction_cutoff_hz, pull=pull, stiffness_bounds=stiffness_bounds,
                     reference=reference, controller=controller, iv_iterations=iv_iterations,
                     iv_tolerance=iv_tolerance, keep_weak=keep_weak or None, repair_report=report)
    if motor_side is not None:
        q, tau = motor_side.to_joints(q, tau)
    identification = _identify(robot, (t, q, tau), method, options)
    for warning in identification.settings["warnings"]:
        _warnings.warn(f"arash.identify: {warning}", UserWarning, stacklevel=2)
    return identification


def _identify_from_currents(
    robot: Robot,
    run: tuple[Any, Any, Any],
    loaded: Any,
    load: Optional[dict[str, Any]],
    unloaded: Optional[Sequence[tuple[Any, Any, Any]]],
    method: Optional[str],
    repair: bool,
    options: dict[str, Any],
    datasheet: Optional[Sequence[tuple[float, float]]] = None,
    gains_fit: Optional[str] = None,
) -> Identification:
    """``identify`` with ``loaded``: the runs with their flags, the load checked for its keys."""
    if not isinstance(load, dict) or "body" not in load or "mass" not in load:
        raise ValueError("load: a dict with at least 'body' (the link it rides on) and 'mass' (kg)")
    unknown = set(load) - {"body", "mass", "com", "inertia"}
    if unknown:
        raise ValueError(f"load: unknown key(s) {sorted(unknown)}; expected body, mass, com, inertia")
    loaded_runs = [loaded] if isinstance(loaded, tuple) else list(loaded)
    runs = [(run, False)] + [(r, False) for r in (unloaded or [])] + [(r, True) for r in loaded_runs]
    arrays = []
    for k, (r, flag) in enumerate(runs):
        if not isinstance(r, tuple) or len(r) != 3:
            raise ValueError(f"run {k}: expected a tuple (t, q, i)")
        if repair:
            r = repair_log(*r)[:3]
        arrays.append((*(_np.asarray(a, dtype=float) for a in r), flag))
    com = load.get("com")
    inertia = load.get("inertia")
    spec = (str(load["body"]), float(load["mass"]), None if com is None else [float(x) for x in com],
            None if inertia is None else [float(x) for x in inertia])
    given = None if datasheet is None else [(float(k), float(s)) for k, s in datasheet]
    identification = _identify_with_load(robot, arrays, spec, method, options, (given, gains_fit))
    for warning in identification.settings["warnings"]:
        _warnings.warn(f"arash.identify: {warning}", UserWarning, stacklevel=3)
    return identification


def design_excitation(
    robot: Robot,
    *,
    harmonics: Optional[int] = None,
    period_s: Optional[float] = None,
    restarts: Optional[int] = None,
    seed: Optional[int] = None,
    iterations: Optional[int] = None,
    acceleration_limits: Optional[Sequence[float]] = None,
    min_range_fraction: Optional[float] = None,
    min_speed_fraction: Optional[float] = None,
    keep_weak: bool = False,
    quiet: bool = False,
) -> Excitation:
    """Design a persistently exciting Fourier trajectory: the paper's L harmonics over a period
    T, at rest at both ends, minimising the normalised condition number within the limits, each
    joint covering at least ``min_range_fraction`` of its usable range at a peak speed of at least
    ``min_speed_fraction`` of the fastest the series can reach. keep_weak: design for the weak base
    parameters too (by default the design measures only the identifiable ones). None keeps arash's default for each (docs/identification.md); progress goes
    to stderr unless ``quiet``."""
    options = _given(harmonics=harmonics, period_s=period_s, restarts=restarts, seed=seed,
                     iterations=iterations, min_range_fraction=min_range_fraction,
                     min_speed_fraction=min_speed_fraction, keep_weak=keep_weak or None,
                     acceleration_limits=None if acceleration_limits is None else list(acceleration_limits))
    return _design_excitation(robot, options, quiet)


def diagnose(
    robot: Robot,
    t: Any,
    q: Any,
    tau: Any,
    *,
    model: Optional[Identification] = None,
    validation: Optional[Union[tuple[Any, Any, Any], Sequence[tuple[Any, Any, Any]]]] = None,
    transmission: Optional[Sequence[float]] = None,
    cutoff_hz: Optional[float] = None,
    friction_cutoff_hz: Optional[float] = None,
    order: Optional[int] = None,
    block_s: Optional[float] = None,
    batch_s: Optional[float] = None,
    alpha: Optional[float] = None,
    min_gain: Optional[float] = None,
    effects: Optional[Sequence[str]] = None,
    torque_from_currents: Optional[bool] = None,
    refit: Optional[bool] = None,
    hold_friction: Optional[bool] = None,
    consistent: Optional[bool] = None,
    consistent_cutoff_hz: Optional[float] = None,
    motor_side: Optional[Transmission] = None,
    repair: bool = False,
    currents: bool = False,
    start: Optional[str] = None,
) -> Diagnosis:
    """Find what the declared model lacks in a log, and the error before and after.

    robot: a ``Robot``. t (N,), q and tau (N, dof), SI units, uniformly sampled.
    model: an ``Identification`` to diagnose against (its inertial parameters held, friction
        refitted and kept where it predicts the held-out data better); no joint ends predicting
        the held-out data worse than it (``Diagnosis.reverted`` lists what was put back, and
        ``error_before`` is this model as it is); default: as ``start`` says.
    start: without a model, ``"identified"`` (default: start from ``identify``'s model of this
        log, its declared parameters refitted with the effects, or held, with friction refitted
        where it predicts better, where the refit predicts a joint of a held-out run worse;
        ``settings["started_from"]``) or ``"declared"`` (the declared model refitted at the
        diagnosis's band).
    validation: a tuple ``(t, q, tau)`` held out for ranking and the held-out errors, or a list of
        such runs recorded one after another (each run is filtered on its own: nothing across the
        jump from one to the next); default: the odd-numbered blocks of the training log.
    transmission: joint motion per motor radian, per joint (enables the cogging search).
    cutoff_hz, friction_cutoff_hz, order: the preprocessing, as ``identify`` takes it (None: the
    band chosen from the data, the widest in which the declared model predicts held-out torque as
    well as in the best, reported in ``settings["reasons"]``; the friction velocity at that
    cut-off, slower where the encoder's steps would blur the friction columns' finest speed
    scale; order 5). A robot that declares no Coulomb law gets each joint's from the data. effects: identifiers to search (docs/diagnosis.md; default: all but drive_gain).
    torque_from_currents: the torque was computed from motor currents; search drive_gain too. refit: with a model, refit all its base
    parameters too. hold_friction: with a model, hold its friction too. consistent: also fit the
    physically consistent model with the effects found (``Diagnosis.model_consistent``), at
    ``consistent_cutoff_hz`` (default: the diagnosis's cut-off; the calibration's own is the
    better choice).
    block_s: the held-out split's blocks without a validation log (2 s). batch_s: the Wald test's
    batches (None: each test chooses from its own scores).
    The other options are the decision rule's (docs/diagnosis.md). None keeps arash's default for
    each; ``DiagnoseOptions()`` shows them. motor_side: a ``Transmission`` when q and tau (and the
    validation's) are motor angles and motor torques; it also gives the cogging search its ratios
    (unless ``transmission`` is given) and the ``coupled_rotor`` search its coupled motors.
    repair: repair the log and each validation run first (``repair_log``); what it did heads
    ``settings["reasons"]``.
    currents: tau (and the validation's) are motor currents and ``model`` was calibrated from
    currents with a known load (``identify(..., loaded=, load=)``): each joint's torque is its
    calibrated gain times its current, so that a payload comes out in kilograms, and a gain that
    changed since is searched as ``drive_gain`` (docs/currents.md).
    """
    report: list[dict[str, Any]] = []
    if repair:
        (t, q, tau), report = _repaired((t, q, tau), "training log")
        if isinstance(validation, list):
            runs = [_repaired(run, f"validation[{k}]") for k, run in enumerate(validation)]
            validation, report = [r for r, _ in runs], report + [line for _, lines in runs for line in lines]
        elif validation is not None:
            validation, lines = _repaired(validation, "validation log")
            report += lines
    if currents:
        gains = None if model is None or model.drive_gains is None else model.drive_gains["gains"]
        if gains is None:
            raise ValueError("currents=True needs a model calibrated from currents with a known load "
                             "(arash.identify(..., loaded=, load=))")
        tau = _np.asarray(tau, dtype=float) * gains
        if isinstance(validation, list):
            validation = [(r[0], r[1], _np.asarray(r[2], dtype=float) * gains) for r in validation]
        elif validation is not None:
            validation = (validation[0], validation[1], _np.asarray(validation[2], dtype=float) * gains)
        torque_from_currents = True
    validation, starts = _runs(validation)
    if motor_side is not None:
        q, tau = motor_side.to_joints(q, tau)
        if validation is not None:
            validation = (validation[0], *motor_side.to_joints(validation[1], validation[2]))
    options = DiagnoseOptions(**_given(
        transmission=None if transmission is None else list(transmission), cutoff_hz=cutoff_hz,
        friction_cutoff_hz=friction_cutoff_hz, order=order, block_s=block_s, batch_s=batch_s, alpha=alpha, min_gain=min_gain,
        effects=None if effects is None else list(effects), torque_from_currents=torque_from_currents,
        refit=refit, hold_friction=hold_friction, consistent=consistent,
        consistent_cutoff_hz=consistent_cutoff_hz, motor_side=motor_side, start=start))
    return _diagnose(robot, (t, q, tau), options, model, validation, starts, report)


def _repaired(run: Any, label: str) -> tuple[tuple[Any, Any, Any], list[dict[str, Any]]]:
    """``repair_log`` of one ``(t, q, tau)``, its choices labelled with the run (``log``)."""
    if not isinstance(run, tuple) or len(run) != 3:
        raise ValueError(f"{label}: expected a tuple (t, q, tau)")
    r = repair_log(*run)
    return (r.t, r.q, r.tau), [{**c, "log": label} for c in r.choices]


def _runs(validation: Any) -> tuple[Optional[tuple[Any, Any, Any]], list[int]]:
    """One held-out log, and where each run after the first begins: a list of runs is joined
    end to end, each run's times re-based to follow the last one's at its own step."""
    if validation is None or not isinstance(validation, list):
        return validation, []
    if not validation:
        raise ValueError("validation: an empty list of runs")
    ts, qs, taus, starts, start, samples = [], [], [], [], 0.0, 0
    for k, run in enumerate(validation):
        if not isinstance(run, tuple) or len(run) != 3:
            raise ValueError(f"validation[{k}]: expected a tuple (t, q, tau)")
        t = _np.asarray(run[0], dtype=float)
        if t.ndim != 1 or len(t) < 2:
            raise ValueError(f"validation[{k}]: t must be 1-D with at least 2 samples, not shape {t.shape}")
        if k:
            starts.append(samples)
        ts.append(t - t[0] + start)
        start, samples = ts[-1][-1] + (t[1] - t[0]), samples + len(t)
        qs.append(_np.asarray(run[1], dtype=float))
        taus.append(_np.asarray(run[2], dtype=float))
    return (_np.concatenate(ts), _np.concatenate(qs), _np.concatenate(taus)), starts


def heldout_errors(
    model: Identification,
    t: Any,
    q: Any,
    tau: Any,
    *,
    motor_side: Optional[Transmission] = None,
) -> dict[str, Any]:
    """Per-joint errors of ``model`` on a log it was not fitted on, the effects a diagnosis added
    included: ``rms``, ``fp_percent`` and ``rel`` (‖e‖/‖τ‖), numpy arrays. Nothing is refitted;
    the log is filtered as the diagnosis filters. ``model.without_effects()`` scores the declared
    part alone, so the two give an effect's gain on data that did not choose it.
    (``Identification.validate`` scores the declared part, at the identification's cut-off.)
    """
    d = diagnose(model.robot, t, q, tau, model=model, hold_friction=True, effects=[], motor_side=motor_side)
    return d.error_before_training
