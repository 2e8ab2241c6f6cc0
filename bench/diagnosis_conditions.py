"""The diagnosis's null and power across the conditions real rigs log in (issue 44, item 4).

Every log comes from the independent Pinocchio generator (tests/python/support/independent.py): current
sensors' noise (white, or band-limited) at 100–500 Hz, smooth Coulomb laws with a friction velocity
of their own, and the short logs of real runs (9–30 s), on three robots. The robot is loaded as a
new user loads it, declaring no Coulomb law, so each joint's law is chosen from the data; the
rows marked "declared" load it with the log's own law.

- null: a log of the declared model with a validation log of the same robot beside it; a hit is
  anything accepted.
- power: one effect injected at SIZE of its joint's RMS torque, no validation log (the held-out
  blocks of the log itself); a hit is the effect named first on its joint (an offset also as
  asymmetric Coulomb friction, whose column it is under sign(q̇)).

Prints markdown tables with the seeds and the median time per diagnosis.

    .venv/bin/python bench/diagnosis_conditions.py null [SEEDS] [TEXT]   # default 20 seeds
    .venv/bin/python bench/diagnosis_conditions.py power [SEEDS] [TEXT]  # default 10 seeds
"""

import collections
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
import arash  # noqa: E402
from support.independent import TANH_EPSILON, Condition, Injected, make_log, urdf_path  # noqa: E402

# robot, fs (Hz), encoder bits, noise (share of RMS torque), Coulomb law, periods, duration (s), noise band (Hz)
CONDITIONS = [
    ("arash_asist", 200, 16, 0.05, "smooth", None, 30.0, None),
    ("arash_asist", 100, 14, 0.08, "smooth", None, 20.0, None),
    ("arash_asist", 500, 16, 0.05, "sign", None, 9.0, None),
    ("arash_asist", 200, 16, 0.05, "smooth", None, 30.0, 20.0),
    ("kuka", 200, 16, 0.05, "smooth", None, 30.0, None),
    ("kuka", 100, 16, 0.08, "sign", None, 15.0, None),
    ("tx40", 500, 18, 0.05, "smooth", None, 9.0, None),
    ("tx40", 200, 16, 0.05, "tanh", None, 20.0, None),
]
SEED_BASE = {"null": 20_000, "power": 30_000}
EFFECTS = [("offset", 0), ("configuration_disturbance", 2), ("armature", 2), ("stribeck", 2)]
SIZE = 0.15
SAME_COLUMN = {"offset": {"offset", "coulomb_asymmetry"}}


def condition(shape, seed):
    *head, noise_hz = shape
    return Condition(*head, seed=seed, noise_hz=noise_hz)


def robot_for(c, declare):
    if not declare:
        return arash.Robot.from_urdf(urdf_path(c.robot))
    return arash.Robot.from_urdf(urdf_path(c.robot), coulomb_epsilon=TANH_EPSILON)


def null(seeds, only):
    print(f"| condition | seeds | logs with anything accepted | what | band chosen (median Hz) | s per log (median) |")
    print("|---|---|---|---|---|---|")
    total = logs = 0
    for shape in CONDITIONS:
        label = condition(shape, 0).label
        if only not in label:
            continue
        for declare in [False, True] if shape[4] == "tanh" else [False]:
            found, times, bands, hits = collections.Counter(), [], [], 0
            for s in range(seeds):
                c = condition(shape, SEED_BASE["null"] + 1000 * s)
                _, train, truth = make_log(c)
                _, held, _ = make_log(condition(shape, c.seed + 500), truth=truth)
                t0 = time.perf_counter()
                d = arash.diagnose(robot_for(c, declare), *train, validation=held)
                times.append(time.perf_counter() - t0)
                bands.append(d.settings["cutoff_hz"])
                hits += bool(d.accepted)
                found.update(f.label for f in d.accepted)
            total, logs = total + hits, logs + seeds
            what = ", ".join(f"{k} ×{n}" for k, n in found.most_common()) or "—"
            seeds_text = f"{SEED_BASE['null']}+1000k, k<{seeds}"
            name = label + (" (law declared)" if declare else "")
            print(f"| {name} | {seeds_text} | {hits} of {seeds} | {what} | {median(bands):.1f} | {median(times):.2f} |",
                  flush=True)
    print(f"\nanything accepted on {total} of {logs} diagnoses")


def power(seeds, only):
    names = [f"{kind} on joint {joint}" for kind, joint in EFFECTS]
    print("| condition | " + " | ".join(names) + " | s per log (median) |")
    print("|---|" + "---|" * (len(EFFECTS) + 1))
    total = hits_all = 0
    for shape in CONDITIONS:
        label = condition(shape, 0).label
        if only not in label:
            continue
        cells, times = [], []
        for kind, joint in EFFECTS:
            effect, hits = Injected(kind, joint, SIZE), 0
            for s in range(seeds):
                c = condition(shape, SEED_BASE["power"] + s)
                robot, train, _ = make_log(c, effect=effect)
                t0 = time.perf_counter()
                d = arash.diagnose(robot, *train)
                times.append(time.perf_counter() - t0)
                first = d.accepted[0] if d.accepted else None
                hits += first is not None and first.name in SAME_COLUMN.get(kind, {kind}) and joint in first.joints
            cells.append(f"{hits}/{seeds}")
            total, hits_all = total + seeds, hits_all + hits
        print(f"| {label} | " + " | ".join(cells) + f" | {median(times):.2f} |", flush=True)
    print(f"\nnamed first on its joint in {hits_all} of {total} logs (seeds {SEED_BASE['power']}–"
          f"{SEED_BASE['power'] + seeds - 1}, each effect at {100 * SIZE:g} % of its joint's RMS torque)")


def median(x):
    x = sorted(x)
    return x[len(x) // 2] if x else float("nan")


def main():
    # The TX40's URDF gives its last link a point mass, which arash loads with a warning.
    warnings.filterwarnings("ignore", message=".*only positive semidefinite.*")
    what = sys.argv[1] if len(sys.argv) > 1 else "null"
    seeds = int(sys.argv[2]) if len(sys.argv) > 2 else (20 if what == "null" else 10)
    only = sys.argv[3] if len(sys.argv) > 3 else ""
    {"null": null, "power": power}[what](seeds, only)


if __name__ == "__main__":
    main()
