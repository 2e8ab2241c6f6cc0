"""How often arash.diagnose accepts anything on logs of the declared model (issue 19's null).

Each log comes from the independent Pinocchio generator (tests/python/support/independent.py) with a
validation log of the same robot beside it; the robot is loaded as a new user loads it (no option
set, so its Coulomb law is sign(q̇) even where the log's is tanh), and a tanh log is diagnosed a
second time with its law declared (`coulomb_epsilon`): that row is the declared model's null, the
first a law the user got wrong. Prints a markdown table: per condition, the logs on which
anything was accepted, and what.

    .venv/bin/python bench/diagnosis_null.py [SEEDS] [TEXT]   # default 20 seeds per condition;
                                                              # TEXT: only conditions whose label has it
"""

import collections
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
import arash  # noqa: E402
from support.independent import TANH_EPSILON, Condition, make_log, urdf_path  # noqa: E402

# robot, fs (Hz), encoder bits, torque noise (share of RMS), Coulomb law, periods, duration (s)
CONDITIONS = [
    ("arash_asist", 1000, 16, 0.01, "sign", 8, 80.0),
    ("arash_asist", 200, 16, 0.01, "sign", None, 30.0),
    ("arash_asist", 1000, 20, 0.005, "sign", None, 10.0),
    ("arash_asist", 1000, 12, 0.02, "tanh", 4, 40.0),
    ("arash_asist", 200, 12, 0.05, "tanh", None, 10.0),
    ("arash_asist", 5000, 16, 0.01, "sign", 2, 10.0),
    ("kuka", 200, 16, 0.02, "sign", 4, 24.0),
    ("kuka", 1000, 18, 0.01, "tanh", None, 30.0),
    ("kuka", 200, 12, 0.05, "sign", None, 10.0),
    ("tx40", 5000, 18, 0.01, "sign", None, 9.0),
    ("tx40", 1000, 14, 0.01, "tanh", None, 30.0),
    ("tx40", 200, 20, 0.005, "sign", 4, 30.0),
]


def main():
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    only = sys.argv[2] if len(sys.argv) > 2 else ""
    print(f"| condition | logs with anything accepted (of {seeds}) | what | seconds per log (median) |")
    print("|---|---|---|---|")
    total = 0
    logs = 0
    for shape in (s for s in CONDITIONS if only in Condition(*s).label):
        for declare in [False, True] if shape[4] == "tanh" else [False]:
            found, times = collections.Counter(), []
            hits = 0
            for s in range(seeds):
                c = Condition(*shape, seed=1000 * s + 1)
                robot, train, truth = make_log(c)
                _, held, _ = make_log(Condition(*shape, seed=c.seed + 500), truth=truth)
                if declare:
                    robot = arash.Robot.from_urdf(urdf_path(c.robot), coulomb_epsilon=TANH_EPSILON)
                t0 = time.perf_counter()
                d = arash.diagnose(robot, *train, validation=held)
                times.append(time.perf_counter() - t0)
                hits += bool(d.accepted)
                found.update(f.label for f in d.accepted)
            total += hits
            logs += seeds
            times.sort()
            what = ", ".join(f"{k} ×{n}" for k, n in found.most_common()) or "—"
            label = Condition(*shape).label + (" (tanh declared)" if declare else "")
            print(f"| {label} | {hits} | {what} | {times[len(times) // 2]:.2f} |", flush=True)
    print(f"\nanything accepted on {total} of {logs} diagnoses")


if __name__ == "__main__":
    main()
