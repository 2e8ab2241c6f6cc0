"""The simulated rig and its flight log, from Python, against independent references: Pinocchio
for the simulated torques, and the official `mcap` reader with the `mcap-protobuf-support`
decoder for the log."""

import subprocess

import numpy as np
import pytest

import arash
from support.paths import ROBOT_FILES, ROOT

mcap_reader = pytest.importorskip("mcap.reader")
mcap_protobuf = pytest.importorskip("mcap_protobuf.decoder")

NOMINAL = ROOT / "scenarios" / "nominal.toml"
VALIDATION = {"kind": "paper-validation", "omega": 0.9}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    path = tmp_path_factory.mktemp("sim") / "run.mcap"
    result = arash.simulate(NOMINAL, VALIDATION, controller="robust", duration=3.0, log=path, log_truth=True)
    return result, path


def official(path):
    """Every message of the log through the official reader and protobuf decoder."""
    cycles, truth = [], []
    with open(path, "rb") as f:
        reader = mcap_reader.make_reader(f, decoder_factories=[mcap_protobuf.DecoderFactory()])
        for _, channel, _, message in reader.iter_decoded_messages():
            (cycles if channel.topic == "/arash/cycle" else truth).append(message)
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        attachments = {a.name: a.data for a in reader.iter_attachments()}
    return cycles, truth, metadata, attachments


def test_read_log_agrees_with_the_official_decoder(run):
    result, path = run
    cycles, truth, metadata, attachments = official(path)
    log = arash.read_log(path)
    assert len(cycles) == len(truth) == len(log["t"]) == 3000
    for field in ["q", "qd", "tau_cmd", "tau_meas", "q_des", "qd_des", "qdd_des"]:
        np.testing.assert_array_equal(log[field], np.array([list(getattr(m, field)) for m in cycles]), err_msg=field)
        np.testing.assert_array_equal(log[field], result[field], err_msg=field)
    for field in ["t", "cycle", "controller", "mode", "faults"]:
        np.testing.assert_array_equal(log[field], [getattr(m, field) for m in cycles], err_msg=field)
    for field in ["q", "qd", "qdd", "tau_motor", "motor_q", "motor_qd", "tau_hand", "hand_force"]:
        np.testing.assert_array_equal(log["truth"][field], np.array([list(getattr(m, field)) for m in truth]))
    assert log["metadata"] == metadata["arash"]
    assert log["urdf"] == attachments["robot.urdf"].decode() == ROBOT_FILES["arash_asist"].read_text()
    assert set(attachments) == {"robot.urdf", "scenario.toml", "run.json"}
    assert log["joint_names"] == ["yaw", "pitch", "insertion"] and not log["truncated"]
    assert set(np.unique(log["controller"])) == {3} and set(np.unique(log["mode"])) == {1}


def test_a_truncated_log_reads_its_beginning(run, tmp_path):
    _, path = run
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    log = arash.read_log(cut)
    whole = arash.read_log(path)
    n = len(log["t"])
    assert log["truncated"] and 1000 <= n < 3000
    np.testing.assert_array_equal(log["tau_meas"], whole["tau_meas"][:n])


def test_simulated_torques_equal_pinocchio_inverse_dynamics_with_the_true_parameters(run):
    pytest.importorskip("pinocchio")
    from support.independent import Expanded

    result, _ = run
    robot = arash.Robot.arash_asist()
    ref = Expanded(ROBOT_FILES["arash_asist"], robot)
    params = result["true_params"]
    ref.set_parameters(params)
    nb, n = len(robot.body_names()), robot.dof
    fv, fc, ke = params[10 * nb : 10 * nb + 2 * n : 2], params[10 * nb + 1 : 10 * nb + 2 * n : 2], params[-n:]
    truth = result["truth"]
    worst = 0.0
    for i in range(0, 3000, 7):
        q, qd, qdd = truth["q"][i], truth["qd"][i], truth["qdd"][i]
        # The plant's Coulomb law is tanh(q̇/ε) with ε = 1e-3 (scenario truth.coulomb_epsilon).
        tau = ref.torque(q, qd, qdd) + fv * qd + fc * np.tanh(qd / 1e-3) + ke * q
        worst = max(worst, np.max(np.abs(tau - truth["tau_motor"][i]) / (np.abs(truth["tau_motor"]).max(0))))
    assert worst < 1e-9, worst


def test_the_true_parameters_differ_from_cad_but_stay_physical():
    robot = arash.Robot.arash_asist()
    result = arash.simulate(None, VALIDATION, controller="pd", duration=0.01, seed=3)
    truth, cad = result["true_params"], robot.cad_parameters()
    masses = truth[0 : 80 : 10] / cad[0 : 80 : 10]
    assert 0.5 < masses.min() and masses.max() < 1.5 and np.abs(masses - 1).max() > 0.05
    for b in range(8):
        p = truth[10 * b : 10 * b + 10]
        m, h = p[0], p[1:4]
        inertia = np.array([[p[4], p[7], p[8]], [p[7], p[5], p[9]], [p[8], p[9], p[6]]])
        sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia
        pseudo = np.block([[sigma, h[:, None]], [h[None, :], np.array([[m]])]])
        assert np.linalg.eigvalsh(pseudo).min() > 0, b


def test_simulate_is_deterministic_and_rejects_bad_arguments():
    a = arash.simulate(None, VALIDATION, controller="idc-cad", duration=0.2)
    b = arash.simulate(None, VALIDATION, controller="idc-cad", duration=0.2)
    np.testing.assert_array_equal(a["tau_meas"], b["tau_meas"])
    with pytest.raises(ValueError, match="controller"):
        arash.simulate(None, VALIDATION, controller="lqr")
    with pytest.raises(ValueError, match="idc-cad"):
        arash.simulate(None, VALIDATION, controller="idc-cad", params="truth")
    with pytest.raises(ValueError, match="omega"):
        arash.simulate(None, {"kind": "paper-validation", "omega": -1})
    with pytest.raises(ValueError, match="params must have shape"):
        arash.simulate(None, VALIDATION, params=np.zeros(5))


def test_the_cli_log_identifies_like_the_python_arrays(tmp_path):
    """`arash identify` on an MCAP log gives the fit `arash.identify` gives on the arrays the
    official decoder reads from the same file."""
    log, model = tmp_path / "run.mcap", tmp_path / "model.json"
    binary = ROOT / "target" / "release" / "arash"
    if not binary.exists():
        pytest.skip(f"{binary} is not built")
    subprocess.run([binary, "simulate", "--scenario", NOMINAL, "--trajectory",
                    ROOT / "trajectories" / "paper_validation_0.5.json", "--controller", "idc-cad",
                    "--duration", "12", "-o", log], check=True, capture_output=True)
    subprocess.run([binary, "identify", log, "-o", model], check=True, capture_output=True)
    cycles, _, _, _ = official(log)
    t = np.array([m.t for m in cycles])
    q = np.array([list(m.q) for m in cycles])
    tau = np.array([list(m.tau_meas) for m in cycles])
    cli = arash.load_model(model)
    # Both front ends make every choice from the data, by the same code: no option is passed to
    # either, and they must agree on the choices, their reasons and the fitted model.
    ident = arash.identify(arash.Robot.arash_asist(), t, q, tau)
    assert cli.cutoff_hz == ident.cutoff_hz
    assert cli.settings["choices"] == ident.settings["choices"]
    np.testing.assert_allclose(cli.beta, ident.beta, rtol=1e-9, atol=1e-12)


def test_the_hand_pushes_the_plant_by_pinocchios_jacobian():
    """scenarios/hand.toml's hand at the instrument tip: the joint torque the truth records is
    Jᵀ F with Pinocchio's own frame Jacobian, and the plant feels it: Pinocchio's inverse dynamics
    of the true robot is the motors' torque plus the hand's. Before the random force starts (1 s)
    there is no hand."""
    pin = pytest.importorskip("pinocchio")
    from support.independent import Expanded

    result = arash.simulate(ROOT / "scenarios" / "hand.toml", VALIDATION, controller="robust", duration=2.0)
    robot = arash.Robot.arash_asist()
    ref = Expanded(ROBOT_FILES["arash_asist"], robot)
    params = result["true_params"]
    ref.set_parameters(params)
    tip = ref.model.getFrameId("instrument_tip")
    nb, n = len(robot.body_names()), robot.dof
    fv, fc, ke = params[10 * nb : 10 * nb + 2 * n : 2], params[10 * nb + 1 : 10 * nb + 2 * n : 2], params[-n:]
    truth, t = result["truth"], result["t"]
    assert not truth["hand_force"][t < 1.0].any() and not truth["tau_hand"][t < 1.0].any()
    assert np.abs(truth["hand_force"][t > 1.5]).max() > 0.1
    scale = np.abs(truth["tau_motor"]).max(0)
    for i in range(1100, 2000, 13):
        q, qd, qdd = truth["q"][i], truth["qd"][i], truth["qdd"][i]
        jac = pin.computeFrameJacobian(ref.model, ref.data, ref.configuration(q), tip, pin.LOCAL_WORLD_ALIGNED)
        hand = ref.G.T @ (jac[:3].T @ truth["hand_force"][i])
        np.testing.assert_allclose(truth["tau_hand"][i], hand, rtol=1e-9, atol=1e-12 * scale.max())
        tau = ref.torque(q, qd, qdd) + fv * qd + fc * np.tanh(qd / 1e-3) + ke * q
        assert np.max(np.abs(tau - truth["tau_motor"][i] - hand) / scale) < 1e-9, i
