"""Closed-loop logs of the declared model, from Pinocchio's dynamics and a PD controller of our
own writing here (not arash's simulator or controllers).

The controller reads quantised encoders and differences them for the velocity, as a rig's does,
so the encoders' noise passes through its gains into the torque: the torque is correlated with
the noise of the positions it will be identified from, which is what makes closed-loop data
harder than open-loop data.
"""

from __future__ import annotations

import operator

import numpy as np

import arash
from .independent import (TANH_EPSILON, Condition, Expanded, friction, make_log, quantum, rigid_torques, trajectory,
                          urdf_path)
from .paths import ROBOT_FILES
from .simulated import true_parameters

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
            mass, bias = expanded.dynamics(q, qd)
            qdd = np.linalg.solve(mass, tau - bias - friction(truth, qd, "tanh"))
            qd = qd + h * qdd
            q = q + h * qd
    return robot, (t, q_log, tau_log), truth


def pd_gravity_log(condition, truth_params, *, loop_hz=LOOP_HZ, damping=LOOP_DAMPING, actuator_noise=0.02,
                   noise_hz=None, law=None, substeps=SUBSTEPS, declare=True, velocity_hz=None):
    """PD with gravity compensation from the CAD model, τ = g(q; π_CAD) − K_p e − K_d ė, the law
    IDIM-IV can name, running ``condition``'s trajectory on the robot ``truth_params`` (a full
    parameter vector: bodies, friction, cable stiffness).

    The drive adds white noise of ``actuator_noise`` times each joint's RMS torque to what the
    controller commands, and the log records the torque applied: that noise moves the robot, so
    the positions and the torque error are correlated, which is what biases least squares in
    closed loop. ``noise_hz`` gives that noise a first-order band (a drive's disturbance, slow
    enough to pass the identification's filter); None keeps it white. The encoders quantise at
    ``condition.bits`` and the controller differences them; ``velocity_hz`` passes that difference
    through a first-order low-pass at that frequency (a drive's filtered velocity), None uses it raw.

    ``law`` is the plant's Coulomb law: None for tanh of ``TANH_EPSILON``, a width per joint for
    tanh(q̇/v), or "sign". Under sign(q̇) a joint sticks wherever the other torques stay within its
    dry friction, and the plant is stepped as a set-valued law must be (``coulomb_step``), which
    holds a stuck joint exactly still; the smooth laws are stepped explicitly, ``substeps`` steps
    per control cycle. ``declare``: the robot returned declares the plant's law (tanh laws only);
    otherwise it declares none, as a new user loads it.

    Returns the robot, the log (t, q, τ), the reference (q_d, q̇_d, q̈_d) and the controller as
    IDIM-IV takes it."""
    rng = np.random.default_rng(condition.seed)
    path = urdf_path(condition.robot)
    dof = arash.Robot.from_urdf(path).dof
    widths = None if law == "sign" else np.full(dof, TANH_EPSILON) if law is None else np.asarray(law, dtype=float)
    if declare and widths is not None:
        robot = arash.Robot.from_urdf(path, friction_velocities=list(widths))
    else:
        robot = arash.Robot.from_urdf(path)
    plant, cad = Expanded(path, robot), Expanded(path, robot)
    plant.set_parameters(truth_params)
    cad_params = robot.cad_parameters()
    cad.set_parameters(cad_params)
    n, nb = robot.dof, len(robot.body_names())
    fv = truth_params[10 * nb : 10 * nb + 2 * n : 2]
    fc = truth_params[10 * nb + 1 : 10 * nb + 2 * n : 2]
    ke = truth_params[10 * nb + 2 * n :]

    def smooth_terms(q, qd):
        dry = 0.0 if widths is None else fc * np.tanh(qd / widths)
        return fv * qd + dry + ke * q

    t, q_d, qd_d, qdd_d = trajectory(robot, condition, rng)
    inertia = np.diag(plant.mass_matrix(q_d[0]))
    w = 2 * np.pi * loop_hz
    kp, kd = inertia * w * w, 2 * damping * inertia * w
    # The noise's scale: the torque the trajectory needs, joint by joint.
    needed = rigid_torques(plant, q_d[:: max(1, len(t) // 2000)], qd_d[:: max(1, len(t) // 2000)],
                           qdd_d[:: max(1, len(t) // 2000)])
    noise = actuator_noise * np.sqrt(np.mean(needed**2, axis=0))
    step = quantum(path, robot) / 2**condition.bits
    dt = 1.0 / condition.fs
    h = dt / substeps
    q, qd = q_d[0].copy(), qd_d[0].copy()
    q_log, tau_log = np.empty_like(q_d), np.empty_like(q_d)
    disturbance = rng.normal(size=(len(t), n))
    if noise_hz is not None:
        # x ← a x + √(1 − a²) w keeps the unit variance with a first-order band of noise_hz.
        a = np.exp(-2 * np.pi * noise_hz * dt)
        for i in range(1, len(t)):
            disturbance[i] = a * disturbance[i - 1] + np.sqrt(1 - a * a) * disturbance[i]
    impulse = h * fc
    # The low-pass's share of each new difference; None: the difference itself.
    smoothing = None if velocity_hz is None else 1.0 - np.exp(-2 * np.pi * velocity_hz * dt)
    velocity = qd_d[0].copy()
    for i in range(len(t)):
        measured = np.round(q / step) * step
        if i > 0:
            difference = (measured - measured_before) / dt
            velocity = difference if smoothing is None else velocity + smoothing * (difference - velocity)
        measured_before = measured
        tau = cad.torque(measured, np.zeros(n), np.zeros(n)) - kp * (measured - q_d[i]) - kd * (velocity - qd_d[i])
        tau = tau + noise * disturbance[i]
        q_log[i], tau_log[i] = measured, tau
        for _ in range(substeps):
            mass, bias = plant.dynamics(q, qd)
            inverse = np.linalg.inv(mass)
            free = qd + h * (inverse @ (tau - bias - smooth_terms(q, qd)))
            qd = free if widths is not None else coulomb_step(inverse, free, impulse)
            q = q + h * qd
    controller = {"law": "pd", "params": cad_params, "kp": kp, "kd": kd}
    return robot, (t, q_log, tau_log), (q_d, qd_d, qdd_d), controller


def seeded_loop(seed, law, *, designed=True, bits=16, actuator_noise=0.0, velocity_hz=None):
    """``pd_gravity_log`` on the true robot of ``seed`` (``true_parameters``), the plant stepped at
    10 kHz with dry friction ``law`` ("sign", or a tanh width per joint), 1 kHz, ``bits``-bit
    encoders: four 15 s periods of arash's designed excitation, or (``designed=False``) four 10 s
    periods of a random Fourier series drawn from the seed. The robot returned declares no law, as
    a new user loads it. Returns the robot, the log (t, q, τ) and the true parameters."""
    truth = true_parameters(arash.Robot.from_urdf(ROBOT_FILES["arash_asist"]), np.random.default_rng(seed))
    coulomb = "sign" if law == "sign" else "tanh"
    condition = Condition("arash_asist", 1000, bits, 0.0, coulomb, 4, 60.0 if designed else 40.0, seed=seed,
                          designed=designed)
    robot, log, _, _ = pd_gravity_log(condition, truth, actuator_noise=actuator_noise, law=law, substeps=10,
                                      declare=False, velocity_hz=velocity_hz)
    return robot, log, truth


def coulomb_step(inverse, free, impulse):
    """The velocity after one step of dry friction of the set-valued law sign(q̇) (Moreau's
    time-stepping): v = argmin ½ (v − v_free)ᵀ M (v − v_free) + Σ_k impulse_k |v_k|, where v_free is
    the velocity the other forces give, ``inverse`` is M⁻¹ and ``impulse`` = h·f_c. A joint
    sticks (v_k = 0 exactly) wherever the rest cannot overcome its friction. Solved by projected
    Gauss–Seidel on the friction impulses, each clamped to [−impulse_k, impulse_k]."""
    # Every joint sliding the way its free velocity goes is the minimiser when the velocities
    # that gives keep those signs: then each λ_k = impulse_k · sign(v_k), the optimality
    # condition. It holds on most steps of a moving arm, and the sweeps are for the others.
    sliding = free - inverse @ (np.sign(free) * impulse)
    if np.all(sliding * free > 0):
        return sliding
    n = len(free)
    lam = np.zeros(n)
    # Python floats in the sweep: the same arithmetic as numpy's, without its per-call cost.
    rows, diagonal, reach, target = inverse.tolist(), np.diag(inverse).tolist(), impulse.tolist(), free.tolist()
    values = [0.0] * n
    tolerance = 1e-12 * max(1e-300, max(reach))
    for _ in range(100):
        before = values.copy()
        for k in range(n):
            # v = v_free − M⁻¹ λ; choose λ_k so that v_k = 0, clamped to the friction's reach.
            v_k = target[k] - sum(map(operator.mul, rows[k], values))
            values[k] = min(max(values[k] + v_k / diagonal[k], -reach[k]), reach[k])
        if max(abs(a - b) for a, b in zip(values, before)) <= tolerance:
            break
    lam[:] = values
    return free - inverse @ lam


def paper_validation_fp(robot, model, truth, law=None):
    """FP% per joint of ``model`` on the paper's four validation trajectories (ω = 0.3, 0.5, 0.7,
    0.9, one period at 1 kHz), against the noise-free torque of the true robot from Pinocchio,
    whose Coulomb law is ``law``: None for tanh of ``TANH_EPSILON``, "sign", or a friction
    velocity per joint."""
    expanded = Expanded(ROBOT_FILES["arash_asist"], robot)
    expanded.set_parameters(truth)
    n, nb = robot.dof, len(robot.body_names())
    fv, fc, ke = truth[10 * nb : 10 * nb + 2 * n : 2], truth[10 * nb + 1 : 10 * nb + 2 * n : 2], truth[10 * nb + 2 * n :]
    rows = []
    for omega in (0.3, 0.5, 0.7, 0.9):
        t = np.arange(int(round(2 * np.pi / omega * 1000))) / 1000
        q, qd, qdd = arash.paper_validation_trajectory(omega, t)
        shape = np.sign(qd) if law == "sign" else np.tanh(qd / np.asarray(TANH_EPSILON if law is None else law))
        exact = rigid_torques(expanded, q, qd, qdd) + fv * qd + fc * shape + ke * q
        error = np.linalg.norm(exact - model.predict(q, qd, qdd), axis=0)
        rows.append(100 * (1 - error / np.linalg.norm(exact - exact.mean(axis=0), axis=0)))
    return np.array(rows)
