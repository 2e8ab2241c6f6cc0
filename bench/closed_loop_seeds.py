"""Closed-loop friction on fresh seeds (issue 59, item 3): identification with the defaults on
closed loops it was not tuned on, judged by the worst FP% over the paper's four validation
trajectories against the noise-free truth.

The loop is ``support.closed_loop.seeded_loop`` (Pinocchio's plant, PD with CAD gravity, 16-bit
encoders, no disturbance, the plant stepped at 10 kHz), its controller's velocity either the raw
difference of the encoder or that difference through a first-order low-pass (``--velocity-hz``),
on arash's designed excitation (four 15 s periods) or a random Fourier series (four 10 s
periods); the plant's dry friction is sign(q̇) (set-valued, so joints stick) or tanh(q̇/2·10⁻³).

Run from the repository root with the test venv (about 20 s a log):
    .venv/bin/python bench/closed_loop_seeds.py --seeds 1,2,3 --velocity-hz 60 --trajectory random
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

SMOOTH_WIDTH = 2e-3


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1,2,3")
    parser.add_argument("--laws", default="sign,smooth")
    parser.add_argument("--velocity-hz", type=float, default=None, help="the controller's velocity filter; none: raw")
    parser.add_argument("--bits", type=int, default=16)
    parser.add_argument("--trajectory", choices=["designed", "random"], default="designed")
    args = parser.parse_args()
    designed = args.trajectory == "designed"
    print(f"velocity {'raw difference' if args.velocity_hz is None else f'difference at {args.velocity_hz:g} Hz'}, "
          f"{args.bits}-bit encoders, {args.trajectory} trajectory")
    for seed in map(int, args.seeds.split(",")):
        for name in args.laws.split(","):
            law = "sign" if name == "sign" else [SMOOTH_WIDTH] * 3
            start = time.perf_counter()
            robot, log, truth = seeded_loop(seed, law, designed=designed, bits=args.bits,
                                            velocity_hz=args.velocity_hz)
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
