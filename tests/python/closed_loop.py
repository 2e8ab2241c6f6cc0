"""Closed-loop logs of the declared model, from Pinocchio's dynamics and a PD controller of our
own writing here (not arash's simulator or controllers).

The controller reads quantised encoders and differences them for the velocity, as a rig's does,
so the encoders' noise passes through its gains into the torque: the torque is correlated with
the noise of the positions it will be identified from, which is what makes closed-loop data
harder than open-loop data.
"""

from __future__ import annotations

import numpy as np

import arash
from independent import TANH_EPSILON, Expanded, friction, make_log, quantum, rigid_torques, trajectory, urdf_path

# The loop's bandwidth (Hz) and damping ratio, from each joint's inertia at the start.
LOOP_HZ = 5.0
LOOP_DAMPING = 0.7
# Integration steps per control cycle (semi-implicit Euler).
SUBSTEPS = 2


def closed_loop_log(condition, loop_hz=LOOP_HZ, damping=LOOP_DAMPING):
    """A PD loop with the model's feed-forward follows ``condition``'s trajectory on the declared
    robot (tanh Coulomb friction of width ``TANH_EPSILON``; the condition's Coulomb law is not
    used). Returns the robot (with that law declared), the log (t, quantised q, applied τ) and the
    truth, as ``make_log`` does."""
    rng = np.random.default_rng(condition.seed)
    path = urdf_path(condition.robot)
    robot = arash.Robot.from_urdf(path, coulomb_epsilon=TANH_EPSILON)
    expanded = Expanded(path, robot)
    t, q_d, qd_d, qdd_d = trajectory(robot, condition, rng)
    # The truth's friction and noise scales, as an open-loop log of the same trajectory has them.
    _, _, truth = make_log(condition, states=(t, q_d, qd_d, qdd_d))
    expanded.set_parameters(truth["params"])

    feedforward = rigid_torques(expanded, q_d, qd_d, qdd_d) + friction(truth, qd_d, "tanh")
    inertia = np.diag(expanded.mass_matrix(q_d[0]))
    w = 2 * np.pi * loop_hz
    kp, kd = inertia * w * w, 2 * damping * inertia * w
    step = quantum(path, robot) / 2**condition.bits
    dt = 1.0 / condition.fs
    h = dt / SUBSTEPS
    q, qd = q_d[0].copy(), qd_d[0].copy()
    q_log, tau_log = np.empty_like(q_d), np.empty_like(q_d)
    for i in range(len(t)):
        measured = np.round(q / step) * step
        # The first cycle has no previous reading: it starts at the reference's velocity.
        velocity = qd_d[0] if i == 0 else (measured - measured_before) / dt
        measured_before = measured
        tau = feedforward[i] + kp * (q_d[i] - measured) + kd * (qd_d[i] - velocity)
        tau = tau + truth["noise"] * rng.normal(size=tau.shape)
        q_log[i], tau_log[i] = measured, tau
        for _ in range(SUBSTEPS):
            bias = expanded.torque(q, qd, np.zeros_like(q))
            qdd = np.linalg.solve(expanded.mass_matrix(q), tau - bias - friction(truth, qd, "tanh"))
            qd = qd + h * qdd
            q = q + h * qd
    return robot, (t, q_log, tau_log), truth
