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
from support.yardstick import SIGMAS, assert_no_joint_worse, excess_in_sigmas, relative, yardstick
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


def test_started_from_the_identification_the_kuka_is_no_worse_on_either_held_out_run(kuka):
    """``start="identified"`` with runs 2 and 3 held out together: each run is held to the
    identification on its own. Refitted with the effects, joint 4 predicted run 3 a fifth worse
    while run 2 gained (together, within the noise); the guard now sees that run alone, and the
    diagnosis holds the identified parameters instead, keeping the gains that lose nowhere."""
    robot, identified = kuka
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = arash.diagnose(robot, *kuka_run(1), start="identified", validation=[kuka_run(2), kuka_run(3)])
    assert d.settings["started_from"] == "identified"
    first = d.settings["choices"][0]
    assert first["code"] == "diagnosis_from_identified" and first["periods"] == 2, first
    assert "before: the model identified on this log, as it is" in d.report()
    gains = [assert_no_joint_worse(identified, d.model, kuka_run(run), f"KUKA run {run}") for run in (2, 3)]
    assert any(np.any(after < 0.9 * before) for before, after in gains), d.report()


def test_started_from_the_identification_with_run_2_held_out_the_refit_is_kept(kuka):
    """Run 2 alone held out: the declared parameters refitted with the effects predict no joint
    of it worse than the identification, so the refit is kept, and it gains where the
    identification lacked an offset (the first and the last three joints)."""
    robot, identified = kuka
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = arash.diagnose(robot, *kuka_run(1), start="identified", validation=kuka_run(2))
    assert d.settings["choices"][0]["refitted"] and not d.still_worse, d.report()
    before, after = assert_no_joint_worse(identified, d.model, kuka_run(2), "KUKA run 2 held out")
    assert np.sum(after < 0.75 * before) >= 3, (before, after)


def test_a_refit_that_loses_on_one_held_out_run_is_reported_though_another_gains(kuka):
    """Refitted against the identification with runs 2 and 3 held out together: joints 2 and 4
    lose on run 3 (in another part of the joint space), within the noise of the two runs pooled.
    Each run is held to the start on its own, so ``still_worse`` names them (before, it was
    empty); every joint it names is predicted worse on some run on the independent yardstick too,
    and none the yardstick finds worse beyond its noise is missing."""
    robot, identified = kuka
    d = arash.diagnose(robot, *kuka_run(1), model=identified, refit=True, validation=[kuka_run(2), kuka_run(3)])
    reported = {w["joint"] for w in d.still_worse}
    assert reported and "still worse than the starting model" in d.report(), d.report()
    lost = set()
    for run in (2, 3):
        (e_i, e_d), tau, batch = yardstick([identified, d.model], *kuka_run(run))
        z = excess_in_sigmas(e_d, e_i, batch)
        ratio = relative(e_d, tau) / relative(e_i, tau)
        print(f"\nrun {run}: ‖e‖ ratio {np.round(ratio, 3)}, excess in σ {np.round(z, 1)}; reported {sorted(reported)}")
        assert {robot.joint_names()[k] for k in np.flatnonzero(z > SIGMAS)} <= reported, (run, z, reported)
        lost |= {robot.joint_names()[k] for k in np.flatnonzero(ratio > 1.0)}
    assert reported <= lost, (reported, lost)


def test_started_from_the_identification_a_third_run_is_no_worse_in_the_slow_torque():
    """A TX40 log of the declared model (no effect): the refit against the identification, kept
    at the diagnosis's band (20 Hz; the identification's cut-off 4 Hz), predicted a third
    run's slow torque worse than the identification, joint 1 by 2.7× and joint 4 by 1.7× on the
    8 Hz yardstick, while at the band no joint was worse. The guard now holds each joint to the
    identification in its own band too, so the refit is not kept. (The other null conditions'
    small losses are in docs/diagnosis.md, "Where it starts".)"""
    from test_diagnosis_independent import logs

    condition = Condition("tx40", 1000, 14, 0.01, "tanh", None, 30.0, seed=16)
    robot, train, held, third = logs(condition, more=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        identified = arash.identify(robot, *train)
        d = arash.diagnose(robot, *train, validation=held, start="identified")
    assert d.settings["started_from"] == "identified" and d.accepted == [], d.report()
    # The refit was not kept, for a loss found in the identification's own band, and said so.
    first = d.settings["choices"][0]
    assert not first["refitted"] and first["worse"], first
    assert all(w["band_hz"] == pytest.approx(identified.cutoff_hz) for w in first["worse"]), first
    assert "in the starting model's band" in first["text"], first["text"]
    for label, run in (("held out", held), ("third run", third)):
        assert_no_joint_worse(identified, d.model, run, f"{condition.label}, {label}")
