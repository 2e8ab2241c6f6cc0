"""Closed-loop friction on fresh seeds (issue 59, item 3): identification with the defaults on
closed loops it was not tuned on, judged by the worst FP% over the paper's four validation
trajectories against the noise-free truth.

Two generators, independent of each other and of arash (``--generator``):
- ``pd``: ``support.closed_loop.seeded_loop`` (Pinocchio's plant, PD with CAD gravity, 16-bit
  encoders by default, no disturbance, the plant stepped at 10 kHz), its controller's velocity
  either the raw difference of the encoder or that difference through a first-order low-pass
  (``--velocity-hz``);
- ``computed-torque``: ``support.computed_torque_loop`` (computed torque on the CAD model with
  integral action, an α–β observer's velocity, the command a cycle late, 18-bit encoders by
  default);
each on arash's designed excitation (four 15 s periods) or a random Fourier series (four 10 s
periods); the plant's dry friction is sign(q̇) (set-valued, so joints stick) or tanh(q̇/2·10⁻³).

Run from the repository root with the test venv (about 20 s a log):
    .venv/bin/python bench/closed_loop_seeds.py --seeds 1,2,3 --velocity-hz 60 --trajectory random
    .venv/bin/python bench/closed_loop_seeds.py --generator computed-torque --bits 14 --trajectory random
"""

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import arash

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
from support.closed_loop import paper_validation_fp, seeded_loop  # noqa: E402
from support.computed_torque_loop import computed_torque_loop  # noqa: E402

SMOOTH_WIDTH = 2e-3


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1,2,3")
    parser.add_argument("--laws", default="sign,smooth")
    parser.add_argument("--velocity-hz", type=float, default=None, help="the controller's velocity filter; none: raw")
    parser.add_argument("--generator", choices=["pd", "computed-torque"], default="pd")
    parser.add_argument("--bits", type=int, default=None, help="encoder bits; default 16 (pd), 18 (computed-torque)")
    parser.add_argument("--trajectory", choices=["designed", "random"], default="designed")
    args = parser.parse_args()
    designed = args.trajectory == "designed"
    pd = args.generator == "pd"
    bits = args.bits or (16 if pd else 18)
    velocity = "raw difference" if args.velocity_hz is None else f"difference at {args.velocity_hz:g} Hz"
    print(f"{args.generator} loop, velocity {velocity if pd else 'of an α–β observer'}, {bits}-bit encoders, "
          f"{args.trajectory} trajectory")
    for seed in map(int, args.seeds.split(",")):
        for name in args.laws.split(","):
            law = "sign" if name == "sign" else [SMOOTH_WIDTH] * 3
            start = time.perf_counter()
            if pd:
                robot, log, truth = seeded_loop(seed, law, designed=designed, bits=bits, velocity_hz=args.velocity_hz)
            else:
                robot, log, truth = computed_torque_loop(seed, law, designed=designed, bits=bits)
            made = time.perf_counter() - start
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                model = arash.identify(robot, *log)
            worst = paper_validation_fp(model.robot, model, truth, law).min(axis=0)
            laws = ["sign" if v is None else f"tanh/{v:.2g}" for v in model.robot.friction_velocities]
            print(f"seed {seed} {name:6s} cut-off {model.settings['cutoff_hz']:.2f} Hz laws {laws} "
                  f"worst FP% {np.round(worst, 2)} (log {made:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
