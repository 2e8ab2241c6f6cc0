"""An independent source of robot logs: Pinocchio's dynamics, not arash's.

``Expanded`` is Pinocchio's view of a robot (mimic joints expanded into a tree, the coupling G,
the parameter map T); ``make_log`` turns a ``Condition`` (robot, sample rate, encoder resolution,
torque noise, Coulomb law, periods, duration) into the log a user would record of the declared
model: quantised positions and noisy torques. arash is used only to read the URDF's limits and
parameter layout, never to compute a torque.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import pinocchio as pin

import arash
from .paths import ROBOT_FILES, kuka_urdf, tx40_urdf, urdf_couplings

# ours [m, mx, my, mz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]  <-  Pinocchio's index for each entry
OURS_FROM_PIN = [0, 1, 2, 3, 4, 6, 9, 5, 7, 8]


class Expanded:
    """Pinocchio's view of a robot: the expanded tree, the coupling G and the parameter map T."""

    def __init__(self, path, robot):
        self.robot = robot
        self.model = pin.buildModelFromUrdf(str(path))
        self.data = self.model.createData()
        couplings = urdf_couplings(path)
        actuated = robot.joint_names()
        nv = self.model.nv
        self.G = np.zeros((nv, robot.dof))
        self.offset = np.zeros(nv)
        for jid in range(1, self.model.njoints):
            name = self.model.names[jid]
            _, target, mult, off = couplings[name]
            k = actuated.index(target if target is not None else name)
            self.G[self.model.joints[jid].idx_v, k] = mult
            self.offset[self.model.joints[jid].idx_v] = off
        self.T = self._parameter_map()
        # Where each Pinocchio joint's configuration goes (the tree's encoding, computed once):
        # one angle, or (cos θ, sin θ) for a continuous joint.
        joints = [self.model.joints[jid] for jid in range(1, self.model.njoints)]
        self._angle_q = np.array([j.idx_q for j in joints if j.nq != 2], dtype=int)
        self._angle_v = np.array([j.idx_v for j in joints if j.nq != 2], dtype=int)
        self._circle_q = np.array([j.idx_q for j in joints if j.nq == 2], dtype=int)
        self._circle_v = np.array([j.idx_v for j in joints if j.nq == 2], dtype=int)
        self._lower = np.tril_indices(nv, -1)
        # Without continuous joints the configuration is linear in q: A q + c (`configuration`).
        select = np.zeros((self.model.nq, nv))
        select[self._angle_q, self._angle_v] = 1.0
        self._config_of_q, self._config_offset = select @ self.G, select @ self.offset

    def _parameter_map(self):
        """T with π_pin (10 per Pinocchio joint) = T π_ours (rigid part)."""
        names = self.robot.body_names()
        T = np.zeros((10 * (self.model.njoints - 1), 10 * len(names)))
        for b, link in enumerate(names):
            frame = self.model.frames[self.model.getFrameId(link)]
            jid = frame.parentJoint
            rows = slice(10 * (jid - 1), 10 * jid)
            # The link's inertia lands in its joint's frame through the frame placement (identity
            # for a link moved by its own joint, a fixed offset for a link on a fixed joint).
            # Inertia.se3Action is linear in the dynamic parameters; take it column by column.
            base = pin.Inertia.FromDynamicParameters(np.array([1, 0, 0, 0, 1, 0, 1, 0, 0, 1.0]))
            base_moved = frame.placement.act(base).toDynamicParameters()
            for i in range(10):
                e = np.zeros(10)
                e[OURS_FROM_PIN[i]] = 1.0
                moved = frame.placement.act(pin.Inertia.FromDynamicParameters(base.toDynamicParameters() + e))
                T[rows, 10 * b + i] = moved.toDynamicParameters() - base_moved
        return T

    def set_parameters(self, params):
        pi_pin = self.T @ params[: self.T.shape[1]]
        for jid in range(1, self.model.njoints):
            self.model.inertias[jid] = pin.Inertia.FromDynamicParameters(pi_pin[10 * (jid - 1) : 10 * jid])

    def add_point_mass(self, payload):
        """A load fixed to a link (a ``Payload``), added to the inertia of the Pinocchio joint it
        rides on."""
        if not self.model.existFrame(payload.link):
            raise ValueError(f"no link {payload.link!r} to put a payload on")
        frame = self.model.frames[self.model.getFrameId(payload.link)]
        inertia = np.diag(np.asarray(payload.inertia, dtype=float))
        mass = pin.Inertia(payload.mass, np.asarray(payload.at, dtype=float), inertia)
        self.model.inertias[frame.parentJoint] = self.model.inertias[frame.parentJoint] + frame.placement.act(mass)

    def configuration(self, q):
        """Tree configuration in Pinocchio's encoding: a continuous joint is (cos θ, sin θ)."""
        if not len(self._circle_q):
            # Linear in q: one product, where the indexing below costs a simulator's step more
            # than Pinocchio's algorithms do (the same numbers, bit for bit).
            return self._config_of_q @ q + self._config_offset
        angles = self.G @ q + self.offset
        config = np.zeros(self.model.nq)
        config[self._angle_q] = angles[self._angle_v]
        config[self._circle_q] = np.cos(angles[self._circle_v])
        config[self._circle_q + 1] = np.sin(angles[self._circle_v])
        return config

    def tree(self, q, qd, qdd):
        """The tree's configuration, velocity and acceleration."""
        return self.configuration(q), self.G @ qd, self.G @ qdd

    def torque(self, q, qd, qdd):
        """Gᵀ · Pinocchio's RNEA on the expanded tree: the rigid-body joint torques."""
        config, velocity, acceleration = self.tree(q, qd, qdd)
        return self.G.T @ pin.rnea(self.model, self.data, config, velocity, acceleration)

    def mass_matrix(self, q):
        """Gᵀ · Pinocchio's CRBA · G."""
        return self._reduced_mass(self.configuration(q))

    def dynamics(self, q, qd):
        """The mass matrix and the bias torque (Coriolis, centrifugal, gravity) at one state, as
        ``mass_matrix`` and ``torque(q, q̇, 0)`` give them, from one tree configuration: a
        simulator's step needs both (the closed-loop generators step the plant 10⁵–10⁶ times)."""
        config = self.configuration(q)
        bias = pin.nonLinearEffects(self.model, self.data, config, self.G @ qd)
        return self._reduced_mass(config), self.G.T @ bias

    def _reduced_mass(self, config):
        tree = pin.crba(self.model, self.data, config)
        # CRBA fills the upper triangle; the lower one is ours to overwrite.
        tree[self._lower] = tree.T[self._lower]
        return self.G.T @ tree @ self.G

def joint_torques(robot, q, qd, params):
    """Friction and elastic torques, which Pinocchio's rigid-body algorithms leave out."""
    n, nb = robot.dof, len(robot.body_names())
    fv, fc = params[10 * nb : 10 * nb + 2 * n : 2], params[10 * nb + 1 : 10 * nb + 2 * n : 2]
    ke = params[10 * nb + 2 * n :]
    return fv * qd + fc * np.sign(qd) + ke * q


# Coulomb friction and viscous friction each give this share of a joint's RMS rigid-body torque.
FRICTION_SHARE = 0.05
# No joint's torque scale is below this share of the largest joint's.
RMS_FLOOR_SHARE = 0.01
# A tanh Coulomb law's velocity scale (rad/s or m/s).
TANH_EPSILON = 0.01
# A smooth Coulomb law's friction velocity on each joint, as a share of the joint's RMS speed:
# friction that rises from zero over a speed of its own, as real joints' does (issue 44).
SMOOTH_SHARE = 0.05
# A linear encoder's stroke over its counts (m), for prismatic joints.
LINEAR_STROKE_M = 0.2
HARMONICS = 5
# An aperiodic log's sines have random frequencies up to this (Hz).
APERIODIC_TOP_HZ = 0.5


@dataclass(frozen=True)
class Condition:
    robot: str  # "arash_asist", "kuka" or "tx40"
    fs: float  # Hz
    bits: int  # encoder counts per turn (or per stroke) = 2**bits
    noise: float  # torque noise, as a share of each joint's RMS torque
    coulomb: str  # "sign", "tanh" (TANH_EPSILON on every joint) or "smooth" (SMOOTH_SHARE of each joint's RMS speed)
    periods: Optional[int]  # whole periods in the log; None: not periodic
    duration: float  # s
    seed: int = 0
    # Follow arash's designed excitation (trajectories/excitation_L5_T15.json, evaluated here from
    # the paper's formula) instead of a random Fourier series; `duration / periods` must be its period.
    designed: bool = False
    # A current sensor's noise: None is white; a frequency (Hz) gives the noise a first-order band
    # there (a current loop's ripple and the sensor's own filter), at the same RMS.
    noise_hz: Optional[float] = None

    @property
    def top_frequency(self) -> float:
        """The highest frequency of the trajectory's positions (Hz)."""
        if self.designed:
            spec = json.loads(DESIGNED.read_text())
            return spec["harmonics"] / spec["period_s"]
        if self.periods:
            return HARMONICS * self.periods / self.duration
        return APERIODIC_TOP_HZ

    @property
    def label(self) -> str:
        shape = f"{self.periods}x{self.duration / self.periods:g}s" if self.periods else f"aperiodic {self.duration:g}s"
        source = " designed" if self.designed else ""
        band = f" noise<{self.noise_hz:g}Hz" if self.noise_hz else ""
        return f"{self.robot} {self.fs:g}Hz {self.bits}bit {100 * self.noise:g}%{band} {self.coulomb} {shape}{source}"


def urdf_path(name):
    return {"arash_asist": lambda: ROBOT_FILES["arash_asist"], "kuka": kuka_urdf, "tx40": tx40_urdf}[name]()


def limits(robot):
    """Position range and speed limit per joint, with the fallbacks conftest.random_states uses."""
    lo, hi, vmax = [], [], []
    for (a, b), v in zip(robot.position_limits(), robot.velocity_limits()):
        lo.append(a if math.isfinite(a) else -math.pi)
        hi.append(b if math.isfinite(b) else math.pi)
        vmax.append(v if math.isfinite(v) else 2.0)
    return np.array(lo), np.array(hi), np.array(vmax)


DESIGNED = Path(__file__).resolve().parents[3] / "trajectories" / "excitation_L5_T15.json"


def designed_excitation(t):
    """The paper's Fourier form, q = q₀ + Σₗ aₗ/(ωl) sin(ωlt) − bₗ/(ωl) cos(ωlt), of the stored
    excitation; returns q, q̇, q̈ at the times ``t``."""
    spec = json.loads(DESIGNED.read_text())
    a, b, q0 = np.array(spec["a"]), np.array(spec["b"]), np.array(spec["q0"])
    w = 2 * np.pi / spec["period_s"] * np.arange(1, a.shape[1] + 1)
    s, c = np.sin(t[:, None, None] * w), np.cos(t[:, None, None] * w)
    q = q0 + (a / w * s - b / w * c).sum(axis=2)
    qd = (a * c + b * s).sum(axis=2)
    qdd = (w * (-a * s + b * c)).sum(axis=2)
    return q, qd, qdd


def trajectory(robot, condition, rng):
    """A Fourier series of the log's period, or, for an aperiodic log, sines at incommensurate
    random frequencies; scaled into 80 % of the ranges and speed limits. Returns t, q, q̇, q̈."""
    lo, hi, vmax = limits(robot)
    n, dof = int(round(condition.duration * condition.fs)), robot.dof
    t = np.arange(n) / condition.fs
    if condition.designed:
        return (t, *designed_excitation(t))
    if condition.periods:
        base = condition.periods / condition.duration
        freqs = np.tile(base * np.arange(1, HARMONICS + 1), (dof, 1))
        amps = rng.uniform(0.3, 1.0, (dof, HARMONICS)) / np.arange(1, HARMONICS + 1)
    else:
        freqs = rng.uniform(0.05, APERIODIC_TOP_HZ, (dof, HARMONICS))
        amps = rng.uniform(0.3, 1.0, (dof, HARMONICS))
    phases = rng.uniform(0, 2 * np.pi, (dof, HARMONICS))
    w = 2 * np.pi * freqs
    scale = np.minimum(0.4 * (hi - lo) / amps.sum(axis=1), 0.8 * vmax / (amps * w).sum(axis=1))
    amps = amps * scale[:, None]
    arg = t[:, None, None] * w[None] + phases[None]
    q = 0.5 * (hi + lo) + (amps * np.sin(arg)).sum(axis=2)
    qd = (amps * w * np.cos(arg)).sum(axis=2)
    qdd = -(amps * w * w * np.sin(arg)).sum(axis=2)
    return t, q, qd, qdd


def rigid_torques(expanded, q, qd, qdd):
    """Gᵀ · Pinocchio's RNEA on the expanded tree, sample by sample."""
    return np.array([expanded.torque(q[i], qd[i], qdd[i]) for i in range(len(q))])


def quantum(path, robot):
    """Encoder step per joint: a turn over 2**bits for revolute joints, the stroke for prismatic."""
    kinds = urdf_couplings(path)
    return np.array([LINEAR_STROKE_M if kinds[name][0] == "prismatic" else 2 * np.pi for name in robot.joint_names()])


def coulomb_shape(truth, qd, coulomb):
    """The Coulomb law ``coulomb`` at the velocities ``qd``: "sign", "tanh" of width
    ``TANH_EPSILON``, or "smooth", tanh of each joint's own friction velocity (``truth["vc"]``)."""
    if coulomb == "sign":
        return np.sign(qd)
    if coulomb == "smooth":
        return np.tanh(qd / truth["vc"])
    return np.tanh(qd / TANH_EPSILON)


def friction(truth, qd, coulomb):
    """The truth's viscous and Coulomb friction at the velocities ``qd``, with the Coulomb law
    ``coulomb`` (see ``coulomb_shape``)."""
    return truth["fv"] * qd + truth["fc"] * coulomb_shape(truth, qd, coulomb)


def current_noise(rng, shape, fs, noise_hz):
    """Unit-variance noise of ``shape`` (samples, joints): white, or with a first-order band at
    ``noise_hz`` (x ← a x + √(1 − a²) w)."""
    w = rng.normal(size=shape)
    if noise_hz is None:
        return w
    a = np.exp(-2 * np.pi * noise_hz / fs)
    x = np.empty_like(w)
    x[0] = w[0]
    for i in range(1, len(w)):
        x[i] = a * x[i - 1] + np.sqrt(1 - a * a) * w[i]
    return x


@dataclass(frozen=True)
class Injected:
    """An effect the declared model lacks, added to one joint's torque. Each is written here from
    its physics, not from arash's catalogue (crates/arash-core/src/effects/)."""

    kind: str  # "offset", "configuration_disturbance", "armature", "stribeck", "drive_gain" or "coupled_rotor"
    joint: int
    size: float  # the RMS of its torque on the training log, as a share of the joint's RMS torque
    # For "coupled_rotor": the other joint that turns the motor of ``joint``, and the motor's
    # motion per radian of that joint on ``joint``'s scale (the TX40's wrist: joint 5, ratio 1).
    with_joint: Optional[int] = None
    ratio: float = 1.0
    # For "stribeck": the Stribeck velocity as a share of the joint's RMS speed.
    speed_share: float = 0.1


@dataclass(frozen=True)
class Payload:
    """A known load added to a link: ``mass`` (kg) at ``at`` (m, in the link's frame), with the
    principal moments ``inertia`` (kg·m², about its centre, along the link's axes); a point mass
    by default."""

    link: str
    mass: float
    at: tuple = (0.0, 0.0, 0.0)
    inertia: tuple = (0.0, 0.0, 0.0)


def injected_shape(effect, robot, q, qd, qdd, tau):
    """The effect's torque per unit coefficient on every joint, (N, dof), at the true motion and
    torque ``tau``."""
    if effect.kind == "coupled_rotor":
        # A motor turned by two joints, θ̇ ∝ q̇_k + c·q̇_j: its rotor inertia, viscous and dry
        # friction (each at unit RMS) reach both joints through the gear, joint j's times c.
        k, j, c = effect.joint, effect.with_joint, effect.ratio
        a, v = qdd[:, k] + c * qdd[:, j], qd[:, k] + c * qd[:, j]
        motor = a / np.sqrt(np.mean(a**2)) + v / np.sqrt(np.mean(v**2)) + np.sign(v)
        shape = np.zeros_like(q)
        shape[:, k], shape[:, j] = motor, c * motor
        return shape
    shape = np.zeros_like(q)
    shape[:, effect.joint] = joint_shape(effect, robot, q, qd, qdd, tau)
    return shape


def joint_shape(effect, robot, q, qd, qdd, tau):
    """A one-joint effect's torque per unit coefficient on its joint."""
    k = effect.joint
    if effect.kind == "offset":
        return np.ones(len(q))
    if effect.kind == "configuration_disturbance":
        # A wiring spring over the joint's declared range: one and a half sine periods.
        lo, hi, _ = limits(robot)
        return np.sin(1.5 * np.pi * (q[:, k] - lo[k]) / (hi[k] - lo[k]))
    if effect.kind == "armature":
        return qdd[:, k]
    if effect.kind == "drive_gain":
        # A torque constant off by a share of itself: the joint's whole torque, scaled.
        return tau[:, k]
    if effect.kind == "stribeck":
        # The excess of static over Coulomb friction, decaying over a share of the RMS speed.
        vs = effect.speed_share * np.sqrt(np.mean(qd[:, k] ** 2))
        return np.exp(-((qd[:, k] / vs) ** 2)) * np.sign(qd[:, k])
    raise ValueError(f"unknown injected effect {effect.kind!r}")


def make_log(condition, states=None, truth=None, effect=None, payload=None):
    """The log of ``condition``: t, quantised q, noisy τ, and the truth (params, joint terms).

    ``states`` (t, q, q̇, q̈) replaces the generated trajectory; ``truth`` reuses a previous log's
    parameters (and an injected effect's coefficient), so that a validation log comes from the
    same robot. ``effect`` (an ``Injected``, or a tuple of them) adds a torque the declared model
    lacks. ``payload`` (a ``Payload``) adds a point mass to a link, in Pinocchio's tree.
    """
    rng = np.random.default_rng(condition.seed)
    path = urdf_path(condition.robot)
    robot = arash.Robot.from_urdf(path)
    expanded = Expanded(path, robot)
    t, q, qd, qdd = states if states is not None else trajectory(robot, condition, rng)
    params = robot.cad_parameters().copy() if truth is None else truth["params"]
    expanded.set_parameters(params)
    if payload is not None:
        expanded.add_point_mass(payload)
    rigid = rigid_torques(expanded, q, qd, qdd)
    if truth is None:
        # A joint whose rigid-body torque is nil (a link declared massless) still has friction
        # and noise, sized from the other joints.
        rms = np.maximum(np.sqrt(np.mean(rigid**2, axis=0)), RMS_FLOOR_SHARE * np.sqrt(np.mean(rigid**2, axis=0)).max())
        speed = np.sqrt(np.mean(qd**2, axis=0))
        truth = {"params": params, "fv": FRICTION_SHARE * rms / speed, "fc": FRICTION_SHARE * rms,
                 "noise": condition.noise * rms, "vc": SMOOTH_SHARE * speed, "speed_rms": speed}
    tau = rigid + friction(truth, qd, condition.coulomb)
    effects = () if effect is None else effect if isinstance(effect, tuple) else (effect,)
    declared = tau.copy()
    for i, e in enumerate(effects):
        # Each is sized against the declared model's torque, so that two sizes do not compound.
        shape = injected_shape(e, robot, q, qd, qdd, declared)
        key = "effect" if i == 0 else f"effect_{i}"
        if key not in truth:
            joint_rms = np.sqrt(np.mean(declared[:, e.joint] ** 2))
            truth[key] = e.size * joint_rms / np.sqrt(np.mean(shape[:, e.joint] ** 2))
        tau += truth[key] * shape
    tau = tau + truth["noise"] * current_noise(rng, tau.shape, condition.fs, condition.noise_hz)
    step = quantum(path, robot) / 2**condition.bits
    q_measured = np.round(q / step) * step
    return robot, (t, q_measured, tau), truth


def payload_torque(path, robot, payload, t, q):
    """The torque a point mass adds on a measured motion, from Pinocchio: RNEA with the mass minus
    RNEA without (the dynamics are linear in the masses), at velocities and accelerations from a
    zero-phase 10 Hz filter and central differences, as a torque sensor would feel them."""
    from scipy.signal import butter, filtfilt

    b, a = butter(4, 10.0 / (0.5 / (t[1] - t[0])))
    smooth = filtfilt(b, a, q, axis=0)
    qd = np.gradient(smooth, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    tree = Expanded(path, robot)
    tree.set_parameters(robot.cad_parameters())
    without = np.array([tree.torque(*x) for x in zip(smooth, qd, qdd)])
    tree.add_point_mass(payload)
    return np.array([tree.torque(*x) for x in zip(smooth, qd, qdd)]) - without
