"""A second closed-loop generator (issue 59, item 3), independent of ``closed_loop.pd_gravity_log``
in everything a rig's loop chooses:

- the controller: computed torque on the CAD model with integral action,
  τ = M̂(q̂)(q̈_d + K_p e + K_d ė + K_i ∫e) + ĥ(q̂, v̂), where the first loop is a PD on the
  positions with CAD gravity; under dry friction the integral hunts around each stop;
- the velocity: an α–β tracking observer on the encoder reading, where the first loop
  differences the readings (raw or through a first-order low-pass);
- the command reaches the motors a cycle late, where the first loop applies it at once;
- the encoders' resolution, given here, 16 bits there; and the excitation's random draw.

The plant is the same Pinocchio model of the true robot, stepped as ``closed_loop`` steps it:
the set-valued sign(q̇) by ``coulomb_step`` (a stuck joint stays exactly still), a smooth law
explicitly. Nothing of arash's simulator or controllers is used.
"""

from __future__ import annotations

import numpy as np

import arash
from .closed_loop import coulomb_step
from .independent import Condition, Expanded, quantum, trajectory, urdf_path
from .paths import ROBOT_FILES
from .simulated import true_parameters

# The loop's bandwidth (Hz) and damping ratio, as accelerations (the CAD inertia scales them).
LOOP_HZ = 4.0
LOOP_DAMPING = 0.8
# The integral's corner, as a share of the loop's bandwidth.
INTEGRAL_SHARE = 0.2
# The α–β observer's bandwidth (Hz): both its poles at exp(−2π f dt).
OBSERVER_HZ = 50.0
# Plant steps per control cycle.
SUBSTEPS = 10
# The excitation is drawn from its own stream, not the first generator's.
STREAM = 7919


def alpha_beta(observer_hz, dt):
    """The gains of an α–β observer whose two poles are both at r = exp(−2π f dt): the error
    dynamics' characteristic polynomial z² − (2 − α − β) z + (1 − α) = (z − r)²."""
    r = np.exp(-2 * np.pi * observer_hz * dt)
    return 1 - r * r, (1 - r) ** 2


def computed_torque_loop(seed, law, *, designed=True, bits=18, fs=1000.0, observer_hz=OBSERVER_HZ):
    """A computed-torque loop with integral action on the true robot of ``seed``, its plant's dry
    friction ``law`` ("sign", or a tanh width per joint), ``fs`` Hz, ``bits``-bit encoders read by
    an α–β observer of ``observer_hz``, the command applied one cycle late: four 15 s periods of
    arash's designed excitation, or (``designed=False``) four 10 s periods of a random Fourier
    series. Returns the robot (declaring no law), the log (t, q read, τ applied) and the truth."""
    path = urdf_path("arash_asist")
    robot = arash.Robot.from_urdf(ROBOT_FILES["arash_asist"])
    truth = true_parameters(robot, np.random.default_rng(seed))
    coulomb = "sign" if law == "sign" else "tanh"
    condition = Condition("arash_asist", fs, bits, 0.0, coulomb, 4, 60.0 if designed else 40.0, seed=seed,
                          designed=designed)
    plant, cad = Expanded(path, robot), Expanded(path, robot)
    plant.set_parameters(truth)
    cad.set_parameters(robot.cad_parameters())
    n, nb = robot.dof, len(robot.body_names())
    fv, fc, ke = truth[10 * nb : 10 * nb + 2 * n : 2], truth[10 * nb + 1 : 10 * nb + 2 * n : 2], truth[10 * nb + 2 * n :]
    widths = None if law == "sign" else np.asarray(law, dtype=float)

    t, q_d, qd_d, qdd_d = trajectory(robot, condition, np.random.default_rng(seed + STREAM))
    dt, h = 1.0 / fs, 1.0 / fs / SUBSTEPS
    w = 2 * np.pi * LOOP_HZ
    kp, kd, ki = w * w, 2 * LOOP_DAMPING * w, INTEGRAL_SHARE * w**3
    alpha, beta = alpha_beta(observer_hz, dt)
    step = quantum(path, robot) / 2**bits
    impulse = h * fc

    q, qd = q_d[0].copy(), qd_d[0].copy()
    estimate, velocity = np.round(q / step) * step, qd_d[0].copy()
    integral = np.zeros(n)
    command = cad.torque(q_d[0], qd_d[0], qdd_d[0])
    q_log, tau_log = np.empty_like(q_d), np.empty_like(q_d)
    for i in range(len(t)):
        reading = np.round(q / step) * step
        if i > 0:
            predicted = estimate + velocity * dt
            innovation = reading - predicted
            estimate = predicted + alpha * innovation
            velocity = velocity + beta / dt * innovation
        # The command of the last cycle acts over this one.
        applied = command
        q_log[i], tau_log[i] = reading, applied
        error = q_d[i] - estimate
        integral = integral + error * dt
        acceleration = qdd_d[i] + kp * error + kd * (qd_d[i] - velocity) + ki * integral
        command = cad.torque(estimate, velocity, acceleration)
        for _ in range(SUBSTEPS):
            mass, bias = plant.dynamics(q, qd)
            inverse = np.linalg.inv(mass)
            smooth = fv * qd + ke * q + (0.0 if widths is None else fc * np.tanh(qd / widths))
            free = qd + h * (inverse @ (applied - bias - smooth))
            qd = free if widths is not None else coulomb_step(inverse, free, impulse)
            q = q + h * qd
    return robot, (t, q_log, tau_log), truth
