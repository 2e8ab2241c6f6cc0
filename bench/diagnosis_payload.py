"""A known mass added to (or taken off) a robot after calibration: does arash.diagnose find it?

The user's case of issue 19: a model identified on a run without load, then a run with a known
mass on one link, diagnosed against that model. And the mirror: the model identified with the
mass on, the run without it (the model is then heavier than the data, which is never a payload).
Every log comes from the independent Pinocchio generator (tests/python/support/independent.py), the mass
added as a point mass to Pinocchio's tree; the loaded log and its validation log use other
trajectories than the calibration run.

A hit: for a mass added, the first effect accepted is a payload on that link; for a mass taken
off, the diagnosis says the model is too heavy on that link and accepts nothing. Prints a
markdown table: hits, the median and largest error of the mass, and how often ±3σ covers it.

    .venv/bin/python bench/diagnosis_payload.py [SEEDS]     # default 10 seeds
"""

import statistics
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
import arash  # noqa: E402
from support.independent import Condition, Payload, make_log  # noqa: E402

PAYLOADS = [
    Payload("lwr_7_link", 1.0, (0.0, 0.0, 0.05)),
    Payload("lwr_4_link", 1.0, (0.0, 0.05, 0.0)),
    Payload("insertion_carriage", 0.04),
    Payload("instrument_holder", 0.04, (0.0, 0.02, 0.0)),
]
ROBOT = {"lwr_7_link": "kuka", "lwr_4_link": "kuka", "insertion_carriage": "arash_asist", "instrument_holder": "arash_asist"}
# fs (Hz), encoder bits, torque noise (share of RMS), Coulomb law, periods, duration (s)
LOGS = [(1000, 16, 0.01, "sign", None, 30.0), (200, 12, 0.02, "sign", None, 10.0)]


def trial(payload, log, seed, removed):
    """(hit, fitted mass, its σ) for one seed."""
    shape = (ROBOT[payload.link], *log)
    robot, calibration, truth = make_log(Condition(*shape, seed=seed), payload=payload if removed else None)
    model = arash.identify(robot, *calibration)
    later = None if removed else payload
    _, run, _ = make_log(Condition(*shape, seed=seed + 100), truth=truth, payload=later)
    _, held, _ = make_log(Condition(*shape, seed=seed + 200), truth=truth, payload=later)
    d = arash.diagnose(robot, *run, model=model, validation=held)
    if removed:
        h = d.too_heavy
        hit = h is not None and h["body"] == payload.link and not d.accepted
        return hit, (h["mass_kg"] if hit else None), (h["mass_sigma_kg"] if hit else None)
    first = d.accepted[0] if d.accepted else None
    hit = first is not None and first.name == "payload" and first.body == payload.link
    return hit, (first.mass_kg if hit else None), (first.mass_sigma_kg if hit else None)


def main():
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    warnings.simplefilter("ignore", UserWarning)
    print(f"| mass, link | log | named (of {seeds}) | mass error, median / largest | within ±3σ | s per seed |")
    print("|---|---|---|---|---|---|")
    for removed in (False, True):
        for payload in PAYLOADS:
            for log in LOGS:
                hits, errors, covered = 0, [], 0
                t0 = time.perf_counter()
                for s in range(seeds):
                    hit, mass, sigma = trial(payload, log, 1000 * s + 7, removed)
                    hits += hit
                    if hit:
                        errors.append(abs(mass - payload.mass) / payload.mass)
                        covered += abs(mass - payload.mass) <= 3 * sigma
                per_seed = (time.perf_counter() - t0) / seeds
                what = f"{payload.mass * 1e3:.0f} g {'off' if removed else 'on'} {payload.link}"
                label = Condition(ROBOT[payload.link], *log).label
                error = f"{100 * statistics.median(errors):.1f} / {100 * max(errors):.1f} %" if errors else "—"
                print(f"| {what} | {label} | {hits} | {error} | {covered} of {hits} | {per_seed:.1f} |", flush=True)


if __name__ == "__main__":
    main()
