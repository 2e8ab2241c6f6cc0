"""The cut-off chosen from closed-loop data (issues 17 and 18): logs from ``closed_loop.py``, a
PD loop with feed-forward on Pinocchio's dynamics, whose torque carries the controller's response
to the encoders' noise. With no option set, the model must predict an open-loop log of the same
robot within a point of the best any cut-off gives.
"""

import warnings

import numpy as np
import pytest

pytest.importorskip("pinocchio")
import arash  # noqa: E402

from support.closed_loop import closed_loop_log  # noqa: E402
from support.independent import Condition, make_log  # noqa: E402

CONDITIONS = [
    # Two periods of arash's designed excitation, 16-bit encoders: the daemon's calibration run.
    (Condition("arash_asist", 1000, 16, 0.01, "tanh", 2, 30.0, seed=1, designed=True), 5.0),
    # Coarse encoders under a stiffer loop: the noise's response is 87 % of the unfiltered torque.
    # The cut-off is not the trouble here (every one predicts alike); the friction velocity is.
    # Measured 2026-11-26 at the chosen 1.33 Hz (mean validation FP% by friction cut-off, the
    # training fit beside it): 12 Hz 96.5 (train 97.1), 21 Hz 97.6 (97.7), 24 Hz 98.0 (98.0),
    # 30 Hz 98.5 (98.5), 34 Hz 97.7 (98.6), 43 Hz 92.8 (96.6). The training fit follows the
    # validation up to a cliff near 32 Hz, where the encoders' noise starts to flip the sign,
    # and peaks just past it; the octave grid (…, 21, 43 Hz) misses the top, and a finer grid
    # lands on either side of the cliff by chance.
    # Measured 2026-11-29 over seeds 2-6 (default against best cut-off, validation FP%): 97.99/98.28,
    # 98.05/98.59, 97.29/98.46, 96.03/98.24, 97.26/98.61. The default's friction cut-off is the
    # best of the octave grid on every seed (yaw at 0.67 Hz, seed 5: 21 Hz 65.8, 43 Hz 89.6,
    # 85 Hz 23.5), so the gap is the grid's coarseness at the cliff; seed 2 passes by 0.7 points
    # and failed a strict xfail in CI. Not strict: the outcome is a coin toss near the cliff,
    # not the signal of a fix.
    pytest.param(
        Condition("arash_asist", 1000, 12, 0.01, "tanh", 4, 60.0, seed=2, designed=True),
        10.0,
        marks=pytest.mark.xfail(
            strict=False, reason="closed loop: the friction cut-off's octave grid straddles the noise cliff"
        ),
    ),
]


def validation_fp(model, log):
    return float(np.mean(model.validate(*log, periods=1)["fp_percent"]))


@pytest.mark.parametrize("condition,loop_hz", CONDITIONS, ids=["16bit 2 periods", "12bit stiff loop"])
def test_a_closed_loop_log_is_fitted_as_well_as_the_best_cutoff_allows(condition, loop_hz):
    robot, log, truth = closed_loop_log(condition, loop_hz=loop_hz)
    # The same robot on another trajectory, open loop and noise-free: what the model is for.
    other = Condition("arash_asist", 1000, 20, 0.0, "tanh", 1, 20.0, seed=condition.seed + 100)
    _, validation, _ = make_log(other, truth={**truth, "noise": 0.0 * truth["noise"]})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        default = arash.identify(robot, *log)
        by_cutoff = {}
        for cutoff in np.geomspace(0.5, 250.0, 14):
            try:
                by_cutoff[float(cutoff)] = validation_fp(arash.identify(robot, *log, cutoff_hz=float(cutoff)), validation)
            except ValueError:  # a cut-off the log cannot be filtered or fitted at is no candidate
                continue
    chosen = validation_fp(default, validation)
    best = max(by_cutoff.values())
    table = ", ".join(f"{c:.2f} Hz {fp:.2f}" for c, fp in by_cutoff.items())
    print(f"{condition.label}: default {default.cutoff_hz:.2f} Hz {chosen:.2f}; by cut-off: {table}")
    # The grid must reach the cut-offs that let the noise in, or the comparison proves nothing.
    assert min(by_cutoff.values()) < best - 5.0, table
    assert chosen >= best - 1.0, f"default {default.cutoff_hz:.2f} Hz gives {chosen:.2f}; {table}"
