"""The opt-in log repair (issue 45, item 3): logs as real controllers write them, with a corrupt
block at the start, a bad last row, missed samples and samples stamped early. The logs are
Pinocchio's (tests/python/support/independent.py), the reference for the resampling is numpy's
``interp``, and the check of the whole path is the fit of the same robot from a uniform log."""

import json
import subprocess

import numpy as np
import pytest

import arash
from support.independent import Condition, designed_excitation, make_log
from support.paths import ARASH

CONDITION = Condition("arash_asist", 1000, 16, 0.0, "tanh", 4, 60.0, seed=3, designed=True)
DT = 1.0 / CONDITION.fs
MISSED = [5000, 12000, 20000, 33000, 41000, 52000]
EARLY = [7000, 15000, 26000, 38000, 47000, 56000]
LEADING = 4


def irregular_log(truth):
    """The designed excitation sampled where a real controller's log would have it: six samples
    missed, six taken 0.6 of a step early, then a block of four rows from another clock at the
    start and a last row whose torque is not finite. Returns (t, q, tau) and the same robot's
    uniform log's truth."""
    t = np.arange(int(CONDITION.duration * CONDITION.fs)) * DT
    t[EARLY] -= 0.6 * DT
    t = np.delete(t, MISSED)
    robot, (t, q, tau), _ = make_log(CONDITION, states=(t, *designed_excitation(t)), truth=truth)
    rng = np.random.default_rng(1)
    lead_t = 1000.0 + np.arange(LEADING) * DT
    t = np.concatenate([lead_t, t])
    q = np.vstack([rng.normal(size=(LEADING, 3)), q])
    tau = np.vstack([rng.normal(size=(LEADING, 3)), tau])
    tau[-1, 2] = np.nan
    return robot, (t, q, tau)


@pytest.fixture(scope="module")
def logs():
    t = np.arange(int(CONDITION.duration * CONDITION.fs)) * DT
    robot, uniform, truth = make_log(CONDITION, states=(t, *designed_excitation(t)))
    robot = arash.Robot.from_urdf(robot_path(), friction_velocities=[0.01] * 3)
    _, irregular = irregular_log(truth)
    return robot, uniform, irregular


def robot_path():
    from support.independent import urdf_path

    return urdf_path("arash_asist")


def test_the_repair_trims_the_corrupt_rows_and_interpolates_as_numpy_does(logs):
    _, _, (t, q, tau) = logs
    r = arash.repair_log(t, q, tau, q[:, :1])
    kept = slice(LEADING, len(t) - 1)
    start, end, resampled = r.choices
    assert (start["code"], start["end"], start["first"], start["last"]) == ("trimmed", "start", 0, LEADING - 1), start
    assert start["why"]["code"] == "time_goes_back" and start["why"]["row"] == LEADING, start
    last = len(t) - 1
    assert (end["end"], end["first"], end["last"], end["why"]) == (
        "end", last, last, {"code": "not_finite", "row": last, "signal": "tau"}), end
    assert resampled["code"] == "resampled" and resampled["first"] == LEADING, resampled
    assert r.report == [c["text"] for c in r.choices]
    # The grid is the median step from the first kept stamp, as long as the kept rows span.
    t0, span = t[kept][0], t[kept][-1] - t[kept][0]
    np.testing.assert_allclose(r.t, t0 + np.arange(round(span / DT) + 1) * DT, rtol=0, atol=1e-9)
    for out, given in ((r.q, q), (r.tau, tau), (r.extra[0], q[:, :1])):
        assert out.shape == (len(r.t), given.shape[1])
        for k in range(given.shape[1]):
            # A grid point within a millionth of a step of a stamp takes that sample exactly
            # (encoder counts stay counts): the most that differs from interpolating is the
            # signal's steepest slope over that millionth.
            slope = np.max(np.abs(np.diff(given[kept, k]) / np.diff(t[kept])))
            expected = np.interp(r.t, t[kept], given[kept, k])
            np.testing.assert_allclose(out[:, k], expected, rtol=0, atol=1e-6 * DT * slope + 1e-15)


def test_a_repaired_log_fits_as_the_uniform_log_of_the_same_robot(logs):
    robot, uniform, irregular = logs
    with pytest.raises(ValueError, match=r"repair=True in Python, --repair on the command line"):
        arash.identify(robot, *irregular)
    clean = arash.identify(robot, *uniform)
    repaired = arash.identify(robot, *irregular, repair=True)
    choices = repaired.settings["choices"]
    trimmed, resampled = choices[0], choices[2]
    assert trimmed["code"] == "trimmed" and trimmed["end"] == "start" and trimmed["last"] == LEADING - 1, choices[:3]
    assert resampled["code"] == "resampled", choices[:3]
    # The stamps taken at face value instead (bad rows dropped, t made uniform): every sample
    # after a missed one is a step late.
    t, q, tau = irregular
    rows = slice(LEADING, len(t) - 1)
    naive = arash.identify(robot, np.arange(len(t[rows])) * DT, q[rows], tau[rows])

    def distance(model):
        """The prediction's distance from the uniform log's fit on the paper's trajectories."""
        worst = 0.0
        for omega in (0.3, 0.5, 0.7, 0.9):
            tt = np.arange(int(round(2 * np.pi / omega * 1000))) / 1000
            state = arash.paper_validation_trajectory(omega, tt)
            reference = clean.predict(*state)
            worst = max(worst, np.linalg.norm(model.predict(*state) - reference) / np.linalg.norm(reference))
        return worst

    near, far = distance(repaired), distance(naive)
    print(f"repaired {near:.2e}, stamps at face value {far:.2e} from the uniform log's fit")
    # Resampled at the stamps, the log fits as the uniform one does, to well within what taking
    # the stamps at face value costs (1.2e-4 when measured; 3e-8 repaired).
    assert near < far / 10 and near < 1e-4, (near, far)


def test_a_break_in_the_middle_is_refused_by_its_rows(logs):
    _, (t, q, tau), _ = logs
    bad = tau.copy()
    bad[30000, 1] = np.inf
    with pytest.raises(ValueError, match=r"the longest usable run is rows 0–29999.*row 30000 has tau not finite"):
        arash.repair_log(t, q, bad)
    with pytest.raises(ValueError, match=r"extra\[0\] must have 60000 rows"):
        arash.repair_log(t, q, tau, q[:-1])


def test_the_cli_repairs_a_csv_on_request_and_records_it(logs, tmp_path):
    if not ARASH.exists():
        pytest.skip(f"{ARASH} not built (cargo build --release)")
    _, _, (t, q, tau) = logs
    names = arash.Robot.arash_asist().joint_names()
    header = ["t"] + [f"q.{n}" for n in names] + [f"tau.{n}" for n in names]
    rows = np.column_stack([t, q, tau]).astype(object)
    rows[0, 1] = "corrupt"  # a cell that is no number at all
    path = tmp_path / "run.csv"
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(str(v) for v in row) for row in rows) + "\n")
    out = tmp_path / "model.json"
    common = [str(ARASH), "identify", str(path), "--friction-velocity", "0.01,0.01,0.01", "-o", str(out)]
    refused = subprocess.run(common, capture_output=True, text=True, timeout=600)
    assert refused.returncode != 0 and "--repair" in refused.stderr, refused.stderr
    done = subprocess.run(common + ["--repair"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "note: " in done.stderr, done.stderr
    reasons = json.loads(out.read_text())["settings"]["reasons"]
    first = reasons[0]
    assert (first["code"], first["log"], first["end"], first["last"]) == ("trimmed", str(path), "start", LEADING - 1), first
    assert first["why"]["code"] == "time_goes_back", first
    assert any(r["code"] == "resampled" for r in reasons[:3]), reasons[:3]
    assert first["text"] in done.stderr, (first["text"], done.stderr)


def test_diagnose_repairs_the_training_log_and_each_held_out_run(logs):
    robot, uniform, irregular = logs
    t, q, tau = irregular
    half = len(t) // 2
    runs = [(t[:half], q[:half], tau[:half]), (t[half:], q[half:], tau[half:])]
    d = arash.diagnose(robot, *irregular, validation=runs, effects=[], repair=True)
    trims = [(c["log"], c["end"], c["first"], c["last"]) for c in d.settings["choices"] if c["code"] == "trimmed"]
    assert trims[0] == ("training log", "start", 0, LEADING - 1), trims
    assert ("validation[0]", "start", 0, LEADING - 1) in trims, trims
    assert any(log == "validation[1]" and end == "end" for log, end, _, _ in trims), trims
    assert d.settings["reasons"][0] == d.settings["choices"][0]["text"]
