//! The hand's force: the momentum observer against closed forms and a simulated arm, and the map
//! to the instrument tip against the tip's own motion.

use arash_core::control::EffectFeedforward;
use arash_core::dynamics::{forward_dynamics_with_armature, gravity_torque, Parameters};
use arash_core::effects::{EffectKind, EffectTerm};
use arash_core::force::{FrameForce, MomentumObserver, ObserverError, TorqueTiming};
use arash_core::kinematics::frame_placement;
use arash_core::{arash_asist, forward_kinematics, parse_urdf, Data, Model};

const DT: f64 = 1e-3;

/// One joint sliding along gravity: mass 2 kg, viscous 3 N·s/m, no Coulomb.
fn slider() -> Model {
    let mut model = parse_urdf(
        r#"<robot name="slider"><link name="base"/>
        <link name="cart"><inertial><mass value="2"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
        <joint name="x" type="prismatic"><parent link="base"/><child link="cart"/><axis xyz="0 0 1"/>
        <limit lower="-10" upper="10" velocity="10" effort="100"/><dynamics damping="3" friction="0"/></joint></robot>"#,
    )
    .unwrap();
    model.joints[0].coulomb = 0.0;
    model
}

/// A constant force on a cart that starts at rest: `m v̇ = F − m g − b v` has the closed form
/// `v = (F − m g)/b · (1 − e^{−b t/m})`, and the observer's estimate must be the first-order lag
/// `F (1 − e^{−2π f t})` of the force it did not see, at every sample.
#[test]
fn a_constant_force_on_a_sliding_cart_is_estimated_through_the_first_order_lag() {
    let model = slider();
    let (m, b, g, force, hz) = (2.0, 3.0, 9.81, 7.5, 5.0);
    let mut observer =
        MomentumObserver::new(&model, &model.cad_parameters(), &[], &[hz], &[1e-3], TorqueTiming::Held).unwrap();
    let terminal = (force - m * g) / b;
    let mut worst = 0.0_f64;
    for i in 0..2000 {
        let t = i as f64 * DT;
        let v = terminal * (1.0 - (-b * t / m).exp());
        let x = terminal * (t - m / b * (1.0 - (-b * t / m).exp()));
        let r = observer.step(DT, &[x], &[v], &[0.0]).unwrap()[0];
        let expected = force * (1.0 - (-std::f64::consts::TAU * hz * t).exp());
        worst = worst.max((r - expected).abs());
    }
    assert!(worst < 1e-5 * force, "largest error {worst:e} N against the closed form");
}

/// ARASH:ASiST's CAD model with a rotor inertia and a drive gain, driven along a sinusoid by a
/// PD law while a constant torque pushes on every joint: the observer recovers the torque once
/// the lag has passed, and only when it knows the effects.
#[test]
fn the_observer_recovers_a_constant_torque_on_the_moving_arm_with_its_effects() {
    let model = arash_asist();
    let mut params = model.cad_parameters();
    let layout = model.layout();
    (0..3).for_each(|k| params[layout.coulomb(k)] = 0.0);
    let external = [0.05, -0.08, 0.6];
    let armature = [2e-4, 3e-4, 0.05];
    let gain = 0.12;
    let mut rotor = EffectTerm::new(EffectKind::Armature, None);
    rotor.coefficients = armature.to_vec();
    let mut drive = EffectTerm::new(EffectKind::DriveGain, Some(1));
    drive.coefficients = vec![gain];
    let hz = [20.0; 3];
    let mut knowing =
        MomentumObserver::new(&model, &params, &[rotor, drive], &hz, &[1e-3; 3], TorqueTiming::Held).unwrap();
    let mut blind = MomentumObserver::new(&model, &params, &[], &hz, &[1e-3; 3], TorqueTiming::Held).unwrap();

    let mut data = Data::new(&model);
    let (mut q, mut qd) = ([0.0, 0.3, 0.0], [0.0; 3]);
    let (mut worst_knowing, mut worst_blind) = (0.0_f64, 0.0_f64);
    for i in 0..3000 {
        let t = i as f64 * DT;
        let tau = pd_along_sinusoids(&model, &mut data, &params, t, &q, &qd);
        // The drive delivers τ; its log says (1 + g) τ on the pitch.
        let mut logged = tau;
        logged[1] *= 1.0 + gain;
        let knew = knowing.step(DT, &q, &qd, &logged).unwrap().to_vec();
        let saw = blind.step(DT, &q, &qd, &logged).unwrap().to_vec();
        if t > 0.5 {
            for k in 0..3 {
                worst_knowing = worst_knowing.max((knew[k] - external[k]).abs() / external[k].abs());
                worst_blind = worst_blind.max((saw[k] - external[k]).abs() / external[k].abs());
            }
        }
        let applied: Vec<f64> = (0..3).map(|k| tau[k] + external[k]).collect();
        rk4(&model, &mut data, &params, &armature, &applied, &mut q, &mut qd);
    }
    assert!(worst_knowing < 0.01, "with the effects: worst relative error {worst_knowing:.2e}");
    assert!(worst_blind > 0.1, "without them the estimate must be off; it was within {worst_blind:.2e}");
}

/// A drive's telemetry pairs each position with the torque of the cycle that ended there (the
/// daemon's log): read as [`TorqueTiming::Preceding`] the constant torque on the moving arm is
/// recovered; read as a command held from its sample, each cycle's change of the PD torque is
/// taken for a hand.
#[test]
fn a_drive_reports_the_torque_of_the_cycle_that_ended_and_preceding_reads_it() {
    let model = arash_asist();
    let mut params = model.cad_parameters();
    (0..3).for_each(|k| params[model.layout().coulomb(k)] = 0.0);
    let external = [0.05, -0.08, 0.6];
    let observer = |timing| MomentumObserver::new(&model, &params, &[], &[20.0; 3], &[1e-3; 3], timing).unwrap();
    let (mut preceding, mut held) = (observer(TorqueTiming::Preceding), observer(TorqueTiming::Held));
    let mut data = Data::new(&model);
    let (mut q, mut qd) = ([0.0, 0.3, 0.0], [0.0; 3]);
    let mut reported = [0.0; 3];
    let (mut worst_preceding, mut worst_held) = (0.0_f64, 0.0_f64);
    for i in 0..2000 {
        let t = i as f64 * DT;
        let r = preceding.step(DT, &q, &qd, &reported).unwrap().to_vec();
        let h = held.step(DT, &q, &qd, &reported).unwrap().to_vec();
        if t > 0.5 {
            for k in 0..3 {
                worst_preceding = worst_preceding.max((r[k] - external[k]).abs() / external[k].abs());
                worst_held = worst_held.max((h[k] - external[k]).abs() / external[k].abs());
            }
        }
        let tau = pd_along_sinusoids(&model, &mut data, &params, t, &q, &qd);
        let applied: Vec<f64> = (0..3).map(|k| tau[k] + external[k]).collect();
        rk4(&model, &mut data, &params, &[0.0; 3], &applied, &mut q, &mut qd);
        // Reported with the next sample's position, as telemetry answers the command.
        reported = tau;
    }
    assert!(worst_preceding < 0.01, "read as preceding: worst relative error {worst_preceding:.2e}");
    assert!(worst_held > 3.0 * worst_preceding, "read as held: {worst_held:.2e}, no worse than preceding");
}

/// The PD law with gravity compensation both moving-arm tests drive the arm with, along
/// sinusoids on every joint.
fn pd_along_sinusoids(model: &Model, data: &mut Data, params: &[f64], t: f64, q: &[f64; 3], qd: &[f64; 3]) -> [f64; 3] {
    let target = [0.5 * (3.0 * t).sin(), 0.3 + 0.4 * (2.0 * t).sin(), 0.01 * (4.0 * t).sin()];
    let mut tau = [0.0; 3];
    gravity_torque(model, data, q, params, &mut tau);
    let (kp, kd) = ([20.0, 20.0, 400.0], [1.0, 1.0, 20.0]);
    (0..3).for_each(|k| tau[k] += kp[k] * (target[k] - q[k]) - kd[k] * qd[k]);
    tau
}

/// Ten RK4 steps of 0.1 ms across one cycle, the torque held.
fn rk4(
    model: &Model,
    data: &mut Data,
    params: &[f64],
    armature: &[f64],
    tau: &[f64],
    q: &mut [f64; 3],
    qd: &mut [f64; 3],
) {
    let h = DT / 10.0;
    let mut acc = |q: &[f64; 3], qd: &[f64; 3]| {
        let mut qdd = [0.0; 3];
        let parameters = Parameters { params, armature: Some(armature) };
        forward_dynamics_with_armature(model, data, q, qd, tau, parameters, &mut qdd).unwrap();
        qdd
    };
    let shift = |x: &[f64; 3], d: &[f64; 3], s: f64| std::array::from_fn::<f64, 3, _>(|k| x[k] + s * d[k]);
    for _ in 0..10 {
        let (k1q, k1v) = (*qd, acc(q, qd));
        let (q2, v2) = (shift(q, &k1q, h / 2.0), shift(qd, &k1v, h / 2.0));
        let (k2q, k2v) = (v2, acc(&q2, &v2));
        let (q3, v3) = (shift(q, &k2q, h / 2.0), shift(qd, &k2v, h / 2.0));
        let (k3q, k3v) = (v3, acc(&q3, &v3));
        let (q4, v4) = (shift(q, &k3q, h), shift(qd, &k3v, h));
        let (k4q, k4v) = (v4, acc(&q4, &v4));
        for k in 0..3 {
            q[k] += h / 6.0 * (k1q[k] + 2.0 * k2q[k] + 2.0 * k3q[k] + k4q[k]);
            qd[k] += h / 6.0 * (k1v[k] + 2.0 * k2v[k] + 2.0 * k3v[k] + k4v[k]);
        }
    }
}

#[test]
fn bad_input_is_refused_by_name() {
    let model = arash_asist();
    let params = model.cad_parameters();
    let e =
        MomentumObserver::new(&model, &params, &[], &[10.0, 0.0, 10.0], &[1e-3; 3], TorqueTiming::Held).unwrap_err();
    assert_eq!(e, ObserverError::Bandwidth { joint: 1, value: 0.0 });
    let e = MomentumObserver::new(&model, &params[1..], &[], &[10.0; 3], &[1e-3; 3], TorqueTiming::Held).unwrap_err();
    assert_eq!(e.to_string(), "π has 88 entries; the robot's model has 89 parameters");
    let e = MomentumObserver::new(&model, &params, &[], &[10.0; 2], &[1e-3; 3], TorqueTiming::Held).unwrap_err();
    assert!(e.to_string().contains("bandwidth has 2 entries"), "{e}");
    let mut observer = MomentumObserver::new(&model, &params, &[], &[10.0; 3], &[1e-3; 3], TorqueTiming::Held).unwrap();
    let e = observer.step(DT, &[0.0, f64::NAN, 0.0], &[0.0; 3], &[0.0; 3]).unwrap_err();
    assert!(e.to_string().contains("position on joint 1 is not a number"), "{e}");
    // A drive that would reverse its torque: the logged torque cannot be divided by 1 + g ≤ 0.
    let mut reversed = EffectTerm::new(EffectKind::DriveGain, Some(2));
    reversed.coefficients = vec![-1.0];
    let e = MomentumObserver::new(&model, &params, &[reversed], &[10.0; 3], &[1e-3; 3], TorqueTiming::Held)
        .unwrap_err()
        .to_string();
    assert!(e.contains("drive_gain on insertion") && e.contains("1 + g must be positive"), "{e}");
    let e = FrameForce::new(&model, "tool", "remote_centre", 1e-3).unwrap_err().to_string();
    assert!(e.contains("no frame `tool`") && e.contains("instrument_tip"), "{e}");
}

/// The tip is on the instrument axis, `d` past the remote centre, its z axis along the
/// instrument; a force put there by `τ = J_vᵀ F` (with `J_v` by finite differences of the tip's
/// placement) comes back, and the map says singular where the tip is at the centre, or on the
/// yaw axis, instead of dividing by the lever it lacks.
#[test]
fn a_force_at_the_instrument_tip_comes_back_from_its_joint_torque() {
    let model = arash_asist();
    let tip = model.frame("instrument_tip").unwrap();
    let centre = model.frame("remote_centre").unwrap();
    let mut data = Data::new(&model);
    let mut map = FrameForce::new(&model, "instrument_tip", "remote_centre", 1e-3).unwrap();
    let place = |data: &mut Data, q: &[f64; 3]| {
        forward_kinematics(&model, data, q);
        (frame_placement(data, &tip), frame_placement(data, &centre).1)
    };
    let force = [0.4, -0.7, 1.3];
    for q in [[0.3, 0.5, 0.02], [-0.6, -0.3, -0.012], [0.1, 0.9, 0.005]] {
        let ((rot, at), rcm) = place(&mut data, &q);
        let offset = at - rcm;
        assert!((offset.norm() - q[2].abs()).abs() < 1e-12, "the tip is |d| from the centre");
        assert!((offset.normalize() * q[2].signum() - rot.column(2)).norm() < 1e-9, "z along the instrument");
        let mut tau = [0.0; 3];
        for (k, t) in tau.iter_mut().enumerate() {
            let h = 1e-6;
            let (mut up, mut down) = (q, q);
            up[k] += h;
            down[k] -= h;
            let velocity = (place(&mut data, &up).0 .1 - place(&mut data, &down).0 .1) / (2.0 * h);
            *t = (0..3).map(|i| velocity[i] * force[i]).sum();
        }
        let sample = map.map(&q, &tau, &[0.01, 0.01, 0.1]);
        assert!(!sample.singular, "q = {q:?}");
        for i in 0..3 {
            assert!((sample.force[i] - force[i]).abs() < 1e-6, "q = {q:?}: {:?} vs {force:?}", sample.force);
        }
        let along = (0..3).map(|i| rot[(i, 2)] * force[i]).sum::<f64>();
        assert!((sample.local[2] - along).abs() < 1e-6, "the force along the instrument");
        let moment = offset.cross(&arash_core::spatial::Vec3::from(force));
        assert!((0..3).all(|i| (sample.moment[i] - moment[i]).abs() < 1e-9), "the moment about the centre");
        assert!(sample.sigma.iter().all(|s| s.is_finite() && *s > 0.0));
    }
    for (q, why) in [([0.2, 0.4, 0.0], "the tip at the centre"), ([0.2, 0.0, 0.02], "the instrument on the yaw axis")] {
        let sample = map.map(&q, &[0.01, 0.01, 0.5], &[0.01, 0.01, 0.1]);
        assert!(sample.singular, "{why}: not marked singular");
        assert!(sample.force.iter().all(|f| f.is_finite() && f.abs() < 10.0), "{why}: {:?}", sample.force);
    }
}

/// The observer's pieces agree with the controller's feedforward: the forces at zero
/// acceleration, the inertia times an acceleration and the drive gain rebuild `add`.
#[test]
fn the_effects_taken_apart_rebuild_the_feedforward() {
    let model = arash_asist();
    let mut rotor = EffectTerm::new(EffectKind::Armature, None);
    rotor.coefficients = vec![1e-4, 2e-4, 0.03];
    let mut drive = EffectTerm::new(EffectKind::DriveGain, Some(2));
    drive.coefficients = vec![-0.07];
    let mut friction = EffectTerm::new(EffectKind::ViscousNonlinear, Some(0));
    friction.coefficients = vec![0.4];
    let mut params = model.cad_parameters();
    let mut whole = EffectFeedforward::new(&model, &[rotor, drive, friction], &[0.01; 3], &mut params);
    let mut parts = whole.clone();
    let (q, qd, qdd) = ([0.1, 0.2, 0.01], [0.3, -0.2, 0.02], [1.0, -2.0, 0.5]);
    let mut tau = [0.1, 0.2, 0.3];
    whole.add(&q, &qd, &qdd, &mut tau);
    let mut forces = [0.0; 3];
    parts.add_forces(&q, &qd, &mut forces);
    let mut inertia = [0.0; 9];
    parts.add_inertia(&mut inertia);
    for k in 0..3 {
        let inertial: f64 = (0..3).map(|j| inertia[k * 3 + j] * qdd[j]).sum();
        let rebuilt = parts.drive_gain(k) * ([0.1, 0.2, 0.3][k] + forces[k] + inertial);
        assert!((rebuilt - tau[k]).abs() < 1e-12, "joint {k}: {rebuilt} vs {}", tau[k]);
    }
}
