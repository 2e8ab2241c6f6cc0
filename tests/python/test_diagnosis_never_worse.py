"""Issue 59, item 1: a diagnosis against an identified model never leaves a joint predicting a
held-out run worse than that model, beyond the yardstick's sampling error.

The yardstick is the tests' own, not arash's (``support/yardstick.py``: scipy's zero-phase
Butterworth at 8 Hz, ‖e‖/‖τ‖ per joint, "worse" beyond two standard errors of 1 s batch means).
On runs nobody here recorded (the KUKA's, ../shared/data; the TX40's in test_real_data.py) and on
Pinocchio's dynamics with an effect the declared model lacks.
"""

import warnings

import numpy as np
import pytest

import arash
from support.yardstick import assert_no_joint_worse
from test_real_data import KUKA, kuka_run, need


@pytest.fixture(scope="module")
def kuka():
    robot = arash.Robot.from_urdf(need(KUKA / "kuka_lwr4.urdf"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # two periods only, said in settings["warnings"]
        return robot, arash.identify(robot, *kuka_run(1))


def test_the_kuka_diagnosed_against_its_identification_predicts_runs_2_and_3_no_worse(kuka):
    """Trained on run 1 alone (held-out blocks): the runs it never saw, 2 and 3 (3 in another
    part of the joint space), are predicted no worse on any joint. Without the guard the
    friction refitted on run 1 predicted joints 2, 4, 6 and 7 worse than the identification on
    its own held-out blocks; the report says what was put back."""
    robot, identified = kuka
    d = arash.diagnose(robot, *kuka_run(1), model=identified)
    assert d.reverted and all(r["rms_after"] <= r["rms_before"] for r in d.reverted), d.reverted
    assert "Kept no worse than the starting model" in d.report()
    for run in (2, 3):
        assert_no_joint_worse(identified, d.model, kuka_run(run), f"KUKA run {run}")


def test_with_run_2_held_out_the_kuka_diagnosis_predicts_it_better_and_no_joint_worse(kuka):
    """Run 2 as the validation log: the effects found cut its error where they act, and no joint
    is worse than the identification on it; the report's "before" is the identification as it
    is, not a refit of it."""
    robot, identified = kuka
    d = arash.diagnose(robot, *kuka_run(1), model=identified, validation=kuka_run(2))
    before, after = assert_no_joint_worse(identified, d.model, kuka_run(2), "KUKA run 2 held out")
    assert d.accepted and np.any(after < 0.9 * before), d.report()
    assert "before: the given model as it is" in d.report()


pytest.importorskip("pinocchio")
from support.independent import Condition, Injected, make_log  # noqa: E402

# A configuration disturbance on one joint at 15 % of its torque, on Pinocchio's dynamics of
# each declared robot (16-bit encoders, 1 % noise, sign(q̇), aperiodic): trained, held out and
# judged on three runs of the same robot.
CASES = [("arash_asist", 2, 9300), ("kuka", 1, 9310)]


@pytest.mark.parametrize("name,joint,seed", CASES, ids=lambda v: str(v))
def test_a_diagnosis_against_an_identified_model_is_no_worse_on_a_third_run(name, joint, seed):
    effect = Injected("configuration_disturbance", joint, 0.15)
    shape = (name, 1000, 16, 0.01, "sign", None, 20.0)
    robot, train, truth = make_log(Condition(*shape, seed=seed), effect=effect)
    runs = [make_log(Condition(*shape, seed=seed + k), truth=truth, effect=effect)[1] for k in (1, 2)]
    identified = arash.identify(robot, *train)
    d = arash.diagnose(robot, *train, model=identified, validation=runs[0])
    before, after = assert_no_joint_worse(identified, d.model, runs[1], f"{name}, third run")
    # Some joint gains: the guard does not simply hand the identification back. (On the KUKA the
    # identification, fitted on the same log, takes up most of the disturbance on joint 2, and
    # the diagnosis names a payload on the last link that cuts joint 7's error by a third.)
    assert np.any(after < 0.9 * before), d.report()
