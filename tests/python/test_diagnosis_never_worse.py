"""Issue 59, item 1: a diagnosis against an identified model never leaves a joint predicting a
held-out run worse than that model, beyond the yardstick's sampling error.

The yardstick is this file's own, not arash's: scipy's zero-phase Butterworth at 8 Hz on q and τ,
numpy's differences for q̇ and q̈, each model's ``predict``, and ‖e‖/‖τ‖ per joint over the run
(its filter's start-up left out). "Worse" is the mean over samples of e_diagnosed² − e_identified²
above twice its standard error from 1 s batch means. On runs nobody here recorded (the KUKA's,
../shared/data) and on Pinocchio's dynamics with an effect the declared model lacks.
"""

import warnings

import numpy as np
import pytest
from scipy.signal import butter, filtfilt

import arash
from test_real_data import KUKA, kuka_run, need

CUTOFF_HZ = 8.0  # the common yardstick
BATCH_S = 1.0
SIGMAS = 2.0


def yardstick(models, t, q, tau):
    """Per model, the residual on the filtered run; the filtered torque; samples per batch."""
    fs = 1.0 / np.median(np.diff(t))
    b, a = butter(4, CUTOFF_HZ / (fs / 2))
    qf, tauf = filtfilt(b, a, q, axis=0), filtfilt(b, a, tau, axis=0)
    qd = np.gradient(qf, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    edge = 3 * int(fs / CUTOFF_HZ)
    inner = slice(edge, len(t) - edge)
    return [(tauf - m.predict(qf, qd, qdd))[inner] for m in models], tauf[inner], max(1, int(BATCH_S * fs))


def excess_in_sigmas(diagnosed, identified, batch):
    """Per joint, the mean of e_d² − e_i² in standard errors of batch means (0 where equal)."""
    d = diagnosed**2 - identified**2
    n = len(d) // batch
    means = d[: n * batch].reshape(n, batch, -1).mean(axis=1)
    se = means.std(axis=0, ddof=1) / np.sqrt(n)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(se > 0, d.mean(axis=0) / se, 0.0)


def relative(e, tau):
    return np.linalg.norm(e, axis=0) / np.linalg.norm(tau, axis=0)


def assert_no_joint_worse(identified, diagnosed, run, label):
    (e_i, e_d), tau, batch = yardstick([identified, diagnosed], *run)
    z = excess_in_sigmas(e_d, e_i, batch)
    print(f"\n{label}: ‖e‖/‖τ‖ identified {np.round(relative(e_i, tau), 3)}, "
          f"diagnosed {np.round(relative(e_d, tau), 3)}; excess in σ {np.round(z, 1)}")
    assert np.all(z <= SIGMAS), (label, z)
    return relative(e_i, tau), relative(e_d, tau)


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
    assert "before (the given model as it is)" in d.report()


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
