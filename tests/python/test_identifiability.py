"""Identifiability against what the robot can reach (issue 18, item 1), checked with numpy on
trajectories arash did not make: sums of sines at random frequencies (not arash's Fourier family,
not its periods), scaled into the position, speed and acceleration limits."""

import numpy as np
import pytest

import arash
from support.paths import kuka_urdf, random_physical_params, tx40_urdf


def reachable_trajectories(robot, count, rng, samples=200):
    """`count` trajectories of `samples` instants: per joint 4 sines at 0.05–0.8 Hz with random
    phases, scaled until range, speed or acceleration (5 × the speed limit per second) reaches
    its limit, centred in the range."""
    lo = np.array([a for a, _ in robot.position_limits()])
    hi = np.array([b for _, b in robot.position_limits()])
    vmax = np.array(robot.velocity_limits())
    lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    vmax = np.where(np.isfinite(vmax), vmax, 2.0)
    amax = 5 * vmax
    Q, QD, QDD = [], [], []
    for _ in range(count):
        t = np.linspace(0, rng.uniform(10, 40), samples)
        q, qd, qdd = (np.empty((samples, robot.dof)) for _ in range(3))
        for j in range(robot.dof):
            w = 2 * np.pi * rng.uniform(0.05, 0.8, 4)
            c, ph = rng.normal(size=4), rng.uniform(0, 2 * np.pi, 4)
            x = (c * np.sin(np.outer(t, w) + ph)).sum(1)
            v = (c * w * np.cos(np.outer(t, w) + ph)).sum(1)
            a = (-c * w * w * np.sin(np.outer(t, w) + ph)).sum(1)
            k = min(0.95 * (hi[j] - lo[j]) / np.ptp(x), vmax[j] / abs(v).max(), amax[j] / abs(a).max())
            q[:, j] = 0.5 * (hi[j] + lo[j]) + k * (x - 0.5 * (x.max() + x.min()))
            qd[:, j], qdd[:, j] = k * v, k * a
        Q.append(q), QD.append(qd), QDD.append(qdd)
    return np.vstack(Q), np.vstack(QD), np.vstack(QDD)


def relative_residuals(W):
    """Each column's part outside the span of all the others, over its norm (numpy lstsq)."""
    out = []
    for k in range(W.shape[1]):
        others = np.delete(W, k, axis=1)
        c, *_ = np.linalg.lstsq(others, W[:, k], rcond=None)
        out.append(np.linalg.norm(W[:, k] - others @ c) / np.linalg.norm(W[:, k]))
    return np.array(out)


@pytest.fixture(scope="module")
def robot():
    return arash.Robot.arash_asist()


def test_the_weak_base_parameter_is_the_one_no_reachable_trajectory_separates(robot):
    exact, base = robot.base_parameters(), robot.base_parameters(regroup_weak=True)
    assert (exact.p, base.p) == (23, 22)
    assert [w[0] for w in base.weak] == ["instrument_holder.my_R"]
    q, qd, qdd = reachable_trajectories(robot, 48, np.random.default_rng(3))
    W = exact.reduced_regressor(q, qd, qdd).reshape(-1, exact.p)
    weak = exact.names.index("instrument_holder.my_R")
    # On trajectories the test drew itself (7.5e-4 against 3.7e-2 when written): the weak column
    # is numerically in the span of the others; without it, every other column is well outside
    # the span of the rest.
    residual = relative_residuals(W)[weak]
    others = relative_residuals(np.delete(W, weak, axis=1))
    assert residual < 2e-3, residual
    assert residual < 0.05 * others.min(), (residual, np.sort(others)[:3])


def test_regrouped_base_parameters_reproduce_the_torque_on_reachable_trajectories(robot):
    base, exact = robot.base_parameters(regroup_weak=True), robot.base_parameters()
    q, qd, qdd = reachable_trajectories(robot, 16, np.random.default_rng(4))
    Y = robot.regressor(q, qd, qdd)
    for seed in range(5):
        pi = random_physical_params(robot, np.random.default_rng(seed))
        tau = Y @ pi
        regrouped = base.reduced_regressor(q, qd, qdd) @ base.project(pi)
        kept = [exact.independent.index(c) for c in base.independent]
        dropped = exact.reduced_regressor(q, qd, qdd)[..., kept] @ exact.project(pi)[kept]
        for j in range(robot.dof):
            scale = np.linalg.norm(tau[:, j])
            error = np.linalg.norm(tau[:, j] - regrouped[:, j]) / scale
            assert error < 2e-3, (seed, j, error)
            # Regrouping does better than leaving the weak parameter out.
            assert error <= 0.1 * np.linalg.norm(tau[:, j] - dropped[:, j]) / scale + 1e-12, (seed, j)


def test_the_design_reports_the_condition_number_both_ways(robot):
    exc = arash.design_excitation(robot, restarts=2, quiet=True)
    assert exc.condition_number < 300
    assert exc.condition_number_with_weak > 1e3
    q, qd, qdd = exc.sample(200.0)[1:]
    for regroup_weak, kappa in [(True, exc.condition_number), (False, exc.condition_number_with_weak)]:
        base = robot.base_parameters(regroup_weak=regroup_weak)
        # arash's κ samples 150 instants of one period; 200 Hz sampling gives nearly the same.
        W = base.reduced_regressor(q, qd, qdd).reshape(-1, base.p)
        s = np.linalg.svd(W / np.linalg.norm(W, axis=0), compute_uv=False)
        assert s[0] / s[-1] == pytest.approx(kappa, rel=0.2)


@pytest.mark.parametrize("urdf", [kuka_urdf, tx40_urdf], ids=["kuka", "tx40"])
def test_measured_robots_have_no_weak_base_parameter(urdf):
    robot = arash.Robot.from_urdf(urdf())
    base = robot.base_parameters(regroup_weak=True)
    assert base.weak == [] and base.p == robot.base_parameters().p
    assert "none" in base.weak_report()


@pytest.mark.parametrize("designed", [False, True], ids=["random sines", "arash's design"])
def test_identify_fits_the_identifiable_base_parameters_unless_told_to_keep_the_weak_one(designed):
    """On a log of Pinocchio's dynamics (not arash's simulator), the default fit regroups the weak
    parameter, says so, and predicts as well as the fit that keeps it, while the parameters the
    weak one leaned on are no longer lost in its noise."""
    pytest.importorskip("pinocchio")
    from support import independent

    condition = independent.Condition("arash_asist", 1000, 16, 0.01, "sign", 4, 60.0, seed=4, designed=designed)
    robot, log, _ = independent.make_log(condition)
    regrouped = arash.identify(robot, *log)
    kept = arash.identify(robot, *log, keep_weak=True)
    assert regrouped.base.names == robot.base_parameters(regroup_weak=True).names
    assert kept.base.names == robot.base_parameters().names
    grouped = [c for c in regrouped.settings["choices"] if c["code"] == "regrouped"]
    assert grouped and "instrument_holder.my_R" in grouped[0]["names"], regrouped.settings["reasons"]
    assert not any(c["code"] == "regrouped" for c in kept.settings["choices"]), kept.settings["reasons"]
    # The weak direction is what set κ (10⁵–10⁶ when written; 350–1000 without it).
    assert regrouped.condition_number < 0.01 * kept.condition_number
    np.testing.assert_allclose(regrouped.fp_percent, kept.fp_percent, atol=0.2)
    # rocker_a.my_R, the column the weak one nearly repeats: its σ shrinks tenfold or more.
    assert absolute_sigma(regrouped, "rocker_a.my_R") < 0.1 * absolute_sigma(kept, "rocker_a.my_R")


def absolute_sigma(ident, name):
    k = ident.base.names.index(name)
    return ident.sigma_percent[k] / 100 * abs(ident.beta[k])


def test_the_diagnosis_fits_the_exact_base_parameters():
    """The regrouping's residual is a bias of arash's own that an effect could take up, so the
    diagnosis keeps the weak parameter (its inertial parameters are nuisance)."""
    pytest.importorskip("pinocchio")
    from support import independent

    robot, log, _ = independent.make_log(independent.Condition("arash_asist", 200, 16, 0.01, "sign", None, 10.0, seed=5))
    assert arash.diagnose(robot, *log).model.base.names == robot.base_parameters().names
    assert arash.identify(robot, *log).base.p == 22
