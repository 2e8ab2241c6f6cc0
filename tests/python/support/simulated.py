"""Simulated logs with known truth: model torques plus noise, on Fourier excitation trajectories."""

import numpy as np

NOISE = np.array([0.003, 0.003, 0.05])  # N·m, N·m, N


def pseudo_inertia(block):
    """4×4 pseudo-inertia of one body's [m, mx, my, mz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]."""
    m, hx, hy, hz, ixx, iyy, izz, ixy, ixz, iyz = block
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    j = np.zeros((4, 4))
    j[:3, :3] = sigma
    j[:3, 3] = j[3, :3] = (hx, hy, hz)
    j[3, 3] = m
    return j


def true_parameters(robot, rng):
    """CAD bodies with mass and inertia scaled by up to ±30 % and centres moved by up to 1 cm."""
    pi = robot.cad_parameters().copy()
    for b in range(len(robot.body_names())):
        blk = pi[10 * b : 10 * b + 10]
        m, c = blk[0], blk[1:4] / blk[0]
        inertia = pseudo_to_tensor(blk)
        i_com = inertia - m * (c @ c * np.eye(3) - np.outer(c, c))
        m2, c2 = m * (1 + rng.uniform(-0.3, 0.3)), c + rng.uniform(-0.01, 0.01, 3)
        i2 = i_com * (1 + rng.uniform(-0.3, 0.3)) + m2 * (c2 @ c2 * np.eye(3) - np.outer(c2, c2))
        pi[10 * b : 10 * b + 10] = [m2, *(m2 * c2), i2[0, 0], i2[1, 1], i2[2, 2], i2[0, 1], i2[0, 2], i2[1, 2]]
    nb = len(robot.body_names())
    pi[10 * nb : 10 * nb + 6] = [0.02, 0.03, 0.015, 0.025, 3.0, 0.4]
    pi[10 * nb + 6 :] = [0.05, 0.08, 20.0]
    return pi


def pseudo_to_tensor(block):
    ixx, iyy, izz, ixy, ixz, iyz = block[4:10]
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def fourier_trajectory(robot, rng, period=15.0, harmonics=5):
    """Random Fourier series scaled into 80 % of the joint ranges and speed limits."""
    w = 2 * np.pi / period
    lo, hi = np.array(robot.position_limits()).T
    vmax = np.array(robot.velocity_limits())
    a = rng.uniform(-1, 1, (3, harmonics)) / np.arange(1, harmonics + 1)
    b = rng.uniform(-1, 1, (3, harmonics)) / np.arange(1, harmonics + 1)
    l = np.arange(1, harmonics + 1)
    amp = np.hypot(a, b).sum(axis=1)
    speed = (np.hypot(a, b) * w * l).sum(axis=1)
    scale = np.minimum(0.4 * (hi - lo) / amp, 0.8 * vmax / speed)
    a, b = a * scale[:, None], b * scale[:, None]
    centre = 0.5 * (hi + lo)

    def at(t):
        s, c = np.sin(np.outer(t, w * l)), np.cos(np.outer(t, w * l))
        q = centre + s @ a.T + c @ b.T
        qd = (c * (w * l)) @ a.T - (s * (w * l)) @ b.T
        qdd = -(s * (w * l) ** 2) @ a.T - (c * (w * l) ** 2) @ b.T
        return q, qd, qdd

    return at


def log(robot, params, states, t, rng, noise=NOISE):
    q, qd, qdd = states(t) if callable(states) else states
    tau = robot.inverse_dynamics(q, qd, qdd, params) + noise * rng.normal(size=q.shape)
    return t, q, tau
