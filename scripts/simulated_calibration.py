#!/usr/bin/env python3
"""A calibration run on simulated data with known truth, the way a lab engineer would do it on the rig.

1. Design the excitation: L = 5 harmonics, T = 15 s.
2. Log 300 s of it at 1 kHz, which is 20 periods. The torques are the "true" model's, from a
   perturbed CAD, plus sensor noise.
3. Log the paper's validation trajectories at ω = 0.3, 0.5, 0.7 and 0.9 rad/s.
4. Run `arash identify` with OLS and with the consistent method. It prints Tables I and II.

Until the simulated rig (issue 4) lands, the torques come from the model itself plus white noise.
Run from the repository root, after scripts/test or a maturin build:

    .venv/bin/python scripts/simulated_calibration.py [--quick]

The output goes to logs/sim-calibration/.
"""

import argparse
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))
import arash  # noqa: E402
from support.simulated import log, true_parameters  # noqa: E402


def write_csv(path, robot, t, q, tau):
    names = robot.joint_names()
    header = ",".join(["t"] + [f"q.{n}" for n in names] + [f"tau.{n}" for n in names])
    np.savetxt(path, np.column_stack([t, q, tau]), delimiter=",", header=header, comments="", fmt="%.9g")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="2 restarts and 4 periods instead of 6 and 20")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    out = ROOT / "logs" / "sim-calibration"
    out.mkdir(parents=True, exist_ok=True)
    robot = arash.Robot.arash_asist()
    rng = np.random.default_rng(args.seed)
    truth = true_parameters(robot, rng)

    print("== designing the excitation (L = 5, T = 15 s)", flush=True)
    excitation = arash.design_excitation(robot, restarts=2 if args.quick else 6, seed=args.seed)
    print(f"   normalised condition number κ = {excitation.condition_number:.4g}")
    periods = 4 if args.quick else 20
    t, q, qd, qdd = excitation.sample(1000.0, periods)
    _, q, tau = log(robot, truth, (q, qd, qdd), t, rng)
    write_csv(out / "train.csv", robot, t, q, tau)
    print(f"== logged {len(t)} samples ({periods} periods) to {out / 'train.csv'}")

    validation = []
    for omega in (0.3, 0.5, 0.7, 0.9):
        period = 2 * math.pi / omega
        samples = 3 * int(round(period * 1000))
        tv = np.arange(samples) / 1000.0
        states = arash.paper_validation_trajectory(omega, tv)
        _, qv, tauv = log(robot, truth, states, tv, rng)
        path = out / f"omega_{omega:.1f}.csv"
        write_csv(path, robot, tv, qv, tauv)
        validation.append(str(path))

    arash_bin = ROOT / "target" / "release" / "arash"
    if not arash_bin.exists():
        subprocess.run(["cargo", "build", "--release", "-p", "arash-cli"], cwd=ROOT, check=True)
    for method in ("ols", "consistent"):
        print(f"\n== arash identify --method {method}", flush=True)
        subprocess.run(
            [str(arash_bin), "identify", str(out / "train.csv"), "--method", method, "--periods", str(periods),
             "--decimate", "5", "--validate", *validation, "--validate-periods", "3",
             "-o", str(out / f"model_{method}.json")],
            cwd=ROOT, check=True,
        )

    ident = arash.load_model(out / "model_ols.json")
    beta_true = ident.base.project(truth)  # the base parameters the model file fitted
    sigma = ident.sigma_percent / 100 * np.abs(ident.beta)
    inside = np.abs(ident.beta - beta_true) <= 3 * sigma
    print(f"\n== truth check: {inside.sum()}/{len(inside)} base parameters within 3σ of the truth")


if __name__ == "__main__":
    main()
