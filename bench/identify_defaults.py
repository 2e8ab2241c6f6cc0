"""What the data-driven choices cost (issue 17): `arash.identify` with the defaults (period found,
cut-off searched) against the same cut-offs set by hand, on the issue's
independent log (tests/python/support/independent.py: Pinocchio, ARASH:ASiST, 8 × 10 s at 1 kHz, 16-bit
encoders, 1 % torque noise). Medians of 7 calls.

    .venv/bin/python bench/identify_defaults.py
"""

import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
import arash  # noqa: E402
from support.independent import Condition, make_log  # noqa: E402


def median_seconds(call, repeats=7):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


if __name__ == "__main__":
    warnings.simplefilter("ignore")
    robot, log, _ = make_log(Condition("arash_asist", 1000, 16, 0.01, "sign", 8, 80.0, seed=1))
    chosen = arash.identify(robot, *log)
    fixed = {"cutoff_hz": chosen.cutoff_hz, "friction_cutoff_hz": chosen.settings["friction_cutoff_hz"]}
    print(f"defaults (searched): {median_seconds(lambda: arash.identify(robot, *log)):.3f} s")
    print(f"the same cut-offs set by hand: {median_seconds(lambda: arash.identify(robot, *log, **fixed)):.3f} s")
