"""Coverage of the drive gains fitted with a known load (issue 45, docs/currents.md): Pinocchio
logs (tests/python/support/independent.py) as currents τ/k, gains k drawn from 0.5–2× per joint and seed,
2 % current noise, 30 s per run, sign law declared. Per condition and seed: the unloaded run and
the loaded run (a point mass at (0, 0, 0.05) m on the link, its mass alone given) fit the gains;
then a second payload (half the mass, at (0, 0.03, 0.02) m) on two later runs is diagnosed with
the currents and the calibrated gains (``currents=True``) and must come out as a payload on that
link. Prints one table row per condition and gains fit: the share of gains the fit calls fixed, of
those within 3σ and within 2 % of the truth, the share of seeds whose second payload is found
within 10 % in kg and within 3σ (its σ counting the gains'), and the median times.

    .venv/bin/python bench/drive_gains.py [seeds]        # 20 seeds by default
"""

import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
import arash  # noqa: E402
from support.independent import Condition, Payload, make_log, urdf_path  # noqa: E402

CONDITIONS = [  # robot, link, mass (kg), rate (Hz), gains fit
    ("kuka", "lwr_7_link", 2.0, 1000.0, "current"),
    ("kuka", "lwr_7_link", 2.0, 100.0, "current"),
    ("kuka", "lwr_7_link", 2.0, 100.0, "tls"),
    ("kuka", "lwr_7_link", 0.2, 100.0, "current"),  # a light load
    ("kuka", "lwr_4_link", 2.0, 1000.0, "current"),  # a load that moves with joints 1–4 only
    ("tx40", "link_6", 1.0, 200.0, "current"),
    ("tx40", "link_6", 2.805, 100.0, "current"),  # issue 45's held-back arm: 2.805 kg, 100 Hz
    ("tx40", "link_6", 2.805, 100.0, "tls"),
    ("arash_asist", "insertion_carriage", 0.3, 1000.0, "current"),
    ("arash_asist", "insertion_carriage", 0.3, 1000.0, "tls"),
]


def one(robot_name, link, mass, fs, fit, seed):
    shape = (robot_name, fs, 16, 0.02, "sign", None, 30.0)
    robot, free, truth = make_log(Condition(*shape, seed=seed))
    carried = make_log(Condition(*shape, seed=seed + 100), truth=truth, payload=Payload(link, mass, (0, 0, 0.05)))[1]
    gains = np.random.default_rng(seed).uniform(0.5, 2.0, robot.dof)
    declared = arash.Robot.from_urdf(urdf_path(robot_name), friction_velocities=[None] * robot.dof)
    start = time.perf_counter()
    model = arash.identify(declared, free[0], free[1], free[2] / gains,
                           loaded=(carried[0], carried[1], carried[2] / gains), load={"body": link, "mass": mass},
                           gains_fit=fit)
    fit_s = time.perf_counter() - start
    g = model.drive_gains
    fixed = np.array(g["fixed"])
    error = np.abs(g["gains"] - gains)
    second = Payload(link, 0.5 * mass, (0.0, 0.03, 0.02))
    (t, q, tau), held = [make_log(Condition(*shape, seed=seed + s), truth=truth, payload=second)[1] for s in (200, 300)]
    start = time.perf_counter()
    d = arash.diagnose(declared, t, q, tau / gains, model=model, validation=(held[0], held[1], held[2] / gains),
                       currents=True)
    diagnose_s = time.perf_counter() - start
    first = d.accepted[0] if d.accepted else None
    payload = first is not None and first.name == "payload" and first.body == link
    found = payload and abs(first.mass_kg - second.mass) <= 0.1 * second.mass
    covered = payload and abs(first.mass_kg - second.mass) <= 3 * first.mass_sigma_kg
    return fixed, error <= 3 * g["sigma"], error <= 0.02 * gains, found, fit_s, diagnose_s, covered


def main():
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    warnings.simplefilter("ignore")
    print("| robot, load, rate, gains fit | gains fixed | fixed within 3σ | fixed within 2 % | second payload within "
          "10 % | within 3σ | fit (median s) | diagnosis (median s) |\n|---|---|---|---|---|---|---|---|")
    for robot_name, link, mass, fs, fit in CONDITIONS:
        rows = [one(robot_name, link, mass, fs, fit, seed) for seed in range(seeds)]
        fixed = np.concatenate([r[0] for r in rows])
        sigma = np.concatenate([r[1][r[0]] for r in rows])
        close = np.concatenate([r[2][r[0]] for r in rows])
        found, covered = sum(r[3] for r in rows), sum(r[6] for r in rows)
        print(f"| {robot_name}, {mass:g} kg on {link}, {fs:g} Hz, {fit} | {fixed.sum()}/{fixed.size} | "
              f"{sigma.sum()}/{sigma.size} | {close.sum()}/{close.size} | {found}/{seeds} | {covered}/{seeds} | "
              f"{np.median([r[4] for r in rows]):.1f} | {np.median([r[5] for r in rows]):.1f} |", flush=True)


if __name__ == "__main__":
    main()
