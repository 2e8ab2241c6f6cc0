"""The preprocessing choices over the whole range of conditions (issue 17): random logs from the
independent generator (tests/python/support/independent.py: Pinocchio, ARASH:ASiST, KUKA LWR4+ and TX40;
100 Hz to 5 kHz; 12 to 20 bits; 0.5 to 5 % torque noise; sign or tanh Coulomb; 2 to 20 periods
or aperiodic; 5 to 300 s), each identified with the defaults and compared with the best single
cut-off of the test's grid (those that pass the trajectory).

    .venv/bin/python bench/preprocessing_sweep.py SEED COUNT      # needs ../shared/data for KUKA/TX40

Prints one line per log ("ok" when the defaults' mean training FP% is within a point of the best)
and the number of misses.
"""

import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
import arash  # noqa: E402
from support.independent import Condition, make_log  # noqa: E402
from support.references import fits_by_cutoff  # noqa: E402

# Longer logs than this many samples make the Pinocchio generator (a Python loop) too slow.
MOST_SAMPLES = 150_000


def random_condition(rng):
    while True:
        robot = str(rng.choice(["arash_asist", "kuka", "tx40"]))
        fs = float(rng.choice([100, 200, 1000, 5000]))
        duration = float(rng.choice([5, 10, 30, 60, 120, 300]))
        periods = int(rng.integers(2, 21)) if rng.random() < 0.6 else None
        if (periods and duration / periods < 2) or fs * duration > MOST_SAMPLES:
            continue
        return Condition(robot, fs, int(rng.integers(12, 21)), float(rng.choice([0.005, 0.01, 0.02, 0.05])),
                         str(rng.choice(["sign", "tanh"])), periods, duration, seed=int(rng.integers(1000)))


def main(seed, count):
    warnings.simplefilter("ignore")
    rng = np.random.default_rng(seed)
    misses = 0
    for _ in range(count):
        c = random_condition(rng)
        robot, log, _ = make_log(c)
        start = time.perf_counter()
        try:
            ident = arash.identify(robot, *log)
        except ValueError as refused:
            print(f"refused {c.label} (seed {c.seed}): {refused}")
            continue
        seconds = time.perf_counter() - start
        grid = fits_by_cutoff(robot, log, c.fs, c.top_frequency)
        best = grid[np.argmax(grid.mean(axis=1))].mean()
        gap = best - ident.fp_percent.mean()
        misses += gap > 1.0
        print(f"{'ok  ' if gap <= 1.0 else 'MISS'} {c.label} (seed {c.seed}): cut-off {ident.cutoff_hz:.2f} Hz, "
              f"friction {ident.settings['friction_cutoff_hz']:.2f} Hz, FP% {ident.fp_percent.mean():.2f} against "
              f"{best:.2f} at best ({gap:+.2f}), {seconds:.1f} s", flush=True)
    print(f"{misses} of {count} more than a point below the best cut-off")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 0, int(sys.argv[2]) if len(sys.argv) > 2 else 20)
