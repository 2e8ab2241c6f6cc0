"""IDIM-IV on closed-loop logs that arash did not make (issue 18): a PD loop with gravity
compensation from CAD, written here on Pinocchio's dynamics (``closed_loop.pd_gravity_log``), whose
drive adds a disturbance the log records and whose 16-bit encoders the controller differences.
The true parameters are known, so the estimates and their σ are checked against them."""

import json
import warnings

import numpy as np
import pytest

pytest.importorskip("pinocchio")
import arash  # noqa: E402

from support.closed_loop import paper_validation_fp, pd_gravity_log, seeded_loop  # noqa: E402
from support.computed_torque_loop import computed_torque_loop  # noqa: E402
from support.paths import ROBOT_FILES, ROOT  # noqa: E402
from support.independent import Condition  # noqa: E402
from support.simulated import true_parameters  # noqa: E402


def closed_loop_case(seed, disturbance=0.1):
    """Four 10 s periods of a random Fourier excitation at 1 kHz, 16-bit encoders, a disturbance
    of ``disturbance`` of the RMS torque in a 2 Hz band; the robot, log, reference, controller and
    the true base parameters."""
    robot = arash.Robot.from_urdf(ROBOT_FILES["arash_asist"])
    truth = true_parameters(robot, np.random.default_rng(seed))
    condition = Condition("arash_asist", 1000, 16, 0.0, "tanh", 4, 40.0, seed=seed)
    robot, log, reference, controller = pd_gravity_log(condition, truth, actuator_noise=disturbance, noise_hz=2.0)
    return robot, log, reference, controller, truth


def within_three_sigma(model, truth):
    beta_true = model.base.project(truth)
    sigma = np.abs(model.sigma_percent / 100 * model.beta)
    return np.abs(model.beta - beta_true) <= 3 * sigma


@pytest.mark.parametrize("method,name", [("idim-iv", "IDIM-IV"), ("didim", "DIDIM")])
def test_the_estimate_settles_and_its_sigma_cover_the_truth_of_an_independent_loop(method, name):
    """Three seeds: IDIM-IV and DIDIM settle and their σ cover the truth."""
    covered = []
    for seed in range(3):
        robot, log, reference, controller, truth = closed_loop_case(seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            model = arash.identify(robot, *log, method=method, reference=reference, controller=controller)
        simulated = [c for c in model.settings["choices"] if c["code"] == "closed_loop" and c["estimator"] == name]
        assert simulated, model.settings["reasons"]
        unsettled = [c for c in model.settings["concerns"] if c["code"] == "closed_loop_not_settled"]
        assert not unsettled, model.settings["warnings"]
        covered.extend(within_three_sigma(model, truth))
        print(f"seed {seed}: {model.settings['reasons'][-1]}; {np.mean(within_three_sigma(model, truth)):.2f} within 3σ")
    assert np.mean(covered) >= 0.9, f"{name}'s 3σ cover {100 * np.mean(covered):.1f} % of the base parameters"


def test_idim_iv_from_a_noise_free_loop_validates_on_the_papers_trajectories():
    """The loop without a disturbance (its encoders still 16-bit): the model predicts the true
    robot on the paper's four validation trajectories at FP% ≥ 95 on every joint (issue 18's bar).
    With the disturbance of the test above, yaw reaches 93.7–93.8 % at ω = 0.9 with IDIM-IV and OLS
    alike: a limit of that log, not of the estimator (docs/identification.md)."""
    robot, log, reference, controller, truth = closed_loop_case(0, disturbance=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        model = arash.identify(robot, *log, method="idim-iv", reference=reference, controller=controller)
    validation = paper_validation_fp(robot, model, truth)
    print(f"FP% on the paper's trajectories (rows ω = 0.3 … 0.9):\n{np.round(validation, 2)}")
    assert np.all(validation >= 95.0), validation


@pytest.mark.parametrize("method", ["idim-iv-consistent", "didim-consistent"])
def test_the_consistent_closed_loop_fits_are_physical_with_no_pull_toward_cad(method):
    robot, log, reference, controller, truth = closed_loop_case(4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        model = arash.identify(robot, *log, method=method, pull=0.0, reference=reference, controller=controller)
    assert model.method == method
    assert np.min(model.min_pseudo_inertia_eigenvalue) >= 0.0, model.min_pseudo_inertia_eigenvalue
    assert np.mean(within_three_sigma(model, truth)) >= 0.9


def test_a_simulated_run_and_its_flight_log_carry_the_controller_idim_iv_needs(tmp_path):
    """arash's own rig under PD: the run and the log it writes both name the controller, and the
    estimate from the log through IDIM-IV predicts the rig as OLS does (the rig's loop is not
    biased: its torque noise is the current sensor's, which the loop never sees)."""
    robot = arash.Robot.arash_asist(coulomb_epsilon=1e-3)
    path = tmp_path / "run.mcap"
    run = arash.simulate(ROOT / "scenarios" / "nominal.toml", ROOT / "trajectories" / "excitation_L5_T15.json",
                         controller="pd", duration=45.0, log=path)
    logged = arash.read_log(path)
    assert json.loads(run["logged_controller"]) == json.loads(logged["logged_controller"])
    assert json.loads(run["logged_controller"])["kind"] == "pd"
    log = (logged["t"], logged["q"], logged["tau_meas"])
    reference = (logged["q_des"], logged["qd_des"], logged["qdd_des"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        ols = arash.identify(robot, *log)
        iv = arash.identify(robot, *log, method="idim-iv", reference=reference, controller=logged["logged_controller"])
    assert iv.method == "idim-iv"
    assert any(c["code"] == "closed_loop" and c["estimator"] == "IDIM-IV" for c in iv.settings["choices"])
    np.testing.assert_allclose(iv.fp_percent, ols.fp_percent, atol=0.5)


def test_idim_iv_names_what_its_closed_loop_lacks():
    robot, log, reference, controller, _ = closed_loop_case(5, disturbance=0.0)
    for method in ("idim-iv", "didim-consistent"):
        with pytest.raises(ValueError, match=f"method {method} needs the closed loop's reference .* ols, wls and"):
            arash.identify(robot, *log, method=method)
    with pytest.raises(ValueError, match="reference was given without controller"):
        arash.identify(robot, *log, method="idim-iv", reference=reference)
    with pytest.raises(ValueError, match="controller was given without reference"):
        arash.identify(robot, *log, method="idim-iv", controller=controller)
    with pytest.raises(ValueError, match=r"reference qd_des must have shape \(40000, 3\)"):
        arash.identify(robot, *log, method="idim-iv", reference=(reference[0], reference[1][:-1], reference[2]),
                       controller=controller)
    with pytest.raises(ValueError, match="parameter vector has 5 entries"):
        arash.identify(robot, *log, method="idim-iv", reference=reference,
                       controller={**controller, "params": np.zeros(5)})
    with pytest.raises(ValueError, match="not a controller"):
        arash.identify(robot, *log, method="idim-iv", reference=reference, controller={"law": "lqr"})


def test_the_stick_step_holds_a_joint_still_until_the_other_torques_overcome_its_friction():
    """``coulomb_step``, the generator's set-valued dry friction, against its own definition:
    one joint under a force below its friction stays exactly still and above it moves as
    (F − f_c)/m; two coupled joints give the minimiser of ½ (v − v_f)ᵀ M (v − v_f) + Σ h f_c |v_k|,
    checked against scipy's minimiser of that convex function."""
    from scipy.optimize import minimize

    from support.closed_loop import coulomb_step

    h, m, fc = 1e-3, 2.0, 3.0
    for force, expected in ((2.5, 0.0), (-2.9, 0.0), (5.0, h * (5.0 - fc) / m), (-4.0, h * (-4.0 + fc) / m)):
        v = coulomb_step(np.array([[1 / m]]), np.array([h * force / m]), np.array([h * fc]))
        assert abs(v[0] - expected) < 1e-15, (force, v, expected)
    mass = np.array([[2.0, 0.6], [0.6, 1.0]])
    impulse = h * np.array([0.5, 2.0])
    for free in (np.array([1e-3, 2e-3]), np.array([4e-3, -1e-4]), np.array([-2e-4, 3e-4])):
        v = coulomb_step(np.linalg.inv(mass), free, impulse)
        cost = lambda x: 0.5 * (x - free) @ mass @ (x - free) + impulse @ np.abs(x)  # noqa: E731
        reference = minimize(cost, free, method="Nelder-Mead", options={"xatol": 1e-12, "fatol": 1e-18}).x
        assert cost(v) <= cost(reference) + 1e-15, (v, reference)


@pytest.fixture(scope="module")
def smooth_law_closed_loop():
    """Issue 44's closed loop: PD with CAD gravity, no disturbance, the plant stepped at 10 kHz,
    its dry friction tanh(q̇/2·10⁻³) on every joint, arash's designed excitation (four periods),
    16-bit encoders. The robot returned declares no law, as a new user loads it."""
    law = [2e-3] * 3
    robot, log, truth = seeded_loop(0, law)
    return robot, truth, law, log


@pytest.mark.parametrize("declared", [True, False], ids=["law declared", "law chosen from the data"])
def test_a_closed_loop_whose_friction_rises_over_2_mm_s_validates_with_its_law(smooth_law_closed_loop, declared):
    """Calibrated with the plant's law declared, or with each joint's law chosen from the data,
    the model predicts the true robot on the paper's four trajectories at FP% ≥ 95 on every
    joint. (With the law grid capped at half the RMS speed the insertion's law came out at
    1.2 mm/s and the insertion validated at 46 %: it moves at 2.4 mm/s RMS; docs/identification.md.)"""
    robot, truth, law, log = smooth_law_closed_loop
    assert not robot.coulomb_laws_declared
    if declared:
        robot = arash.Robot.from_urdf(ROBOT_FILES["arash_asist"], friction_velocities=law)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        model = arash.identify(robot, *log)
    validation = paper_validation_fp(robot, model, truth, law)
    print(f"laws {model.robot.friction_velocities}; FP% on the paper's trajectories (rows ω = 0.3 … 0.9):\n"
          f"{np.round(validation, 2)}")
    if not declared:
        # Every smooth law chosen is near the plant's (within the grid's refinement and what the
        # 16-bit encoders let the velocity show), and the insertion's is smooth: it moves at about
        # its friction velocity, where the law shows. A joint whose motion does not show its law
        # clearly keeps sign(q̇) (docs/identification.md §7), and the validation below judges it.
        chosen = np.array([np.nan if v is None else v for v in model.robot.friction_velocities])
        smooth = ~np.isnan(chosen)
        assert smooth[2] and np.all((chosen[smooth] > 0.25 * 2e-3) & (chosen[smooth] < 4 * 2e-3)), chosen
    assert np.all(validation >= 95.0), validation


@pytest.fixture(scope="module")
def sign_law_closed_loop():
    """The same closed loop with dry friction sign(q̇): the plant is stepped as the set-valued law
    (``coulomb_step``), so that a stuck joint stays exactly still until the loop's torque breaks
    it away. The insertion rests at about a quarter of the samples."""
    robot, log, truth = seeded_loop(0, "sign")
    return robot, truth, log


@pytest.fixture(scope="module")
def noisy_sign_law_closed_loop():
    """The sign-law closed loop with the drive's white noise at 2 % of each joint's RMS torque:
    the insertion rests at about half the samples, and identification filters the velocity that
    switches friction at 0.79 Hz, where the motion's band is 6.3 Hz."""
    robot, log, truth = seeded_loop(0, "sign", actuator_noise=0.02)
    return robot, truth, log


def test_a_noisy_sign_law_closed_loop_keeps_sign_where_a_smooth_law_would_fit_the_filter(noisy_sign_law_closed_loop):
    """Left to the data, the insertion's friction velocity filtered at 0.79 Hz strays by more
    than a smooth law's own v where that law acts, and a law that narrow is a law of the filter's
    slow passage through zero, not of the joint: sign(q̇) is kept and says why, and the model
    predicts the true robot at FP% ≥ 95 on every joint. (Kept, tanh(q̇/1.2·10⁻⁴) validated the
    insertion at 94.7 %; docs/identification.md, "A sign-law closed loop".) Since the choice also
    leaves out the rows near stops shorter than a rest (2026-12-07), no smooth law predicts the
    held-out stretches better than sign(q̇) here, so there is none to refuse (the stray rule is
    checked on its own in ``signal/friction_law.rs``)."""
    robot, truth, log = noisy_sign_law_closed_loop
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        model = arash.identify(robot, *log)
    laws = next(c for c in model.settings["choices"] if c["code"] == "laws_chosen")
    validation = paper_validation_fp(model.robot, model, truth, "sign")
    print(f"{laws['text']}\nFP% on the paper's trajectories:\n{np.round(validation, 2)}")
    assert model.robot.friction_velocities[2] is None, laws["text"]
    assert np.all(validation >= 95.0), validation


@pytest.mark.parametrize("declared", [True, False], ids=["sign declared", "laws chosen from the data"])
def test_a_closed_loop_that_sticks_validates_with_its_resting_samples_left_out(sign_law_closed_loop, declared):
    """Where a joint rests, its friction is whatever holds it, no law of its velocity; identification
    leaves those rows out (``signal/resting.rs``) and says so. The model then predicts the true
    sign-law robot on the paper's four trajectories at FP% ≥ 95 on every joint. With those rows in,
    least squares validated at 77 / 98 / 81 % (docs/identification.md, "A sign-law closed loop")."""
    robot, truth, log = sign_law_closed_loop
    if declared:
        robot = arash.Robot.from_urdf(ROBOT_FILES["arash_asist"], friction_velocities=[None] * 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        model = arash.identify(robot, *log)
    rests = [c for c in model.settings["choices"] if c["code"] == "resting"]
    assert rests and rests[0]["shares"][2] > 0.0, model.settings["reasons"]
    validation = paper_validation_fp(robot if declared else model.robot, model, truth, "sign")
    print(f"{rests[0]['text']}\nlaws {model.robot.friction_velocities}; FP% on the paper's trajectories:\n"
          f"{np.round(validation, 2)}")
    assert np.all(validation >= 95.0), validation


def test_a_sign_law_closed_loop_on_a_fresh_random_excitation_validates_with_the_chosen_laws():
    """The sign-law closed loop (PD with CAD gravity, 16-bit encoders differenced, no disturbance)
    on a random Fourier excitation of seed 3, four 10 s periods, which no choice was tuned on: with
    each law left to the data, the model predicts the true robot on the paper's four trajectories
    at FP% ≥ 95 on every joint. Until the law's choice left out the rows near stops shorter than a
    rest, and refused a law whose transition lies in rests and stops (``signal/resting.rs``,
    ``Resolution`` in ``signal/friction_law.rs``), the data chose tanh(q̇/5.9·10⁻³), tanh(q̇/6.8·10⁻³)
    and tanh(q̇/2.5·10⁻⁴), and the yaw and the insertion validated at 93.0 and 91.9 %
    (bench/closed_loop_seeds.py; docs/identification.md, "Fresh seeds, and a second loop")."""
    robot, log, truth = seeded_loop(3, "sign", designed=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        model = arash.identify(robot, *log)
    validation = paper_validation_fp(model.robot, model, truth, "sign")
    print(f"laws {model.robot.friction_velocities}; FP% on the paper's trajectories:\n{np.round(validation, 2)}")
    assert model.robot.friction_velocities == [None] * 3, model.settings["reasons"]
    assert np.all(validation >= 95.0), validation


@pytest.mark.parametrize("law,seed", [("sign", 3), ("smooth", 1)], ids=["sign law", "smooth law"])
def test_a_second_independent_loop_with_coarser_encoders_validates_with_the_chosen_laws(law, seed):
    """The second generator (``support/computed_torque_loop.py``: computed torque on CAD with
    integral action, an α–β observer's velocity, the command a cycle late) with 14-bit encoders
    on a random excitation, each law left to the data: the model predicts the true robot on the
    paper's four trajectories at FP% ≥ 95 on every joint, and the smooth-law insertion, which
    moves through its transition, keeps a law near the plant's. On the sign-law loop the choice
    before the rule above took tanh(q̇/6.2·10⁻³), tanh(q̇/9.1·10⁻³) and tanh(q̇/3.1·10⁻⁴) and
    validated at 92.9 / 98.6 / 91.4 %."""
    plant = "sign" if law == "sign" else [2e-3] * 3
    robot, log, truth = computed_torque_loop(seed, plant, designed=False, bits=14)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        model = arash.identify(robot, *log)
    validation = paper_validation_fp(model.robot, model, truth, plant)
    laws = model.robot.friction_velocities
    print(f"laws {laws}; FP% on the paper's trajectories:\n{np.round(validation, 2)}")
    if law == "sign":
        assert laws == [None] * 3, model.settings["reasons"]
    else:
        assert laws[2] is not None and 0.5 * 2e-3 < laws[2] < 2 * 2e-3, laws
    assert np.all(validation >= 95.0), validation
