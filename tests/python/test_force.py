"""The hand's force against an independent simulation: Pinocchio's dynamics of ARASH:ASiST with a
force applied at the instrument tip through Pinocchio's own frame Jacobian, not arash's plant.

The arm tracks a sinusoid under a PD law (gravity compensated by Pinocchio) while a press of known
shape pushes on the tip. arash's momentum observer sees only the log (t, q, q̇, τ) and must return
the press's joint torque and tip force through its first-order lag.
"""

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")
import arash  # noqa: E402

from support.independent import Expanded  # noqa: E402
from support.paths import ROBOT_FILES  # noqa: E402

DT = 1e-3
BANDWIDTH_HZ = 25.0
VISCOUS = np.array([0.005, 0.005, 2.0])


def press(t):
    """A tip force (N, base frame) that rises and falls as a raised cosine over 0.6 s from 0.8 s."""
    shape = np.where((t > 0.8) & (t < 1.4), 0.5 * (1.0 - np.cos(2.0 * np.pi * (t - 0.8) / 0.6)), 0.0)
    return np.outer(shape, [0.6, -0.9, -1.5])


def simulate(seconds=2.2):
    """The arm under PD, pressed at the tip: Pinocchio's M and bias, RK4 in four steps per cycle,
    command and force held over each cycle as a drive and a hand at 1 kHz would."""
    path = ROBOT_FILES["arash_asist"]
    robot = arash.Robot.from_urdf(path)
    ref = Expanded(path, robot)
    tip = ref.model.getFrameId("instrument_tip")

    def tip_torque(q, force):
        config = ref.configuration(q)
        jac = pin.computeFrameJacobian(ref.model, ref.data, config, tip, pin.LOCAL_WORLD_ALIGNED)
        return ref.G.T @ (jac[:3].T @ force)

    def acceleration(q, qd, tau):
        mass, bias = ref.dynamics(q, qd)
        return np.linalg.solve(mass, tau - bias - VISCOUS * qd)

    steps = int(seconds / DT)
    t = np.arange(steps) * DT
    forces = press(t)
    q, qd = np.array([0.1, 0.5, 0.015]), np.zeros(3)
    log_q, log_qd, log_tau, log_ext = (np.zeros((steps, 3)) for _ in range(4))
    for i in range(steps):
        target = np.array([0.1 + 0.3 * np.sin(2.0 * t[i]), 0.5 + 0.2 * np.sin(3.0 * t[i]), 0.015 + 0.006 * np.sin(4.0 * t[i])])
        _, gravity = ref.dynamics(q, np.zeros(3))
        tau = gravity + np.array([20.0, 20.0, 400.0]) * (target - q) - np.array([1.0, 1.0, 20.0]) * qd
        external = tip_torque(q, forces[i])
        log_q[i], log_qd[i], log_tau[i], log_ext[i] = q, qd, tau, external
        h = DT / 4
        for _ in range(4):
            k1q, k1v = qd, acceleration(q, qd, tau + external)
            k2q, k2v = qd + h / 2 * k1v, acceleration(q + h / 2 * k1q, qd + h / 2 * k1v, tau + external)
            k3q, k3v = qd + h / 2 * k2v, acceleration(q + h / 2 * k2q, qd + h / 2 * k2v, tau + external)
            k4q, k4v = qd + h * k3v, acceleration(q + h * k3q, qd + h * k3v, tau + external)
            q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            qd = qd + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    return robot, t, log_q, log_qd, log_tau, log_ext, forces


def lagged(x, hz):
    """The first-order lag at ``hz`` of a signal held over each cycle (the observer's ideal)."""
    alpha = 1.0 - np.exp(-2.0 * np.pi * hz * DT)
    out = np.zeros_like(x)
    for i in range(1, len(x)):
        out[i] = out[i - 1] + alpha * (x[i - 1] - out[i - 1])
    return out


@pytest.fixture(scope="module")
def pressed_arm():
    return simulate()


def params_of(robot):
    params = robot.cad_parameters()
    names = robot.parameter_names()
    for k, joint in enumerate(robot.joint_names()):
        params[names.index(f"{joint}.fv")] = VISCOUS[k]
        params[names.index(f"{joint}.fc")] = 0.0
    return params


def test_the_observer_returns_a_press_at_the_tip_simulated_by_pinocchio(pressed_arm):
    robot, t, q, qd, tau, external, forces = pressed_arm
    out = arash.external_force(
        robot, t, q, tau, qd=qd, bandwidth_hz=BANDWIDTH_HZ, params=params_of(robot),
        frame="instrument_tip", about="remote_centre", sigma=[0.01, 0.01, 0.1], torque="held",
    )
    truth = lagged(external, BANDWIDTH_HZ)
    peak = np.abs(external).max(axis=0)
    error = np.abs(out["tau_ext"] - truth).max(axis=0) / peak
    assert np.all(error < 0.02), f"joint torque error / peak {error}"
    assert not out["singular"].any()
    force_error = np.abs(out["force"] - lagged(forces, BANDWIDTH_HZ)).max(axis=0) / np.abs(forces).max(axis=0)
    assert np.all(force_error < 0.03), f"tip force error / peak {force_error}"
    quiet = t < 0.75
    assert np.abs(out["force"][quiet]).max() < 0.02 * np.abs(forces).max(), "a force where there was none"


def test_the_same_log_without_the_friction_model_misses_the_press(pressed_arm):
    """The check above can fail: the CAD friction the arm does not have is read as a hand."""
    robot, t, q, qd, tau, external, _ = pressed_arm
    out = arash.external_force(robot, t, q, tau, qd=qd, bandwidth_hz=BANDWIDTH_HZ, torque="held")
    error = np.abs(out["tau_ext"] - lagged(external, BANDWIDTH_HZ)).max(axis=0) / np.abs(external).max(axis=0)
    assert error.max() > 0.05, f"the CAD friction changed nothing: {error}"


def test_the_zero_phase_estimate_returns_the_press_itself_without_the_lag(pressed_arm):
    """Offline the observer's lag is undone: the estimate matches the applied press, not its lagged
    copy, to a third of the causal estimate's error against the same press."""
    robot, t, q, qd, tau, external, forces = pressed_arm
    options = dict(qd=qd, bandwidth_hz=BANDWIDTH_HZ, params=params_of(robot), frame="instrument_tip",
                   about="remote_centre", torque="held")
    causal = arash.external_force(robot, t, q, tau, **options)
    smooth = arash.external_force(robot, t, q, tau, zero_phase=True, **options)
    inside = (t > 0.3) & (t < t[-1] - 0.3)

    def error(out):
        return (np.abs(out["force"] - forces)[inside].max(axis=0) / np.abs(forces).max(axis=0),
                np.abs(out["tau_ext"] - external)[inside].max(axis=0) / np.abs(external).max(axis=0))

    (smooth_force, smooth_joint), (causal_force, causal_joint) = error(smooth), error(causal)
    assert np.all(smooth_force < 0.02) and np.all(smooth_joint < 0.02), f"zero-phase error / peak {smooth_force}, {smooth_joint}"
    assert np.all(smooth_joint < causal_joint / 2.5), f"no better than the causal estimate: {smooth_joint} vs {causal_joint}"
    assert any(c["code"] == "zero_phase" for c in smooth["choices"]), smooth["reasons"]


def test_bad_input_is_refused_by_name():
    robot = arash.Robot.arash_asist()
    t = np.arange(5) * DT
    q = np.tile([0.1, 0.5, 0.01], (5, 1))
    with pytest.raises(ValueError, match="no frame `tool`"):
        arash.external_force(robot, t, q, q * 0, qd=q * 0, bandwidth_hz=10.0, frame="tool")
    bad = q.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="q is not finite at sample 3"):
        arash.external_force(robot, t, bad, q * 0, qd=q * 0, bandwidth_hz=10.0)
    with pytest.raises(ValueError, match="bandwidth on joint 0"):
        arash.external_force(robot, t, q, q * 0, qd=q * 0, bandwidth_hz=-1.0)
    with pytest.raises(ValueError, match='torque is "measured"'):
        arash.external_force(robot, t, q, q * 0, qd=q * 0, bandwidth_hz=10.0, torque="measured")
    with pytest.raises(ValueError, match="t does not increase at sample 2"):
        arash.external_force(robot, t[[0, 1, 1, 3, 4]], q, q * 0, qd=q * 0, bandwidth_hz=10.0)
    with pytest.raises(ValueError, match="no held-out residual statistics"):
        arash.external_force(robot, t, q, q * 0, qd=q * 0, bandwidth_hz=10.0, thresholds="sigma")
    with pytest.raises(ValueError, match=r"collision threshold on joint 2 \(0.5\) is below the contact"):
        arash.external_force(robot, t, q, q * 0, qd=q * 0, bandwidth_hz=10.0, thresholds=([1.0, 1.0, 1.0], [2.0, 2.0, 0.5]))


def test_a_press_over_the_collision_threshold_is_flagged_within_20_ms(pressed_arm):
    """The press's joint torque crosses a collision level set by hand; the estimate, a 25 Hz lag of
    it, must cross within 20 ms (issue 58), flag nothing before the press, and report one episode."""
    robot, t, q, qd, tau, external, _ = pressed_arm
    peak = np.abs(external).max(axis=0)
    contact, collision = 0.1 * peak, 0.3 * peak
    out = arash.external_force(robot, t, q, tau, qd=qd, bandwidth_hz=BANDWIDTH_HZ, params=params_of(robot),
                               torque="held", thresholds=(contact, collision))
    crossed = np.argmax((np.abs(external) > collision).any(axis=1))
    flagged = np.argmax(out["level"] == 2)
    assert out["level"][flagged] == 2 and flagged >= crossed, (crossed, flagged)
    assert (t[flagged] - t[crossed]) <= 0.020, f"flagged {1e3 * (t[flagged] - t[crossed]):.1f} ms after the crossing"
    assert not out["level"][t < 0.75].any()
    assert [e[2] for e in out["episodes"]] == [2], out["episodes"]
    np.testing.assert_allclose(out["collision_threshold"], collision)


def test_the_held_out_residual_is_the_unmodelled_torque_of_the_held_out_run():
    """Identified on one Pinocchio log, held out on another of the same robot with a constant torque
    the model lacks on the pitch: the recorded σ on the pitch is that torque, the others stay at the
    noise, and thresholds="sigma" then sits at 4σ and 8σ of it."""
    from support.independent import Condition, make_log

    shape = ("arash_asist", 1000, 16, 0.01, "sign", None, 9.0)
    robot, train, truth = make_log(Condition(*shape, seed=5801))
    _, (t, q, tau), _ = make_log(Condition(*shape, seed=5802), truth=truth)
    offset = 20.0 * truth["noise"][1]
    held = tau + np.array([0.0, offset, 0.0])
    model = arash.identify(robot, *train).with_held_out([(t, q, held)])
    rms = model.held_out["rms"]
    assert abs(rms[1] - offset) < 0.1 * offset, (rms, offset)
    assert np.all(rms[[0, 2]] < 2.0 * truth["noise"][[0, 2]]), (rms, truth["noise"])
    # The samples the filter has settled on (its start-up is left out), thinned as the fit was.
    assert 0 < model.held_out["samples"] <= len(t) and model.held_out["source"] == "validation runs: runs[0]"
    # The observer on the same held-out run, hand-free: the pitch's constant torque passes every
    # bandwidth alike, so the pitch widens to the grid's end and its σ is that torque; the yaw's
    # noise grows with the band and keeps it at the least. Each joint takes the widest bandwidth
    # whose σ is within 25 % of its σ at the least.
    observer = model.held_out["observer"]
    grid, sigma = observer["grid_hz"], observer["grid_sigma"]
    assert grid[0] == 20.0 and np.all(np.diff(grid) > 0), grid
    assert observer["bandwidth_hz"][1] == grid[-1] and abs(observer["sigma"][1] - offset) < 0.1 * offset, observer
    assert sigma[1, 0] > 1.25 * sigma[0, 0] and observer["bandwidth_hz"][0] == grid[0], observer
    for k in range(3):
        widest = max(g for g in range(len(grid)) if sigma[g, k] <= 1.25 * sigma[0, k])
        assert observer["bandwidth_hz"][k] == grid[widest] and observer["sigma"][k] == sigma[widest, k], (k, observer)
    out = arash.external_force(robot, t, q, tau, model=model, thresholds="sigma")
    assert any(c["code"] == "sigma_from_observer" for c in out["choices"]), out["reasons"]
    np.testing.assert_allclose(out["bandwidth_hz"], observer["bandwidth_hz"])
    np.testing.assert_allclose(out["sigma_joint"], observer["sigma"])
    np.testing.assert_allclose(out["contact_threshold"], 4.0 * observer["sigma"])
    # Collision at 8σ, raised to 1.5 × the largest hand-free estimate the held-out run reached.
    assert np.all(observer["peak"] >= observer["sigma"]), observer
    np.testing.assert_allclose(out["collision_threshold"], np.maximum(8.0 * observer["sigma"], 1.5 * observer["peak"]))
