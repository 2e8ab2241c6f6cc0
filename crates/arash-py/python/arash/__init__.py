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

from ._arash import _simulate
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
    "Excitation",
    "Identification",
    "Robot",
    "__version__",
    "butter",
    "consistent_least_squares",
    "design_excitation",
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
