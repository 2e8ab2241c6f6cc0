"""How often arash.diagnose names an injected effect first, on its joint, across sample rates and
encoder resolutions (issue 19, item 5's table).

The same generator and detection rule as ``diagnosis_power.py`` (the Pinocchio-based
``tests/python/support/independent.py``, the declared ARASH:ASiST model, 1 % torque noise, sign(q̇)
Coulomb friction, aperiodic 30 s logs, no validation log), each effect at 15 % of its joint's RMS
torque; here the sample rate and the encoders vary. ``drive_gain`` is left out: it is searched
only when the torque comes from currents and is measured against a calibrated model
(``test_diagnosis_independent.py``).

    .venv/bin/python bench/diagnosis_injected.py [SEEDS]     # default 10 seeds per cell
"""

import sys
import time

from diagnosis_power import EFFECTS, detected  # noqa: E402  (also puts tests/python on the path)

import arash  # noqa: E402
from support.independent import Condition, Injected, make_log  # noqa: E402

RATES = [200, 1000]
BITS = [12, 16, 20]
SIZE = 0.15


def main():
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    columns = [(fs, bits) for fs in RATES for bits in BITS]
    print("| effect, joint | " + " | ".join(f"{fs} Hz, {bits}-bit" for fs, bits in columns) + " |")
    print("|---|" + "---|" * len(columns))
    times, total, hits = [], 0, 0
    for kind, joint in EFFECTS:
        effect = Injected(kind, joint, SIZE)
        cells = []
        for fs, bits in columns:
            found = 0
            for seed in range(seeds):
                robot, train, _ = make_log(Condition("arash_asist", fs, bits, 0.01, "sign", None, 30.0,
                                                     seed=8000 + seed), effect=effect)
                t0 = time.perf_counter()
                d = arash.diagnose(robot, *train)
                times.append(time.perf_counter() - t0)
                found += detected(d, effect)
            cells.append(f"{found}/{seeds}")
            total, hits = total + seeds, hits + found
        name = robot.joint_names()[joint]
        print(f"| {kind}, {name} | " + " | ".join(cells) + " |", flush=True)
    times.sort()
    print(f"\nnamed first on its joint in {hits} of {total} logs; median diagnosis {times[len(times) // 2]:.2f} s")


if __name__ == "__main__":
    main()
