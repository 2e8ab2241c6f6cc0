"""arash: dynamics, calibration and control of the ARASH:ASiST haptic robot.

Arrays are numpy float64 in SI units (rad, m, s, N·m, N). A batch of states is an ``(N, dof)``
array; a single ``(dof,)`` vector gives a result without the batch axis.

>>> import arash
>>> robot = arash.Robot.arash_asist()
>>> robot.base_parameters().p
23
"""

import json as _json
import os as _os
from pathlib import Path as _Path

from ._arash import _diagnose, _simulate
from ._arash import (
    BaseParameters,
    Excitation,
    Identification,
    Robot,
    __version__,
    butter,
    consistent_least_squares,
    design_excitation,
    filtfilt,
    identify,
    load_model,
    paper_validation_trajectory,
    read_log,
)

__all__ = [
    "BaseParameters",
    "Diagnosis",
    "Effect",
    "Excitation",
    "Identification",
    "Robot",
    "__version__",
    "butter",
    "consistent_least_squares",
    "design_excitation",
    "diagnose",
    "filtfilt",
    "identify",
    "load_model",
    "paper_validation_trajectory",
    "read_log",
    "simulate",
]


def simulate(
    scenario=None,
    trajectory=None,
    *,
    controller="robust",
    params=None,
    duration=None,
    seed=None,
    robot=None,
    gain_units="si",
    log=None,
    log_truth=False,
):
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
    "qdd", "tau_motor", "motor_q"), "true_params" (P,), "joint_names" and "scenario" (TOML).
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
    return _simulate(robot, scenario_text, scenario_name, trajectory_text, controller, params,
                     duration, seed, gain_units, log, log_truth)


class Effect:
    """An effect the diagnosis accepted: ``name`` (catalogue identifier), ``joints`` (0-based),
    ``coefficients`` and ``sigma`` (numpy), ``columns``, ``p_value``, ``statistic``,
    ``heldout_gain`` (relative cut of the held-out squared error), ``aliases`` (candidates it
    cannot be told from), ``label``, and for a payload ``mass_kg`` and ``body``."""

    def __init__(self, finding):
        import numpy as np

        term = finding["term"]
        self.name = finding["name"]
        self.joints = list(finding["joints"])
        self.label = finding["label"]
        self.columns = list(term["columns"])
        self.coefficients = np.asarray(term["coefficients"], dtype=float)
        self.sigma = np.asarray(term["sigma"], dtype=float)
        self.statistic = finding["statistic"]
        self.p_value = finding["p_value"]
        self.heldout_gain = finding["heldout_gain"]
        self.aliases = list(finding["aliases"])
        self.mass_kg = finding.get("mass_kg")
        self.body = finding.get("body")

    def __repr__(self):
        return f"Effect({self.label!r}, p={self.p_value:.2e}, heldout_gain={self.heldout_gain:.3f})"


class Diagnosis:
    """What ``arash.diagnose`` found (docs/diagnosis.md).

    accepted: list of ``Effect``, in the order they were added.
    rejected: list of dicts with ``name``, ``joints``, ``label`` and ``reason``.
    error_before, error_after: per-joint numpy arrays keyed ``rms``, ``fp_percent`` and ``rel``
        (‖e‖/‖τ‖), on the held-out data; ``error_before_training`` and ``error_after_training``
        are the same on the training data.
    model: the updated model (an ``Identification`` with the effects).
    model_consistent: with ``consistent=True``, the physically consistent model fitted together
        with the effects found (the model the model-based controllers accept); else None.
    series: the signals behind the residual plots (dict of numpy arrays).
    """

    def __init__(self, raw):
        import numpy as np

        self._raw = raw
        data = _json.loads(raw.to_json())
        self.accepted = [Effect(f) for f in data["accepted"]]
        self.rejected = data["rejected"]
        self.settings = data["settings"]
        self.joint_names = data["joint_names"]

        def errors(metrics):
            return {
                "rms": np.asarray(metrics["rms"], dtype=float),
                "fp_percent": np.asarray(metrics["fp_percent"], dtype=float),
                "rel": np.asarray(metrics["relative_error"], dtype=float),
            }

        self.error_before = errors(data["before"]["heldout"])
        self.error_after = errors(data["after"]["heldout"])
        self.error_before_training = errors(data["before"]["training"])
        self.error_after_training = errors(data["after"]["training"])
        self.model = raw.model
        self.model_consistent = raw.model_consistent

    @property
    def series(self):
        return self._raw.series

    def report(self):
        """The report as text: effects with evidence, errors before and after, rejections."""
        return self._raw.report()

    def to_json(self):
        return self._raw.to_json()

    def __repr__(self):
        return f"Diagnosis(accepted={[e.label for e in self.accepted]})"


def diagnose(robot, t, q, tau, *, model=None, validation=None, **options):
    """Find what the declared model lacks in a log, and the error before and after.

    robot: a ``Robot``. t (N,), q and tau (N, dof), SI units, uniformly sampled.
    model: an ``Identification`` to diagnose against (its inertial parameters held, friction
        refitted); default: refit the declared model.
    validation: a tuple ``(t, q, tau)`` held out for ranking and the held-out errors; default:
        the odd-numbered 2 s blocks of the training log.
    options: ``transmission`` (joint motion per motor radian, per joint; enables the cogging
        search), ``cutoff_hz`` (20), ``block_s`` (2), ``alpha`` (0.01), ``min_gain`` (0.2),
        ``effects`` (list of identifiers to search), ``refit`` (False: with a model, refit only
        its friction), ``hold_friction`` (False: with a model, True holds its friction too),
        ``consistent`` (False: True also fits the physically consistent model with the effects
        found, as ``model_consistent``), ``consistent_cutoff_hz`` (that fit's cut-off; default
        ``cutoff_hz``; the calibration's own is the better choice, see docs/diagnosis.md).
    """
    return Diagnosis(_diagnose(robot, t, q, tau, model=model, validation=validation, **options))
