"""The sign-law closed loop of issue 44 (docs/identification.md, "A sign-law closed loop"): PD
with CAD gravity, no disturbance, the plant stepped at 10 kHz with the set-valued law sign(q̇) (a stuck joint stays exactly still), arash's designed excitation (four periods),
16-bit encoders. Prints the paper's validation FP% (minimum over its four trajectories) of OLS and
IDIM-IV, with the laws from the data and with sign(q̇) declared, and of an oracle: least squares on
the plant's exact states at the log's instants (q̈ the mean over each control period), no
filtering, no quantisation. Identification leaves each joint's resting samples out
(signal/resting.rs), which the reasons report. About 2½ minutes.

    .venv/bin/python bench/sign_closed_loop.py
"""

import sys
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
import arash  # noqa: E402
from support import closed_loop as cl  # noqa: E402
from support.paths import ROBOT_FILES  # noqa: E402
from support.independent import Condition, Expanded, urdf_path  # noqa: E402
from support.simulated import true_parameters  # noqa: E402
from support.closed_loop import paper_validation_fp  # noqa: E402

CONDITION = Condition("arash_asist", 1000, 16, 0.0, "sign", 4, 60.0, seed=0, designed=True)
SUBSTEPS = 10


def validation_fp(robot, truth, predict):
    """Minimum FP% per joint over the paper's four trajectories against the true sign-law robot."""
    return paper_validation_fp(robot, SimpleNamespace(predict=predict), truth, "sign").min(axis=0)


def exact_states(truth):
    """The plant of ``closed_loop.pd_gravity_log(CONDITION, truth, law="sign")``, stepped alike,
    recording its exact states at the log's instants and the torque applied."""
    rng = np.random.default_rng(CONDITION.seed)
    path = urdf_path(CONDITION.robot)
    robot = arash.Robot.from_urdf(path, friction_velocities=[None] * 3)
    plant, cad = Expanded(path, robot), Expanded(path, robot)
    plant.set_parameters(truth)
    cad.set_parameters(robot.cad_parameters())
    n, nb = robot.dof, len(robot.body_names())
    fv, fc, ke = truth[10 * nb : 10 * nb + 2 * n : 2], truth[10 * nb + 1 : 10 * nb + 2 * n : 2], truth[10 * nb + 2 * n :]
    t, q_d, qd_d, _ = cl.trajectory(robot, CONDITION, rng)
    inertia = np.diag(plant.mass_matrix(q_d[0]))
    w = 2 * np.pi * cl.LOOP_HZ
    kp, kd = inertia * w * w, 2 * cl.LOOP_DAMPING * inertia * w
    step = cl.quantum(path, robot) / 2**CONDITION.bits
    dt = 1.0 / CONDITION.fs
    h = dt / SUBSTEPS
    q, qd = q_d[0].copy(), qd_d[0].copy()
    states = [np.empty_like(q_d) for _ in range(4)]
    measured_before = None
    for i in range(len(t)):
        measured = np.round(q / step) * step
        velocity = qd_d[0] if i == 0 else (measured - measured_before) / dt
        measured_before = measured
        tau = cad.torque(measured, np.zeros(n), np.zeros(n)) - kp * (measured - q_d[i]) - kd * (velocity - qd_d[i])
        start = qd.copy()
        states[0][i], states[1][i], states[3][i] = q, qd, tau
        for _ in range(SUBSTEPS):
            bias = plant.torque(q, qd, np.zeros(n))
            mass = plant.mass_matrix(q)
            free = qd + h * np.linalg.solve(mass, tau - bias - (fv * qd + ke * q))
            qd = cl.coulomb_step(mass, free, h * fc)
            q = q + h * qd
        states[2][i] = (qd - start) / dt
    return robot, states


def main():
    warnings.simplefilter("ignore")
    robot = arash.Robot.from_urdf(ROBOT_FILES["arash_asist"])
    truth = true_parameters(robot, np.random.default_rng(0))
    undeclared, log, reference, controller = cl.pd_gravity_log(CONDITION, truth, actuator_noise=0.0, law="sign",
                                                               substeps=SUBSTEPS, declare=False)
    declared = arash.Robot.from_urdf(ROBOT_FILES["arash_asist"], friction_velocities=[None] * 3)
    print("| estimator | laws from the data | sign(q̇) declared |\n|---|---|---|")
    for method in ("ols", "idim-iv"):
        cells = []
        for r in (undeclared, declared):
            extra = {} if method == "ols" else {"reference": reference, "controller": controller}
            model = arash.identify(r, *log, method=method, **extra)
            cells.append(" / ".join(f"{v:.1f}" for v in validation_fp(r, truth, model.predict)))
        print(f"| {method} | " + " | ".join(cells) + " |", flush=True)
    # Whether any hand-set preprocessing does better: the main and the friction velocity's cut-off.
    best = None
    for cutoff in (0.5, 1.0, 2.0, 4.0, 8.0):
        for friction in (cutoff, 4 * cutoff, 16 * cutoff, 100.0):
            model = arash.identify(declared, *log, cutoff_hz=cutoff, friction_cutoff_hz=friction)
            fp = validation_fp(declared, truth, model.predict)
            if best is None or fp.min() > best[2].min():
                best = (cutoff, friction, fp)
    print(f"\nOLS, sign(q̇) declared, best hand-set cut-offs of 20 (by the worst joint): {best[0]:g} Hz, friction "
          f"velocity {best[1]:g} Hz: " + " / ".join(f"{v:.1f}" for v in best[2]))
    signed, (q, qd, qdd, tau) = exact_states(truth)
    y = signed.regressor(q, qd, qdd)
    p = signed.num_params
    print(f"\nstuck share per joint: {np.round(np.mean(qd == 0, axis=0), 3)}")
    after = np.vstack([qd[1:], qd[-1:]])  # the velocity at the end of each control period
    steady = np.all((qd != 0) & (after != 0) & (np.sign(qd) == np.sign(after)), axis=1)
    for label, rows in (("every sample", np.ones(len(q), bool)),
                        (f"the {100 * steady.mean():.0f} % of periods in which no joint sticks or reverses", steady)):
        residual = np.sqrt(np.mean((y[rows] @ truth - tau[rows]) ** 2, axis=0))
        print(f"the true parameters' residual there (RMS per joint): {np.round(residual, 3)} against the torque's "
              f"{np.round(np.sqrt(np.mean(tau[rows] ** 2, axis=0)), 3)}")
        a, b = y[rows].reshape(-1, p), tau[rows].reshape(-1)
        scale = np.linalg.norm(a, axis=0)
        scale[scale == 0] = 1.0
        params = np.linalg.lstsq(a / scale, b, rcond=None)[0] / scale
        fp = validation_fp(signed, truth, lambda q_, qd_, qdd_: signed.regressor(q_, qd_, qdd_) @ params)
        print(f"oracle, exact states, {label}: " + " / ".join(f"{v:.1f}" for v in fp))


if __name__ == "__main__":
    main()
