"""The paper's tracking result on the simulated rig when the declared model describes it: the
demo's calibration (its excitation design, logged in closed loop under inverse dynamics control
with CAD, fitted by IDIM-IV) covers the rig's own parameters, and its consistent form gives a robust
controller that halves the CAD baseline's maximum error and tracks as the rig's own parameters do. On the demo's rig, whose undeclared
effects leave no model of the declared form able to halve it, `tests/demo.rs` checks the rest.

The truth is the simulator's, so this checks the demo's pipeline end to end, not the estimator
against an independent reference (tests/python/test_closed_loop_identification.py does that)."""

import json
import warnings

import numpy as np
import pytest

import arash
from support.paths import ROOT

NOMINAL = ROOT / "scenarios" / "nominal.toml"
OMEGA = 0.5
PERIOD = 2 * np.pi / OMEGA


def max_error(controller, params, seed):
    """The maximum tracking error per joint over the second of two periods of the paper's ω = 0.5
    trajectory (the first holds the start-up transient), as `arash demo` scores it."""
    run = arash.simulate(NOMINAL, {"kind": "paper-validation", "omega": OMEGA}, controller=controller,
                         params=params, duration=2 * PERIOD, seed=seed)
    second = run["t"] >= run["t"][0] + PERIOD
    return np.abs(run["q"][second] - run["q_des"][second]).max(axis=0)


# Seeds 2 and 3 are the long tier's (scripts/test --full): other draws of the same rig; `demo.rs`
# runs the demo's own rig in the suite.
@pytest.mark.parametrize("seed", [1, pytest.param(2, marks=pytest.mark.full), pytest.param(3, marks=pytest.mark.full)])
def test_the_identified_model_covers_the_truth_and_halves_cads_tracking_error_on_a_rig_the_model_describes(seed):
    robot = arash.Robot.arash_asist()
    # `arash demo --restarts 1`'s design and 60 s of it; the seed also draws the rig's parameters.
    design = arash.design_excitation(robot, seed=seed, restarts=1, quiet=True)
    run = arash.simulate(NOMINAL, json.loads(design.to_json()), controller="idc-cad",
                         duration=4 * design.period_s, seed=seed)
    closed_loop = dict(reference=(run["q_des"], run["qd_des"], run["qdd_des"]), controller=run["logged_controller"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        estimate = arash.identify(robot, run["t"], run["q"], run["tau_meas"], method="idim-iv", **closed_loop)
        model = arash.identify(robot, run["t"], run["q"], run["tau_meas"], method="idim-iv-consistent",
                               **closed_loop)
    # The closed-loop estimate covers the rig's own base parameters (issue 18's ≥ 90 %).
    truth = estimate.base.project(run["true_params"])
    z = (estimate.beta - truth) / (estimate.sigma_percent / 100 * np.abs(estimate.beta))
    assert np.sum(np.abs(z) <= 3) >= 0.9 * len(z), np.round(z, 1)
    cad = max_error("idc-cad", "cad", seed)
    own = max_error("robust", "truth", seed)
    identified = max_error("robust", model, seed)
    print(f"seed {seed}: cut against CAD by the rig's own parameters {np.round(cad / own, 2)}, "
          f"by the identified model {np.round(cad / identified, 2)}")
    assert np.all(identified <= 0.5 * cad), (cad, identified)
    # Within the paper's bounds: 0.35° for the rotations, 128 µm for the insertion.
    assert np.degrees(identified[:2]).max() < 0.35 and identified[2] < 128e-6, identified
    # As well as the rig's own parameters, to a quarter: what they leave is 9–13 encoder steps on
    # yaw and pitch and 3 on the insertion, where one step moves a maximum by a third. The demo's earlier design
    # (no least range or speed) fails this on the insertion: 4.5 times the truth's error on seed 1.
    assert np.all(identified <= 1.25 * own), (own, identified)
