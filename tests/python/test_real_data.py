"""Measured logs arash did not make (../shared/data, README there): the TX40's motor-side log
mapped through a declared transmission, the KUKA LWR4+'s torque-sensor runs, each identified with
the defaults. Skips with a message when the data are absent."""

import csv
import functools
import subprocess
import warnings

import numpy as np
import pytest

import arash
from support.paths import ROOT, SHARED_DATA
from support.yardstick import assert_no_joint_worse

TX40 = SHARED_DATA / "staubli_tx40"
KUKA = SHARED_DATA / "kuka_lwr4"
# Upstream's gear ratios (T40X_config.yaml) and its MDH offsets for joints 2 and 3 (README).
TX40_RATIOS = [32.0, 32.0, 45.0, -48.0, 45.0, 32.0]
TX40_OFFSETS = [0.0, -np.pi / 2, np.pi / 2, 0.0, 0.0, 0.0]
TX40_FS = 5000.0


def need(path):
    if not path.exists():
        pytest.skip(f"{path} not found: ../shared/data is absent (see its README)")
    return path


def read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    return np.array(rows[1:], dtype=float)


def tx40_motor_log():
    theta = read_csv(need(TX40 / "pos_read_data.csv"))
    tau_m = read_csv(need(TX40 / "curr_data.csv"))
    return np.arange(len(theta)) / TX40_FS, theta, tau_m


def tx40_transmission():
    return arash.Transmission(TX40_RATIOS, coupling=[(6, 5, 32.0)], offsets=TX40_OFFSETS)


def tx40_robot():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # link_6's inertia, which a test below checks
        return arash.Robot.from_urdf(need(TX40 / "tx40_mdh_modified.urdf"))


@functools.cache
def tx40_identified():
    """The motor-side log identified with the defaults, once for the tests that read it."""
    return arash.identify(tx40_robot(), *tx40_motor_log(), motor_side=tx40_transmission())


@functools.cache
def tx40_diagnosed():
    """The motor-side log diagnosed with the defaults, once for the tests that read it."""
    return arash.diagnose(tx40_robot(), *tx40_motor_log(), motor_side=tx40_transmission())


def test_the_tx40_transmission_maps_as_upstream_does():
    """Upstream's mapping, written out by hand from its README: q = R⁻¹θ with R = diag(N) and
    R[5,4] = N[5], then the MDH offsets; τ = T τ_m with T = diag(N) and T[4,5] = N[5]."""
    _, theta, tau_m = tx40_motor_log()
    N = np.array(TX40_RATIOS)
    R = np.diag(N)
    R[5, 4] = N[5]
    T = np.diag(N)
    T[4, 5] = N[5]
    q_ref = np.linalg.solve(R, theta.T).T + TX40_OFFSETS
    tau_ref = (T @ tau_m.T).T
    q, tau = tx40_transmission().to_joints(theta, tau_m)
    np.testing.assert_allclose(q, q_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(tau, tau_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(tx40_transmission().matrix, R)


def test_a_singular_transmission_is_refused_by_name():
    with pytest.raises(ValueError, match="transmission matrix is singular"):
        arash.Transmission([1.0, 1.0], coupling=[(1, 2, 1.0), (2, 1, 1.0)])
    with pytest.raises(ValueError, match="gear ratio of joint 2 is 0"):
        arash.Transmission([1.0, 0.0])
    with pytest.raises(ValueError, match=r"theta must have shape \(N, 2\)"):
        arash.Transmission([1.0, 2.0]).to_joints(np.zeros((5, 3)), np.zeros((5, 2)))


def test_the_tx40_identifies_from_its_motor_side_log_with_the_defaults():
    """The motor-side log through ``motor_side=`` gives the model the hand-mapped arrays give, and
    the defaults choose from the data and say why."""
    t, theta, tau_m = tx40_motor_log()
    robot = arash.Robot.from_urdf(need(TX40 / "tx40_mdh_modified.urdf"))
    with pytest.warns(UserWarning):  # link_6 has no rotational inertia, as upstream's URDF says
        robot = arash.Robot.from_urdf(TX40 / "tx40_mdh_modified.urdf")
    ident = tx40_identified()
    q, tau = tx40_transmission().to_joints(theta, tau_m)
    by_hand = arash.identify(robot, t, q, tau)
    np.testing.assert_allclose(ident.beta, by_hand.beta, rtol=1e-12, atol=0)
    reasons = "\n".join(ident.settings["reasons"])
    print(f"\nTX40 defaults: cut-off {ident.cutoff_hz:.2f} Hz, FP% {np.round(ident.fp_percent, 1)}\n{reasons}")
    codes = [c["code"] for c in ident.settings["choices"]]
    aperiodic = {"never_moves_away", "does_not_repeat", "edges_left_out"}
    assert aperiodic & set(codes) and "cutoff_searched" in codes and "friction_cutoff_searched" in codes, codes
    # The symptom was a 313 Hz cut-off; the motion of this log is below a few hertz.
    assert ident.cutoff_hz < 50.0
    # The arm's big joints are explained by the declared model with friction; upstream's model
    # has rotor inertia, offsets and the wrist's coupling besides, which the declared one lacks.
    assert np.all(ident.fp_percent[:3] > 85.0), ident.fp_percent
    # Friction is identified independently of upstream's estimate and agrees with it where it is
    # the same quantity, under upstream's law sign(q̇) (the defaults choose smoother laws on most
    # joints, whose fv and fc trade against the law's velocity; docs/real-data.md): within 3
    # standard deviations of the difference (upstream's σ and ours) on joints 1 to 5. On joint 6
    # upstream puts most of the dry friction on motor 6 (fsm6 = 1.95 N·m in T40X_config.yaml),
    # which turns with joints 5 and 6 together; the declared model has no such term, so joint 6's
    # Coulomb column takes it: ours must lie near fs6 + fsm6, not fs6 (docs/real-data.md).
    print(f"friction velocities chosen: {ident.robot.friction_velocities}")
    with pytest.warns(UserWarning):
        signed = arash.Robot.from_urdf(TX40 / "tx40_mdh_modified.urdf", friction_velocities=[None] * 6)
    as_upstream = arash.identify(signed, t, theta, tau_m, motor_side=tx40_transmission())
    for k in range(1, 6):
        for ours, theirs in ((f"joint_{k}.fv", f"fv{k}"), (f"joint_{k}.fc", f"fs{k}")):
            z = published_z(as_upstream, ours, theirs)
            assert abs(z) < 3.0, f"{ours}: {z:+.1f} standard deviations from upstream's {theirs}"
    assert abs(published_z(as_upstream, "joint_6.fc", "fs6")) > 3.0
    assert abs(published_z(as_upstream, "joint_6.fc", "fs6", plus=MOTOR_6_DRY_FRICTION)) < 3.0


# Upstream's dry friction of motor 6 as joints 5 and 6 see it (T40X_config.yaml, fsm6).
MOTOR_6_DRY_FRICTION = 1.95


def tx40_published():
    """Upstream's base parameters: name -> (value, relative standard deviation in %)."""
    with open(need(TX40 / "TX40_bp_5.csv")) as f:
        return {row[0]: (float(row[1]), float(row[2])) for row in csv.reader(f)}


def published_z(ident, ours, theirs, plus=0.0):
    """How many standard deviations of the difference (upstream's and ours combined) an
    identified parameter lies from upstream's published value (plus `plus`)."""
    value, percent = tx40_published()[theirs]
    j = ident.base.names.index(ours)
    sigma = np.hypot(percent / 100 * abs(value), ident.sigma_percent[j] / 100 * abs(ident.beta[j]))
    return (ident.beta[j] - value - plus) / sigma


def upstream_z(effect, i, theirs):
    """How many standard deviations (ours and upstream's combined) coefficient `i` of `effect`
    lies from upstream's published value `theirs`."""
    value, percent = tx40_published()[theirs]
    return (effect.coefficients[i] - value) / np.hypot(effect.sigma[i], percent / 100 * value)


def test_the_tx40_diagnosis_finds_the_wrist_motor_and_rotor_inertias_upstream_models():
    """The diagnosis with the defaults, given only the motor-side log and the declared
    transmission, names what upstream's model has and the declared one lacks: motor 6's rotor on
    joints 5 and 6 (upstream's Iam6, fvm6, fsm6) within 3 combined standard deviations, and rotor
    inertia on joints 3 and 4 within 2 (Ia3, Ia4; issue 44: at the former fixed 20 Hz band they
    cut the held-out error by 15 %, below the bar, and were not added). It cuts joint 5's held-out
    error (FP% 46 before, docs/real-data.md). Nothing beyond upstream's terms is added but an
    alignment of the torque to the positions (a delay is the log's, not the robot's)."""
    d = tx40_diagnosed()
    print("\n" + d.report())
    by_label = {e.label.split(" (")[0]: e for e in d.accepted}
    rotor = by_label["coupled_rotor on joint_6"]
    assert sorted(rotor.joints) == [4, 5], d.report()
    for i, theirs in enumerate(("Iam6", "fvm6", "fsm6")):
        z = upstream_z(rotor, i, theirs)
        assert abs(z) < 3.0, f"{rotor.columns[i]}: {z:+.1f} standard deviations from upstream's {theirs}"
    for joint, theirs in (("joint_3", "Ia3"), ("joint_4", "Ia4")):
        z = upstream_z(by_label[f"armature on {joint}"], 0, theirs)
        assert abs(z) < 2.0, f"rotor inertia on {joint}: {z:+.1f} standard deviations from upstream's {theirs}"
    before, after = d.error_before["rms"], d.error_after["rms"]
    assert after[4] < 0.5 * before[4], (before, after)
    assert np.all(after <= before * 1.02), (before, after)
    names = {e.name for e in d.accepted}
    assert names <= {"delay", "coupled_rotor", "armature", "offset", "coulomb_asymmetry"}, d.report()


def test_the_wrist_motor_found_on_6_s_of_the_tx40_log_cuts_the_error_on_the_other_3_s():
    """The held-out gain on data that did not choose the effect: diagnose the first 6 s alone,
    score the model with and without what it found on the last 3 s. The wrist motor is found and
    cuts joints 5 and 6's error by more than 30 %; no joint is predicted worse."""
    t, theta, tau_m = tx40_motor_log()
    with pytest.warns(UserWarning):
        robot = arash.Robot.from_urdf(need(TX40 / "tx40_mdh_modified.urdf"))
    n = int(6.0 * TX40_FS)
    d = arash.diagnose(robot, t[:n], theta[:n], tau_m[:n], motor_side=tx40_transmission())
    assert "coupled_rotor" in [e.name for e in d.accepted], d.report()
    rest = (t[n:] - t[n], theta[n:], tau_m[n:])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the model's embedded URDF has link_6's warning too
        before = arash.heldout_errors(d.model.without_effects(), *rest, motor_side=tx40_transmission())["rms"]
        after = arash.heldout_errors(d.model, *rest, motor_side=tx40_transmission())["rms"]
    print(f"\nTX40 last 3 s, RMS before {np.round(before, 2)}, after {np.round(after, 2)}")
    assert after[4] < 0.7 * before[4] and after[5] < 0.7 * before[5], (before, after)
    assert np.all(after <= before * (1 + 1e-9)), (before, after)


def test_the_tx40_diagnosed_on_6_s_against_its_identification_predicts_the_other_3_s_no_worse():
    """Issue 59: against the identified model, a diagnosis of the first 6 s leaves no joint
    predicting the last 3 s worse, on the tests' own 8 Hz yardstick (support/yardstick.py), and
    the wrist motor it finds cuts joints 5 and 6's error there (by two thirds and a quarter on
    2026-12-05). The identification saw the whole log, the last 3 s too, which favours it there."""
    t, theta, tau_m = tx40_motor_log()
    n = int(6.0 * TX40_FS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # link_6's inertia, checked above
        d = arash.diagnose(tx40_robot(), t[:n], theta[:n], tau_m[:n], model=tx40_identified(),
                           motor_side=tx40_transmission())
        q, tau = tx40_transmission().to_joints(theta[n:], tau_m[n:])
        before, after = assert_no_joint_worse(tx40_identified(), d.model, (t[n:] - t[n], q, tau), "TX40 last 3 s")
    assert after[4] < 0.5 * before[4] and after[5] < 0.8 * before[5], (before, after)


def test_the_cli_reads_a_motor_side_log_like_python(tmp_path):
    """`arash identify --gear-ratios --coupling --joint-offsets-deg` on a CSV of motor angles and
    motor torques gives the model `arash.identify(..., motor_side=...)` gives."""
    binary = ROOT / "target" / "release" / "arash"
    if not binary.exists():
        pytest.skip(f"{binary} is not built")
    t, theta, tau_m = tx40_motor_log()
    urdf = need(TX40 / "tx40_mdh_modified.urdf")
    with pytest.warns(UserWarning):
        robot = arash.Robot.from_urdf(urdf)
    names = robot.joint_names()
    log, model = tmp_path / "tx40_motor.csv", tmp_path / "model.json"
    header = ["t"] + [f"q.{n}" for n in names] + [f"tau.{n}" for n in names]
    np.savetxt(log, np.column_stack([t, theta, tau_m]), delimiter=",", header=",".join(header), comments="",
               fmt="%.17g")
    offsets = ",".join(f"{np.degrees(o):.17g}" for o in TX40_OFFSETS)
    subprocess.run([binary, "identify", log, "--robot", urdf, "--gear-ratios", ",".join(map(str, TX40_RATIOS)),
                    "--coupling", "6,5,32", "--joint-offsets-deg", offsets, "-o", model], check=True,
                   capture_output=True)
    cli = arash.load_model(model)
    python = tx40_identified()
    assert cli.cutoff_hz == python.cutoff_hz
    np.testing.assert_allclose(cli.beta, python.beta, rtol=1e-9, atol=1e-12)
    # The diagnosis reads the same declared transmission, and with it finds the wrist motor.
    diagnosis = subprocess.run([binary, "diagnose", log, "--robot", urdf, "--gear-ratios", ",".join(map(str, TX40_RATIOS)),
                                "--coupling", "6,5,32", "--joint-offsets-deg", offsets, "-o", tmp_path / "diagnosis"],
                               check=True, capture_output=True, text=True)
    found = tx40_diagnosed().accepted
    effects = diagnosis.stdout.split("Effects found")[1].split("Error per joint")[0]
    assert "coupled_rotor on joint_6" in effects, diagnosis.stdout
    assert all(f"{i + 1}. {e.label}" in effects for i, e in enumerate(found)), diagnosis.stdout
    singular = subprocess.run([binary, "identify", log, "--robot", urdf, "--gear-ratios", "1,1,1,1,1,1",
                               "--coupling", "1,2,1", "--coupling", "2,1,1", "-o", model], capture_output=True,
                              text=True)
    assert singular.returncode != 0 and "singular" in singular.stderr, singular.stderr


def kuka_run(i):
    data = np.load(need(KUKA / f"measurements_{i}.npz"))
    t = data["times"] - data["times"][0]
    return t, data["positions"], data["torques"]


def test_a_model_whose_laws_the_data_chose_predicts_with_them():
    """A robot that declares no Coulomb law is identified with each joint's law chosen from the
    data; the model's predictions, validation and base use those laws, exactly as a model of the
    same robot declared with them, fitted with the same cut-offs, does. (Until 2026-11-27 the
    Python model predicted with sign(q̇): a closed loop's insertion validated at 77 % where its
    fit was 97 %.) On the TX40, whose data choose smooth laws on most joints; the KUKA's run 1
    keeps sign(q̇) on every joint under the one-standard-error rule (docs/identification.md §7)."""
    t, theta, tau_m = tx40_motor_log()
    q, tau = tx40_transmission().to_joints(theta, tau_m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # link_6 has no rotational inertia, as upstream's URDF says
        robot = arash.Robot.from_urdf(need(TX40 / "tx40_mdh_modified.urdf"))
        chosen = arash.identify(robot, t, q, tau)
        laws = chosen.robot.friction_velocities
        assert any(v is not None for v in laws), laws  # the test needs a law that is not sign(q̇)
        declared = arash.Robot.from_urdf(TX40 / "tx40_mdh_modified.urdf", friction_velocities=laws)
        settings = chosen.settings
        same = arash.identify(declared, t, q, tau, cutoff_hz=settings["cutoff_hz"],
                              friction_cutoff_hz=settings["friction_cutoff_hz"])
    np.testing.assert_allclose(chosen.beta, same.beta, rtol=1e-9, atol=1e-12)
    qd = np.gradient(q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    np.testing.assert_allclose(chosen.predict(q, qd, qdd), same.predict(q, qd, qdd), rtol=1e-9, atol=1e-9)
    for key in ("fp_percent", "rms"):
        np.testing.assert_allclose(chosen.validate(t, q, tau)[key], same.validate(t, q, tau)[key], rtol=1e-9)


def test_the_kuka_model_from_run_1_predicts_run_2_as_well_as_a_hand_set_cutoff():
    """Train on run 1 with the defaults, predict run 2 (upstream's validation run). The declared
    model has no torque-sensor offset, which joints 1, 6 and 7 need (issue 19), so the bar is not
    the README's 65–99 %: it is that no hand-set cut-off predicts run 2 better by more than a point
    (mean FP% over joints), and that the joints the model explains (2–4) are predicted at ≥ 85 %.
    bench/real_data.py prints the full table (runs 2 and 3, ‖e‖/‖τ‖ and FP%)."""
    robot = arash.Robot.from_urdf(need(KUKA / "kuka_lwr4.urdf"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # two periods only, said in settings["warnings"]
        default = arash.identify(robot, *kuka_run(1))
        # The hand-set cut-offs with the Coulomb laws the defaults chose, so that only the
        # cut-off differs (each cut-off's own choice of laws moves the mean by about a point).
        laws = arash.Robot.from_urdf(need(KUKA / "kuka_lwr4.urdf"), friction_velocities=default.robot.friction_velocities)
        by_hand = [arash.identify(laws, *kuka_run(1), cutoff_hz=c) for c in (1.0, 2.0, 4.0, 8.0, 16.0, 32.0)]
    run2 = default.validate(*kuka_run(2))["fp_percent"]
    hand = np.array([i.validate(*kuka_run(2))["fp_percent"] for i in by_hand])
    print(f"\nKUKA run 2 FP%: defaults (cut-off {default.cutoff_hz:.2f} Hz) {np.round(run2, 1)}; "
          f"best hand-set mean {hand.mean(axis=1).max():.1f}")
    assert run2.mean() >= hand.mean(axis=1).max() - 1.0, (run2, hand)
    assert np.all(run2[1:4] >= 85.0), run2


FLANGE_MASS_KG = 3.0  # a tool of the size the LWR4+ carries (its rated payload is 7 kg)


def test_a_mass_hung_at_the_kuka_flange_is_weighed_by_the_force_estimate():
    """Issue 58 on measured data. Runs 2 and 3 (held out from the run-1 fit; run 3 in another part
    of the joint space) with a 3 kg point mass added at the flange (lwr_7_link's origin) by
    Pinocchio's RNEA of the arm with and without it, from the logged q, q̇, q̈. The observer on the
    model identified from run 1 (q differentiated as the model was fitted, the sensors' torque
    as sampled) must weigh it: the flange force's vertical part is −m g within 10 % where the arm
    moves slowly (its slowest fifth of samples, median). The CAD model is further off on both
    runs. The bandwidth is the model's band, not the default quarter of it: these logs were
    low-pass filtered upstream at about that band, so there is nothing above it for the lag to
    pass, and a quarter (0.27 Hz, a 0.6 s lag) smears the faster motion into the slow samples
    (14 % on run 2)."""
    pin = pytest.importorskip("pinocchio")
    urdf = need(KUKA / "kuka_lwr4.urdf")
    robot = arash.Robot.from_urdf(urdf)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # two periods only, said in settings["warnings"]
        identified = arash.identify(robot, *kuka_run(1))
    bare = pin.buildModelFromUrdf(str(urdf))
    loaded = pin.Model(bare)
    loaded.appendBodyToJoint(loaded.getJointId("lwr_6_joint"), pin.Inertia(FLANGE_MASS_KG, np.zeros(3), 1e-6 * np.eye(3)),
                             pin.SE3.Identity())
    bare_data, loaded_data = bare.createData(), loaded.createData()
    weight = FLANGE_MASS_KG * 9.81
    for i in (2, 3):
        data = np.load(need(KUKA / f"measurements_{i}.npz"))
        t, q, qd, qdd = data["times"] - data["times"][0], data["positions"], data["velocities"], data["accelerations"]
        load = np.array([pin.rnea(loaded, loaded_data, *s) - pin.rnea(bare, bare_data, *s) for s in zip(q, qd, qdd)])
        tau = data["torques"] + load
        speed = np.abs(qd).max(axis=1)
        errors = {}
        for name, kw in [("identified", {"model": identified}), ("CAD", {"qd": qd})]:
            out = arash.external_force(robot, t, q, tau, frame="lwr_7_link", bandwidth_hz=identified.cutoff_hz, **kw)
            slow = (speed < np.quantile(speed, 0.2)) & ~out["singular"]
            errors[name] = abs(np.median(out["force"][slow, 2]) + weight) / weight
        print(f"\nrun {i}: flange weight error, identified {100 * errors['identified']:.1f} %, "
              f"CAD {100 * errors['CAD']:.1f} %")
        assert errors["identified"] <= 0.10, (i, errors)
        assert errors["CAD"] > 1.5 * errors["identified"], (i, errors)
