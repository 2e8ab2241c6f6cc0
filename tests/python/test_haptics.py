"""The haptic mode's virtual fixtures against an independent simulation: Pinocchio's dynamics of
ARASH:ASiST, with a hand's force applied at the instrument tip through Pinocchio's own frame
Jacobian, pressed into a depth wall that arash renders from the sampled state and holds over each
1 ms cycle, as the daemon does.

The energy check: the arm's kinetic energy and the ideal wall's potential (both computed here,
from Pinocchio and the tip's depth) can never exceed the work the hand did on it while the
rendering is passive. At the stiffest wall ``arash.fixture_bounds`` accepts that holds; a fifth
above it the sampled wall feeds energy in, as Colgate and Schenkel's condition says.
"""

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")
import arash  # noqa: E402

from support.independent import Expanded  # noqa: E402
from support.paths import ROBOT_FILES  # noqa: E402

DT = 1e-3
START = np.array([0.1, 0.4, 0.015])


def wall(depth_m, stiffness, damping=0.0):
    return f"[[wall]]\ndepth_m = {depth_m}\nstiffness = {stiffness}\ndamping = {damping}\n"


@pytest.fixture(scope="module")
def arm():
    """arash's robot, Pinocchio's view of it without gravity (the compensation's job, not the
    wall's), and the joints' own damping: the CAD model's viscous friction, which is what arash's
    bound is computed on."""
    path = ROBOT_FILES["arash_asist"]
    robot = arash.Robot.arash_asist()
    ref = Expanded(path, robot)
    ref.model.gravity.linear[:] = 0.0
    names = robot.parameter_names()
    viscous = np.array([robot.cad_parameters()[names.index(f"{j}.fv")] for j in robot.joint_names()])
    return robot, ref, viscous


def tip_frame(ref, q):
    """The tip's position, the instrument's direction into the eye and the tip's linear Jacobian
    (3 × dof), and the remote centre's position, all from Pinocchio."""
    config = ref.configuration(q)
    pin.forwardKinematics(ref.model, ref.data, config)
    pin.updateFramePlacements(ref.model, ref.data)
    tip = ref.data.oMf[ref.model.getFrameId("instrument_tip")]
    centre = ref.data.oMf[ref.model.getFrameId("remote_centre")].translation
    jac = pin.computeFrameJacobian(ref.model, ref.data, config, ref.model.getFrameId("instrument_tip"), pin.LOCAL_WORLD_ALIGNED)
    return tip.translation.copy(), tip.rotation[:, 2].copy(), jac[:3] @ ref.G, centre.copy()


def press(arm, fixtures, stiffness, depth_m, seconds=2.5):
    """Push the tip along the instrument with 1 N (raised over 0.2 s, held to 1.2 s, released by
    1.4 s), the wall's torque rendered by arash at each cycle's start and held; return the stored
    energy less the hand's work, over time (J)."""
    robot, ref, viscous = arm
    q, qd = START.copy(), np.zeros(3)
    energy0, work, excess = None, 0.0, []

    def hand(t):
        rise = np.clip(t / 0.2, 0.0, 1.0)
        fall = np.clip((1.4 - t) / 0.2, 0.0, 1.0)
        return 0.5 * (1.0 - np.cos(np.pi * min(rise, fall)))

    def derivative(q, qd, t, tau_wall):
        _, direction, jac, _ = tip_frame(ref, q)
        force = hand(t) * direction
        mass, bias = ref.dynamics(q, qd)
        return np.linalg.solve(mass, tau_wall + jac.T @ force - bias - viscous * qd), force @ (jac @ qd)

    def stored(q, qd):
        mass, _ = ref.dynamics(q, np.zeros(3))
        tip, direction, _, centre = tip_frame(ref, q)
        past = max(0.0, (tip - centre) @ direction - depth_m)
        return 0.5 * qd @ mass @ qd + 0.5 * stiffness * past**2

    for i in range(int(seconds / DT)):
        t = i * DT
        tau_wall = arash.render_fixtures(robot, fixtures, q, qd)["torque"]
        if energy0 is None:
            energy0 = stored(q, qd)
        h = DT / 4
        for s in range(4):
            ts = t + s * h
            a1, p1 = derivative(q, qd, ts, tau_wall)
            a2, p2 = derivative(q + h / 2 * qd, qd + h / 2 * a1, ts + h / 2, tau_wall)
            a3, p3 = derivative(q + h / 2 * (qd + h / 2 * a1), qd + h / 2 * a2, ts + h / 2, tau_wall)
            a4, p4 = derivative(q + h * (qd + h / 2 * a2), qd + h * a3, ts + h, tau_wall)
            work += h / 6 * (p1 + 2 * p2 + 2 * p3 + p4)
            q = q + h / 6 * (qd + 2 * (qd + h / 2 * a1) + 2 * (qd + h / 2 * a2) + (qd + h * a3))
            qd = qd + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
        excess.append(stored(q, qd) - energy0 - work)
    return np.array(excess)


def start_depth(arm):
    _, ref, _ = arm
    tip, direction, _, centre = tip_frame(ref, START)
    return (tip - centre) @ direction


def test_at_its_bound_the_wall_stores_no_more_than_the_hand_gave_and_a_fifth_above_it_feeds_energy_in(arm):
    robot = arm[0]
    depth = start_depth(arm) + 0.001
    # Colgate and Schenkel's sampled wall, held from the cycle's start: no latency beyond the hold.
    bound = arash.fixture_bounds(robot, wall(depth, 1.0), latency_s=0.0)["fixtures"]["wall[0]"]["stiffness_bound"]
    # The insertion's damping over half the period: the bound is the condition on the joint the
    # depth moves with.
    assert bound == pytest.approx(2.0 * arm[2][2] / DT, rel=1e-9)
    passive = press(arm, wall(depth, 0.999 * bound), 0.999 * bound, depth)
    assert passive.max() <= 1e-6, f"the wall at its bound gave out {passive.max():.3g} J more than the hand put in"
    # The bound is sharp: a fifth above it the wall already gives out energy (6.6e-5 J measured).
    active = press(arm, wall(depth, 1.2 * bound), 1.2 * bound, depth)
    assert active.max() > 1e-5, f"a fifth above the bound the wall stayed passive ({active.max():.3g} J)"


def test_a_fixture_file_with_a_bad_field_a_nan_or_a_stiffness_over_the_bound_is_refused_by_name():
    robot = arash.Robot.arash_asist()
    with pytest.raises(ValueError, match="stifness"):
        arash.fixture_bounds(robot, "[[wall]]\ndepth_m = 0.01\nstifness = 10.0\ndamping = 0.0\n")
    with pytest.raises(ValueError, match=r"wall\[0\]\.stiffness = NaN"):
        arash.fixture_bounds(robot, wall(0.01, "nan"))
    with pytest.raises(ValueError, match=r"cone\[0\]\.half_angle_deg"):
        arash.fixture_bounds(robot, "[[cone]]\naxis = [0.0, 0.0, 1.0]\nhalf_angle_deg = 95.0\nstiffness = 1.0\ndamping = 0.0\n")
    with pytest.raises(ValueError, match=r"wall\[0\]\.stiffness = 5000 N/m is above the passivity bound 1333\.3333 N/m"):
        arash.fixture_bounds(robot, wall(0.01, 5000.0))
