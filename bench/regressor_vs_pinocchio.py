"""Time the batched Python regressor and compare with Pinocchio on the expanded mimic tree.

Run from the repository root, with the venv that .ci/run builds:
    .venv/bin/python bench/regressor_vs_pinocchio.py
Prints medians over repeated runs; the machine is shared, so medians, not means.
"""

import sys
from pathlib import Path

import numpy as np
import pinocchio as pin

import arash

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from support.paths import ROBOT_FILES, random_states  # noqa: E402
from timing import median_seconds  # noqa: E402
from support.independent import Expanded  # noqa: E402


def main():
    robot = arash.Robot.arash_asist()
    ref = Expanded(ROBOT_FILES["arash_asist"], robot)
    rng = np.random.default_rng(0)
    n_big = 300_000
    q, qd, qdd = random_states(robot, n_big, rng)
    robot.regressor(q[:1000], qd[:1000], qdd[:1000])  # warm up

    batched = median_seconds(lambda: robot.regressor(q, qd, qdd), 7)
    print(f"arash  robot.regressor, {n_big} samples (N×3 in, N×3×89 out): median {batched:.3f} s "
          f"= {batched / n_big * 1e9:.0f} ns/sample")
    out = np.empty((n_big, robot.dof, robot.num_params))
    reused = median_seconds(lambda: robot.regressor(q, qd, qdd, out=out), 7)
    print(f"arash  robot.regressor, {n_big} samples into a reused out= buffer: median {reused:.3f} s "
          f"= {reused / n_big * 1e9:.0f} ns/sample")
    touch = median_seconds(lambda: np.ones((n_big, robot.dof, robot.num_params)), 5)
    print(f"numpy  np.ones of the same 641 MB output, for scale: median {touch:.3f} s")

    n_loop = 20_000
    tree = [ref.tree(q[i], qd[i], qdd[i]) for i in range(n_loop)]

    def pinocchio_loop():
        for qt, vt, at in tree:
            pin.computeJointTorqueRegressor(ref.model, ref.data, qt, vt, at)

    def pinocchio_loop_mapped():
        for qt, vt, at in tree:
            ref.G.T @ pin.computeJointTorqueRegressor(ref.model, ref.data, qt, vt, at) @ ref.T

    pin_raw = median_seconds(pinocchio_loop, 5) / n_loop
    pin_mapped = median_seconds(pinocchio_loop_mapped, 5) / n_loop
    ours_small = median_seconds(lambda: robot.regressor(q[:n_loop], qd[:n_loop], qdd[:n_loop]), 7) / n_loop
    print(f"pinocchio computeJointTorqueRegressor on the 8-joint tree, per call from Python: "
          f"median {pin_raw * 1e9:.0f} ns (with Gᵀ·Y·T to the 3×80 mimic regressor: {pin_mapped * 1e9:.0f} ns)")
    print(f"arash  robot.regressor per sample in a {n_loop}-sample batch: {ours_small * 1e9:.0f} ns")
    print(f"ratio  pinocchio raw / arash batched: {pin_raw / (batched / n_big):.1f}×; "
          f"pinocchio mapped / arash batched: {pin_mapped / (batched / n_big):.1f}×")
    print(f"estimated 300,000 samples through pinocchio raw: {pin_raw * n_big:.2f} s")


if __name__ == "__main__":
    main()
