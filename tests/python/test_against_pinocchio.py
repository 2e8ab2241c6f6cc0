"""Cross-check of the model against Pinocchio on the same URDF.

Pinocchio's algorithms do not take mimic joints, so the mimic tree is expanded into independent
tree coordinates, q_tree = multiplier · q + offset, read here from the URDF with ElementTree, and
torques map back through the coupling G: τ_q = Gᵀ τ_tree. Pinocchio orders a body's parameters
[m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] and merges a body on a fixed joint into its parent;
both are mapped explicitly.
"""

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")
import arash  # noqa: E402

from support.paths import ROBOT_FILES, kuka_urdf, random_physical_params, random_states, tx40_urdf  # noqa: E402
from support.independent import Expanded, joint_torques  # noqa: E402

STATES = 1000
TOLERANCE = 1e-9
def robot_cases():
    cases = [(name, path) for name, path in ROBOT_FILES.items()]
    return cases


def parameter_sets(robot, rng):
    return [("CAD", robot.cad_parameters())] + [(f"random {i}", random_physical_params(robot, rng)) for i in range(3)]


def relative_error(a, b):
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-12)


def check_against_pinocchio(path, seed):
    robot = arash.Robot.from_urdf(path)
    ref = Expanded(path, robot)
    rng = np.random.default_rng(seed)
    q, qd, qdd = random_states(robot, STATES, rng)
    Y = robot.regressor(q, qd, qdd)
    worst = {"tau": 0.0, "Y": 0.0, "M": 0.0, "g": 0.0, "C": 0.0}
    for label, params in parameter_sets(robot, rng):
        ref.set_parameters(params)
        tau = robot.inverse_dynamics(q, qd, qdd, params)
        M = robot.mass_matrix(q, params)
        g = robot.gravity(q, params)
        C = robot.coriolis_matrix(q, qd, params)
        for i in range(STATES):
            qt, vt, _ = ref.tree(q[i], qd[i], qdd[i])
            tau_pin = ref.torque(q[i], qd[i], qdd[i]) + joint_torques(robot, q[i], qd[i], params)
            err = relative_error(tau[i], tau_pin)
            assert err < TOLERANCE, f"{path.name} {label} state {i}: τ {tau[i]} vs Pinocchio {tau_pin}"
            worst["tau"] = max(worst["tau"], err)
            # Yπ must reproduce Pinocchio too, not only our own inverse dynamics.
            assert relative_error(Y[i] @ params, tau_pin) < TOLERANCE
            worst["M"] = max(worst["M"], relative_error(M[i], ref.mass_matrix(q[i])))
            g_pin = ref.G.T @ pin.computeGeneralizedGravity(ref.model, ref.data, qt)
            worst["g"] = max(worst["g"], relative_error(g[i], g_pin))
            C_pin = ref.G.T @ pin.computeCoriolisMatrix(ref.model, ref.data, qt, vt) @ ref.G
            worst["C"] = max(worst["C"], relative_error(C[i], C_pin))
    for i in range(STATES):
        qt, vt, at = ref.tree(q[i], qd[i], qdd[i])
        Y_pin = ref.G.T @ pin.computeJointTorqueRegressor(ref.model, ref.data, qt, vt, at) @ ref.T
        rigid = Y[i][:, : ref.T.shape[1]]
        err = relative_error(rigid, Y_pin)
        assert err < TOLERANCE, f"{path.name} state {i}: regressor differs from Pinocchio's by {err:.2e}"
        worst["Y"] = max(worst["Y"], err)
    for key in ("M", "g", "C"):
        assert worst[key] < TOLERANCE, f"{path.name}: {key} differs from Pinocchio's by {worst[key]:.2e}"
    return worst


@pytest.mark.parametrize("name,path", robot_cases(), ids=[c[0] for c in robot_cases()])
def test_model_agrees_with_pinocchio(name, path, record_property):
    worst = check_against_pinocchio(path, seed=hash(name) % 1000)
    record_property("worst_relative_error", {k: float(v) for k, v in worst.items()})
    print(f"\n{name}: worst relative error vs Pinocchio over {STATES} states × 4 parameter sets: "
          + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()))


def test_measured_robot_urdf_agrees_with_pinocchio():
    """The KUKA LWR4+ URDF from ../shared/data: a real 7-DOF description nobody here wrote."""
    worst = check_against_pinocchio(kuka_urdf(), seed=7)
    print("\nkuka_lwr4: " + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()))


def test_a_link_with_only_semidefinite_inertia_loads_with_a_warning_and_agrees_with_pinocchio():
    """The TX40 URDF from ../shared/data gives link_6 0.2 kg and a zero inertia tensor, as generated
    URDFs often do. Pinocchio loads it; so must arash, saying which link, with the same dynamics."""
    path = tx40_urdf()
    with pytest.warns(UserWarning) as caught:
        robot = arash.Robot.from_urdf(path)
    [concern] = robot.concerns
    assert concern["code"] == "semidefinite_inertia" and concern["link"] == "link_6", concern
    assert max(concern["eigenvalues"]) < 1e-12, concern
    assert robot.warnings == [concern["text"]] and concern["text"] in str(caught[0].message)
    with pytest.warns(UserWarning):
        worst = check_against_pinocchio(path, seed=11)
    print("\ntx40: " + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()))



@pytest.mark.parametrize("name,path", robot_cases(), ids=[c[0] for c in robot_cases()])
def test_the_generators_one_call_dynamics_agrees_with_the_model(name, path):
    """``Expanded.dynamics``, which the closed-loop generators step their plants with: its mass
    matrix and its bias torque (Coriolis, centrifugal and gravity, from Pinocchio's CRBA and
    non-linear effects on one tree configuration) are arash's M(q) and C(q, q̇) q̇ + g(q)."""
    robot = arash.Robot.from_urdf(path)
    ref = Expanded(path, robot)
    rng = np.random.default_rng(3)
    params = random_physical_params(robot, rng)
    ref.set_parameters(params)
    q, qd, _ = random_states(robot, 200, rng)
    mass = robot.mass_matrix(q, params)
    bias = np.einsum("nij,nj->ni", robot.coriolis_matrix(q, qd, params), qd) + robot.gravity(q, params)
    for k in range(len(q)):
        m, b = ref.dynamics(q[k], qd[k])
        assert relative_error(m, mass[k]) < TOLERANCE, (k, m, mass[k])
        assert relative_error(b, bias[k]) < TOLERANCE, (k, b, bias[k])
