"""Preprocessing + OLS against numpy/scipy doing the same steps (with arash's regressor, and with
Pinocchio's), and the consistent SDP against cvxpy.

Run from the repository root with the test venv:
    .venv/bin/python bench/identification_vs_scipy.py
Medians of repeated runs; the machine is shared.
"""

import sys
from pathlib import Path

import numpy as np
from scipy import signal

import arash
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from support.simulated import fourier_trajectory, log, true_parameters  # noqa: E402
from timing import median_seconds  # noqa: E402
from support.references import cvxpy_consistent  # noqa: E402
from support.paths import ROBOT_FILES  # noqa: E402
from support.independent import Expanded  # noqa: E402

FS = 1000.0
# The friction velocity's cut-off both pipelines use (Hz), set so that arash runs no search.
FRICTION_CUTOFF = 20.0


def pinocchio_reduced_regressor(ref, robot, base, q, qd, qdd):
    """Y_r from Pinocchio's joint-torque regressor on the expanded tree: the tree states in numpy
    for all samples at once, one Pinocchio call per sample (it has no batched API), then
    Gᵀ·Y_tree·T, the friction and elastic columns and the independent columns in numpy."""
    angles = q @ ref.G.T + ref.offset
    config = np.zeros((len(q), ref.model.nq))
    for jid in range(1, ref.model.njoints):
        joint = ref.model.joints[jid]
        theta = angles[:, joint.idx_v]
        if joint.nq == 2:
            config[:, joint.idx_q], config[:, joint.idx_q + 1] = np.cos(theta), np.sin(theta)
        else:
            config[:, joint.idx_q] = theta
    v, a = qd @ ref.G.T, qdd @ ref.G.T
    tree = np.empty((len(q), ref.model.nv, 10 * (ref.model.njoints - 1)))
    for i in range(len(q)):
        tree[i] = pin.computeJointTorqueRegressor(ref.model, ref.data, config[i], v[i], a[i])
    rigid = ref.G.T @ tree @ ref.T
    n = robot.dof
    joint_cols = np.zeros((len(q), n, 3 * n))
    for k in range(n):
        joint_cols[:, k, 2 * k] = qd[:, k]
        joint_cols[:, k, 2 * k + 1] = np.sign(qd[:, k])
        joint_cols[:, k, 2 * n + k] = q[:, k]
    return np.concatenate([rigid, joint_cols], axis=2)[:, :, base.independent]


def scipy_pipeline(robot, base, t, q, tau, periods, cutoff, regressor=None, friction_cutoff=FRICTION_CUTOFF):
    """The same steps in numpy/scipy: average, filter (sections, filtfilt padding), central
    differences, filter, regressor (arash's: there is no scipy one), the Coulomb columns switched by
    each period's velocity filtered at `friction_cutoff` and averaged, every column filtered like
    the torque, the filter's end transients left out, least squares."""
    sos = signal.butter(5, cutoff, fs=FS, output="sos")
    sos_friction = signal.butter(5, friction_cutoff, fs=FS, output="sos")

    def filt(x, periodic, sections=sos):
        if periodic:
            n = len(x)
            return signal.sosfiltfilt(sections, np.concatenate([x, x, x]), axis=0, padtype="odd", padlen=18)[n:2 * n]
        return signal.sosfiltfilt(sections, x, axis=0, padtype="odd", padlen=18)

    periodic = periods is not None
    h = 1 / FS
    diff = (lambda x: (np.roll(x, -1, 0) - np.roll(x, 1, 0)) / (2 * h)) if periodic else (lambda x: np.gradient(x, h, axis=0))
    # Each period's own friction velocity: the whole periods end to end are one periodic signal.
    whole = q[: len(q) // (periods or 1) * (periods or 1)]
    directions = np.sign(filt(diff(whole), periodic, sos_friction))
    if periodic:
        per = len(t) // periods
        q = q[: per * periods].reshape(periods, per, -1).mean(axis=0)
        tau = tau[: per * periods].reshape(periods, per, -1).mean(axis=0)
        directions = directions.reshape(periods, per, -1).mean(axis=0)
    qf = filt(q, periodic)
    qd = filt(diff(qf), periodic)
    qdd = filt(diff(qd), periodic)
    tauf = filt(tau, periodic)
    Yr = (regressor or base.reduced_regressor)(qf, qd, qdd)
    names = robot.parameter_names()
    coulomb = [base.independent.index(names.index(f"{joint}.fc")) for joint in robot.joint_names()]
    Yr[:, range(robot.dof), coulomb] = directions
    Yr = filt(Yr.reshape(len(Yr), -1), periodic).reshape(Yr.shape)
    # A log that is not periodic loses five cut-off periods at each end, where the zero-phase
    # filter starts up (arash does the same).
    edge = 0 if periodic else int(np.ceil(5 * FS / cutoff))
    Yr, tauf = Yr[edge:len(Yr) - edge], tauf[edge:len(tauf) - edge]
    beta, *_ = np.linalg.lstsq(Yr.reshape(-1, base.p), tauf.reshape(-1), rcond=None)
    return beta


def main():
    # Like with like: the peer takes sign(q̇) on every joint, so arash is told the same law
    # (declared, None = sign) and both cut-offs, and then chooses nothing inside the timed call.
    # What arash's choices cost on top is timed apart below, with nothing declared.
    robot = arash.Robot.arash_asist(friction_velocities=[None] * 3)
    assert robot.coulomb_laws_declared
    undeclared = arash.Robot.arash_asist()
    base = robot.base_parameters(regroup_weak=True)  # the base parameters arash.identify fits
    ref = Expanded(ROBOT_FILES["arash_asist"], robot)
    rng = np.random.default_rng(0)
    truth = true_parameters(robot, rng)
    traj = fourier_trajectory(robot, rng)
    t = np.arange(300_000) / FS
    t, q, tau = log(robot, truth, traj, t, rng)
    cutoff = 1.6667
    fixed = {"cutoff_hz": cutoff, "friction_cutoff_hz": FRICTION_CUTOFF}

    for periods, label in ((20, "20 periods averaged (paper)"), (None, "no averaging: all 300,000 samples")):
        ours = median_seconds(lambda: arash.identify(robot, t, q, tau, method="ols", periods=periods or 1, **fixed), 5)
        peer = median_seconds(lambda: scipy_pipeline(robot, base, t, q, tau, periods, cutoff), 5)
        a = arash.identify(robot, t, q, tau, method="ols", periods=periods or 1, **fixed).beta
        b = scipy_pipeline(robot, base, t, q, tau, periods, cutoff)
        agree = np.abs(a - b).max() / np.abs(b).max()
        print(f"preprocess + OLS, {label}: arash {ours * 1e3:.0f} ms, numpy/scipy {peer * 1e3:.0f} ms, "
              f"ratio {peer / ours:.1f}×; β agree to {agree:.1e} (max rel.)")
        # Both pipelines evaluate arash's regressor at every preprocessed sample, so no arash
        # pipeline can beat the peer by more than the peer's time over that evaluation alone.
        samples = len(t) // (periods or 1)
        states = traj(t[:samples])
        regressor = median_seconds(lambda: base.reduced_regressor(*states), 5)
        print(f"  of which the regressor on {samples} samples (both pipelines): {regressor * 1e3:.0f} ms; "
              f"bound on the ratio: {peer / regressor:.1f}×")
        # The fully independent peer: Pinocchio's regressor instead of arash's.
        pinocchio = lambda *s: pinocchio_reduced_regressor(ref, robot, base, *s)  # noqa: E731
        repeats = 5 if periods else 1
        independent = median_seconds(
            lambda: scipy_pipeline(robot, base, t, q, tau, periods, cutoff, pinocchio), repeats)
        c = scipy_pipeline(robot, base, t, q, tau, periods, cutoff, pinocchio)
        agree = np.abs(a - c).max() / np.abs(c).max()
        print(f"  numpy/scipy with Pinocchio's regressor: {independent * 1e3:.0f} ms, "
              f"ratio {independent / ours:.1f}×; β agree to {agree:.1e} (max rel.)")
        # Not a comparison (the peer makes no choice): arash's defaults, each Coulomb law and both
        # cut-offs chosen from the data, on the same log.
        chosen = median_seconds(lambda: arash.identify(undeclared, t, q, tau, method="ols", periods=periods or 1), 3)
        print(f"  arash with every choice from the data (laws, cut-offs): {chosen * 1e3:.0f} ms, "
              f"of which the choices {(chosen - ours) * 1e3:.0f} ms")

    import cvxpy as cp

    for samples in (1000, 3000):
        q_s, qd_s, qdd_s = traj(np.linspace(0, 15, samples, endpoint=False))
        W = robot.regressor(q_s, qd_s, qdd_s).reshape(-1, robot.num_params)
        tau_s = W @ truth + np.tile([0.003, 0.003, 0.05], samples) * rng.normal(size=3 * samples)
        ours = median_seconds(lambda: arash.consistent_least_squares(robot, W, tau_s), 7)
        peer = median_seconds(lambda: cvxpy_consistent(cp, robot, W, tau_s, 1e-4), 3)
        print(f"consistent SDP, {samples} samples ({3 * samples}×89 W): arash {ours * 1e3:.1f} ms "
              f"(including forming WᵀW), cvxpy+Clarabel {peer * 1e3:.0f} ms (including modelling), ratio {peer / ours:.0f}×")


if __name__ == "__main__":
    main()
