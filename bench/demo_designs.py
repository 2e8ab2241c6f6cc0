"""The demo's pipeline on the simulator alone (no daemon, so deterministic), for an excitation
design and a scenario: design (seeded, one restart as `arash demo --restarts 1`), 60 s of it under
inverse dynamics control with CAD, consistent IDIM-IV, the diagnosis with the paper's four
validation runs held out, and the maximum error on the ω = 0.5 trajectory cut against CAD by the
rig's own parameters of the declared model, the identified model and the model with the effects
found (docs/demo.md, "The excitation").

    .venv/bin/python bench/demo_designs.py [SEED ...] [--scenario nominal|demo] [--earlier]

--earlier: the demo's design before 2026-11-26 (over the exact base parameters, 4000 iterations,
no least range or speed).
"""

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

import arash

ROOT = Path(__file__).resolve().parents[1]
OMEGA = 0.5
PERIOD = 2 * np.pi / OMEGA
VALIDATION_OMEGAS = (0.3, 0.5, 0.7, 0.9)
# The drives' joint motion per motor radian (deploy/daemon.toml), for the cogging search.
TRANSMISSION = [1 / 12, 1 / 12, 0.0025]
EARLIER = dict(iterations=4000, min_range_fraction=0.0, min_speed_fraction=0.0, keep_weak=True)


def max_error(scenario, controller, params, seed):
    run = arash.simulate(scenario, {"kind": "paper-validation", "omega": OMEGA}, controller=controller,
                         params=params, duration=2 * PERIOD, seed=seed)
    second = run["t"] >= run["t"][0] + PERIOD
    return np.abs(run["q"][second] - run["q_des"][second]).max(axis=0)


def held_out(scenario, seed):
    """The validation runs, which `arash.diagnose` joins end to end as the demo does, each
    filtered on its own."""
    runs = [arash.simulate(scenario, {"kind": "paper-validation", "omega": omega}, controller="idc-cad", seed=seed)
            for omega in VALIDATION_OMEGAS]
    return [(run["t"], run["q"], run["tau_meas"]) for run in runs]


def one(seed, scenario, earlier):
    started = time.perf_counter()
    robot = arash.Robot.arash_asist()
    design = arash.design_excitation(robot, seed=seed, restarts=1, quiet=True, **(EARLIER if earlier else {}))
    run = arash.simulate(scenario, json.loads(design.to_json()), controller="idc-cad",
                         duration=4 * design.period_s, seed=seed)
    model = arash.identify(robot, run["t"], run["q"], run["tau_meas"], method="idim-iv-consistent",
                           reference=(run["q_des"], run["qd_des"], run["qdd_des"]),
                           controller=run["logged_controller"])
    truth = model.base.project(run["true_params"])
    z = (model.beta - truth) / (model.sigma_percent / 100 * np.abs(model.beta))
    # The rig's Coulomb law is tanh(q̇/0.001); the demo declares it to the diagnosis.
    diagnosis = arash.diagnose(arash.Robot.arash_asist(coulomb_epsilon=1e-3), run["t"], run["q"], run["tau_meas"],
                               validation=held_out(scenario, seed), transmission=TRANSMISSION, consistent=True,
                               consistent_cutoff_hz=model.cutoff_hz)
    cad = max_error(scenario, "idc-cad", "cad", seed)
    cuts = [cad / max_error(scenario, "robust", params, seed)
            for params in ("truth", model, diagnosis.model_consistent)]
    effects = ", ".join(f"{e.name} on {robot.joint_names()[e.joints[0]]}" for e in diagnosis.accepted) or "none"
    cells = " | ".join(" / ".join(f"{c:.2f}" for c in cut) for cut in cuts)
    print(f"| {seed} | {design.condition_number:.0f} | {int((np.abs(z) <= 3).sum())} of {len(z)} | {cells} | "
          f"{effects} | {time.perf_counter() - started:.0f} s |", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("seeds", nargs="*", type=int, default=[1, 2, 3])
    parser.add_argument("--scenario", default="demo", choices=["nominal", "demo"])
    parser.add_argument("--earlier", action="store_true")
    args = parser.parse_args()
    scenario = ROOT / "scenarios" / f"{args.scenario}.toml"
    print(f"{'earlier' if args.earlier else 'arash excite'} design on {args.scenario}.toml; "
          "cut = CAD's max error over the model's (yaw / pitch / insertion)\n")
    print("| seed | design κ | IDIM-IV within 3σ | rig's own parameters | identified | + effects found | effects found | time |")
    print("|---|---|---|---|---|---|---|---|")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        for seed in args.seeds:
            one(seed, scenario, args.earlier)


if __name__ == "__main__":
    main()
