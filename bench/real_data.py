"""Real-data benchmark (issue 17): identification with the defaults on measured logs arash did not
make, against hand-set cut-offs and, for the TX40, upstream's published friction.

    .venv/bin/python bench/real_data.py          # needs ../shared/data (see its README)

KUKA LWR4+: train on run 1, predict runs 2 and 3 (‖e‖/‖τ‖ and FP% per joint). TX40: the
motor-side log through the declared transmission; identified viscous and Coulomb friction against
TX40_bp_5.csv (value and its stated σ%), z being the difference over the two σ combined. Prints
Markdown tables for docs/real-data.md.
"""

import csv
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import arash

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
HAND_CUTOFFS = (1.0, 2.0, 4.0, 8.0, 16.0, 32.0)


def kuka_run(i):
    d = np.load(DATA / "kuka_lwr4" / f"measurements_{i}.npz")
    return d["times"] - d["times"][0], d["positions"], d["torques"]


def row(label, values, fmt="{:.2f}"):
    return f"| {label} | " + " | ".join(fmt.format(v) for v in values) + " |"


def kuka():
    robot = arash.Robot.from_urdf(DATA / "kuka_lwr4" / "kuka_lwr4.urdf")
    runs = {i: kuka_run(i) for i in (1, 2, 3)}
    start = time.perf_counter()
    default = arash.identify(robot, *runs[1])
    seconds = time.perf_counter() - start
    # The hand-set cut-offs with the laws the defaults chose, so that only the cut-off differs.
    laws = arash.Robot.from_urdf(DATA / "kuka_lwr4" / "kuka_lwr4.urdf",
                                 friction_velocities=default.robot.friction_velocities)
    hand = {c: arash.identify(laws, *runs[1], cutoff_hz=c) for c in HAND_CUTOFFS}
    best_c = max(hand, key=lambda c: hand[c].validate(*runs[2])["fp_percent"].mean())
    print(f"\n### KUKA LWR4+ (train run 1, {seconds:.2f} s to identify with the defaults)\n")
    print(f"defaults: cut-off {default.cutoff_hz:.2f} Hz; best hand-set cut-off on run 2: {best_c:g} Hz\n")
    print("| | " + " | ".join(f"j{k + 1}" for k in range(robot.dof)) + " |")
    print("|---" * (robot.dof + 1) + "|")
    for name, ident in (("defaults", default), (f"hand-set {best_c:g} Hz", hand[best_c])):
        for i in (2, 3):
            v = ident.validate(*runs[i])
            print(row(f"{name}, run {i}, ‖e‖/‖τ‖", v["rel"]))
            print(row(f"{name}, run {i}, FP%", v["fp_percent"], "{:.1f}"))
    print("\nreasons:\n" + "\n".join(f"- {r}" for r in default.settings["reasons"]))


def tx40():
    root = DATA / "staubli_tx40"
    read = lambda name: np.array(list(csv.reader(open(root / name)))[1:], dtype=float)  # noqa: E731
    theta, tau_m = read("pos_read_data.csv"), read("curr_data.csv")
    t = np.arange(len(theta)) / 5000.0
    transmission = arash.Transmission([32.0, 32.0, 45.0, -48.0, 45.0, 32.0], coupling=[(6, 5, 32.0)],
                                      offsets=[0.0, -np.pi / 2, np.pi / 2, 0.0, 0.0, 0.0])
    robot = arash.Robot.from_urdf(root / "tx40_mdh_modified.urdf")
    published = {r[0]: (float(r[1]), float(r[2])) for r in csv.reader(open(root / "TX40_bp_5.csv"))}
    start = time.perf_counter()
    default = arash.identify(robot, t, theta, tau_m, motor_side=transmission)
    seconds = time.perf_counter() - start
    # Friction is compared under upstream's own law, sign(q̇): a smoother law's fv and fc trade
    # against its velocity, so they are not the quantities upstream published.
    signed = arash.Robot.from_urdf(root / "tx40_mdh_modified.urdf", friction_velocities=[None] * 6)
    as_upstream = arash.identify(signed, t, theta, tau_m, motor_side=transmission)
    hand = {c: arash.identify(signed, t, theta, tau_m, motor_side=transmission, cutoff_hz=c)
            for c in (4.0, 8.0, 16.0, 32.0, 64.0)}
    best_c = max(hand, key=lambda c: hand[c].fp_percent.mean())
    names = as_upstream.base.names
    print(f"\n### Stäubli TX40 ({seconds:.2f} s to identify with the defaults)\n")
    velocities = ", ".join("sign" if v is None else f"{v:.3g}" for v in default.robot.friction_velocities)
    print(f"defaults: cut-off {default.cutoff_hz:.2f} Hz, laws {velocities}, training FP% "
          f"{np.round(default.fp_percent, 1)}; sign(q̇) declared: cut-off {as_upstream.cutoff_hz:.2f} Hz, FP% "
          f"{np.round(as_upstream.fp_percent, 1)}; best hand-set cut-off {best_c:g} Hz, FP% "
          f"{np.round(hand[best_c].fp_percent, 1)}\n")
    print("| parameter | published (σ%) | sign(q̇), cut-off from the data (σ%) | z | hand-set (σ%) | z |")
    print("|---|---|---|---|---|---|")

    def z(ident, j, value, sigma):
        combined = np.hypot(sigma / 100 * abs(value), ident.sigma_percent[j] / 100 * abs(ident.beta[j]))
        return (ident.beta[j] - value) / combined

    for k in range(1, 7):
        for ours, theirs in ((f"joint_{k}.fv", f"fv{k}"), (f"joint_{k}.fc", f"fs{k}")):
            if ours not in names:
                continue
            j = names.index(ours)
            value, sigma = published[theirs]
            cells = [f"{i.beta[j]:.3f} ({i.sigma_percent[j]:.1f}) | {z(i, j, value, sigma):+.1f}"
                     for i in (as_upstream, hand[best_c])]
            print(f"| {ours} | {value:.3f} ({sigma:.1f}) | " + " | ".join(cells) + " |")
    print("\nreasons:\n" + "\n".join(f"- {r}" for r in default.settings["reasons"]))


if __name__ == "__main__":
    if not DATA.exists():
        sys.exit(f"{DATA} not found: the measured data live beside the repository (../shared/data)")
    warnings.simplefilter("ignore")
    kuka()
    tx40()
