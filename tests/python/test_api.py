"""The Python contract: shapes, dtypes, base parameters, and clear ValueErrors for bad input."""

import numpy as np
import pytest

import arash
from support.paths import ROBOT_FILES, random_physical_params, random_states


@pytest.fixture(scope="module")
def robot():
    return arash.Robot.arash_asist()


@pytest.fixture(scope="module")
def states(robot):
    return random_states(robot, 500, np.random.default_rng(3))


def test_bundled_robot_matches_the_file(robot):
    from_file = arash.Robot.from_urdf(ROBOT_FILES["arash_asist"])
    assert robot.parameter_names() == from_file.parameter_names()
    np.testing.assert_array_equal(robot.cad_parameters(), from_file.cad_parameters())
    assert robot.dof == 3 and robot.num_params == 89 and len(robot.parameter_names()) == 89
    assert robot.joint_names() == ["yaw", "pitch", "insertion"]
    assert len(robot.body_names()) == 8


def test_batched_shapes_and_single_samples(robot, states):
    q, qd, qdd = states
    Y = robot.regressor(q, qd, qdd)
    assert Y.shape == (500, 3, 89) and Y.dtype == np.float64
    np.testing.assert_array_equal(robot.regressor(q[7], qd[7], qdd[7]), Y[7])
    assert robot.mass_matrix(q).shape == (500, 3, 3)
    assert robot.coriolis_matrix(q, qd).shape == (500, 3, 3)
    assert robot.gravity(q).shape == (500, 3)
    assert robot.inverse_dynamics(q, qd, qdd).shape == (500, 3)
    assert robot.slotine_li_regressor(q, qd, qd, qdd).shape == (500, 3, 89)
    # Non-contiguous input is accepted and read correctly.
    wide = np.zeros((500, 6))
    wide[:, ::2] = q
    np.testing.assert_array_equal(robot.regressor(wide[:, ::2], qd, qdd), Y)


def test_large_batches_split_across_threads_give_the_same_answer(robot):
    q, qd, qdd = random_states(robot, 5000, np.random.default_rng(4))
    Y = robot.regressor(q, qd, qdd)
    for i in (0, 2499, 2500, 4999):
        np.testing.assert_array_equal(robot.regressor(q[i], qd[i], qdd[i]), Y[i])


def test_regressor_and_inverse_dynamics_agree(robot, states):
    q, qd, qdd = states
    params = random_physical_params(robot, np.random.default_rng(5))
    tau = robot.inverse_dynamics(q, qd, qdd, params)
    np.testing.assert_allclose(robot.regressor(q, qd, qdd) @ params, tau, rtol=1e-11, atol=1e-12)
    # Forward dynamics undoes inverse dynamics.
    np.testing.assert_allclose(robot.forward_dynamics(q, qd, tau, params), qdd, rtol=1e-8, atol=1e-8)


def test_base_parameters(robot, states):
    base = robot.base_parameters()  # exact: Y π = Y_r β to round-off
    assert base.p == 23 and base.weak == []
    assert base.B.shape == (23, 89)
    assert len(base.names) == len(base.expressions) == 23
    assert all(e.startswith(f"β{i + 1} = ") for i, e in enumerate(base.expressions))
    np.testing.assert_array_equal(base.B[:, base.independent], np.eye(23))
    q, qd, qdd = states
    pi = np.random.default_rng(6).normal(size=89)  # any π: the identity is algebraic
    Y, Yr = robot.regressor(q, qd, qdd), base.reduced_regressor(q, qd, qdd)
    assert Yr.shape == (500, 3, 23)
    np.testing.assert_allclose(Yr @ base.project(pi), Y @ pi, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(base.project(pi), base.B @ pi, rtol=1e-14)
    # The rank is a property of the robot, not of the samples.
    assert robot.base_parameters(samples=150, seed=99).p == 23


def test_reduced_regressor_is_well_conditioned_enough_to_identify(robot):
    """Least squares on Y_r recovers β exactly from noise-free torques: Y_r has full column rank."""
    base = robot.base_parameters()
    q, qd, qdd = random_states(robot, 2000, np.random.default_rng(8))
    pi = random_physical_params(robot, np.random.default_rng(9))
    tau = robot.inverse_dynamics(q, qd, qdd, pi).reshape(-1)
    W = base.reduced_regressor(q, qd, qdd).reshape(-1, base.p)
    beta, *_ = np.linalg.lstsq(W, tau, rcond=None)
    np.testing.assert_allclose(beta, base.project(pi), rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda r, z: r.regressor(np.zeros((4, 2)), z, z), "q must have shape (N, 3) or (3,)"),
        (lambda r, z: r.regressor(z, np.zeros((5, 3)), z), "q has 4 samples but qd has 5"),
        (lambda r, z: r.regressor(z, z, np.full((4, 3), np.nan)), "qdd is not finite at sample 0"),
        (lambda r, z: r.inverse_dynamics(z, z, z, np.zeros(88)), "params"),
        (lambda r, z: r.mass_matrix(np.zeros((2, 2, 3))), "q must have shape"),
        (lambda r, z: r.gravity(np.array([0.0, np.inf, 0.0])), "q is not finite at sample 0, entry 1"),
        (lambda r, z: r.base_parameters(samples=3), "got 3"),
    ],
)
def test_bad_input_raises_value_error_naming_it(robot, call, message):
    with pytest.raises(ValueError) as err:
        call(robot, np.zeros((4, 3)))
    assert message in str(err.value)


def test_bad_robot_files_raise_value_error(tmp_path):
    with pytest.raises(ValueError, match="cannot read URDF"):
        arash.Robot.from_urdf(tmp_path / "missing.urdf")
    broken = tmp_path / "broken.urdf"
    broken.write_text('<robot name="x"><link name="a"/><link name="b"/>'
                      '<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
                      '<limit lower="-1" upper="1" velocity="1" effort="1"/></joint></robot>')
    with pytest.raises(ValueError, match="link `b`: is moved by joint `j` but has no <inertial>"):
        arash.Robot.from_urdf(broken)
    with pytest.raises(ValueError, match="coulomb_epsilon"):
        arash.Robot.arash_asist(coulomb_epsilon=-1.0)


def test_forward_dynamics_reports_non_physical_parameters(robot):
    params = robot.cad_parameters()
    params[6] = -1.0  # yaw yoke Izz
    with pytest.raises(ValueError, match="not positive definite"):
        robot.forward_dynamics(np.zeros(3), np.zeros(3), np.zeros(3), params)


def test_smooth_coulomb_option(robot):
    smooth = arash.Robot.arash_asist(coulomb_epsilon=0.01)
    Y = smooth.regressor(np.zeros(3), np.array([0.005, 0.0, 0.0]), np.zeros(3))
    fc_yaw = smooth.parameter_names().index("yaw.fc")
    assert Y[0, fc_yaw] == pytest.approx(np.tanh(0.5), rel=1e-14)
    assert robot.regressor(np.zeros(3), np.array([0.005, 0.0, 0.0]), np.zeros(3))[0, fc_yaw] == 1.0


def test_regressor_into_a_reused_buffer(robot, states):
    q, qd, qdd = states
    out = np.full((500, 3, 89), np.nan)
    result = robot.regressor(q, qd, qdd, out=out)
    assert result is out
    np.testing.assert_array_equal(out, robot.regressor(q, qd, qdd))
    with pytest.raises(ValueError, match=r"out must have shape \[500, 3, 89\]"):
        robot.regressor(q, qd, qdd, out=np.zeros((500, 3, 88)))
    with pytest.raises(ValueError, match="C-contiguous"):
        robot.regressor(q, qd, qdd, out=np.zeros((500, 89, 3)).transpose(0, 2, 1))
