//! The simulated rig against its own equations: energy conservation of the integrator, torques
//! equal to `Y π_true`, and each undeclared effect changing the torque exactly as documented.

// Joints are indexed k across several parallel arrays.
#![allow(clippy::needless_range_loop)]

use arash_core::control::{standard_controller, ControllerKind, RobustGains, Trajectory};
use arash_core::record::{Columns, TruthColumns};
use arash_core::sim::scenario::*;
use arash_core::sim::{true_parameters, Integrator, Plant, Rig, Scenario};
use arash_core::spatial::{params_from_com, Mat3, Vec3};
use arash_core::{regressor, CoulombShape, Data, Model};

fn robot() -> Model {
    arash_core::arash_asist()
}

/// Relative energy drift over 10 s of free motion (friction off, no torque).
fn energy_drift(integrator: Integrator, substeps: usize) -> f64 {
    let model = robot();
    let mut scenario = Scenario::default();
    scenario.truth.viscous = vec![0.0; 3];
    scenario.truth.coulomb = vec![0.0; 3];
    scenario.physics.integrator = integrator;
    scenario.physics.substeps = substeps;
    let mut plant = Plant::new(&model, &scenario).unwrap();
    plant.reset(&[0.2, 0.3, 0.005], &[1.0, -0.8, 0.05], &[0.0; 3]);
    let e0 = plant.energy();
    let mut worst: f64 = 0.0;
    let mut kinetic_scale: f64 = 0.0;
    for _ in 0..10_000 {
        plant.advance(1e-3, &[0.0; 3]).unwrap();
        let e = plant.energy();
        worst = worst.max((e - e0).abs());
        let (q, qd) = (plant.q().to_vec(), plant.qd().to_vec());
        let mut data = Data::new(plant.model());
        kinetic_scale =
            kinetic_scale.max(arash_core::kinetic_energy(plant.model(), &mut data, &q, &qd, plant.params()));
    }
    worst / kinetic_scale
}

#[test]
fn energy_is_conserved_without_friction_or_input() {
    // Semi-implicit Euler at 10 kHz: bounded error, no secular drift. RK4: four orders less.
    let euler = energy_drift(Integrator::SemiImplicitEuler, 10);
    let rk4 = energy_drift(Integrator::Rk4, 10);
    println!(
        "energy drift over 10 s relative to the peak kinetic energy: semi-implicit Euler {euler:.2e}, RK4 {rk4:.2e}"
    );
    assert!(euler < 2e-3, "semi-implicit Euler drift {euler:.3e}");
    assert!(rk4 < 1e-8, "RK4 drift {rk4:.3e}");
    // The drift halves with the step (first order), i.e. it is integration error, not a model bug.
    let finer = energy_drift(Integrator::SemiImplicitEuler, 20);
    assert!(finer < 0.7 * euler, "drift {finer:.3e} at 20 kHz against {euler:.3e} at 10 kHz");
}

struct Run {
    model: Model,
    truth_model: Model,
    params: Vec<f64>,
    cycles: Columns,
    truth: TruthColumns,
}

/// 3 s of the robust controller (true parameters) on the ω = 0.9 validation trajectory.
fn run(scenario: &Scenario, seconds: f64) -> Run {
    let model = robot();
    let params = true_parameters(&model, scenario);
    let controller =
        standard_controller(ControllerKind::Robust, &model, &params, Some(&RobustGains::paper(&model).unwrap()))
            .unwrap();
    let mut rig = Rig::new(&model, scenario, Trajectory::PaperValidation { omega: 0.9 }, controller).unwrap();
    let (mut cycles, mut truth) = (Columns::default(), TruthColumns::default());
    for _ in 0..(seconds * 1000.0) as usize {
        rig.step().unwrap();
        cycles.push(rig.record());
        truth.push(rig.truth());
    }
    let truth_model = rig.plant().model().clone();
    Run { model, truth_model, params, cycles, truth }
}

impl Run {
    fn rows(&self) -> usize {
        self.truth.t.len()
    }

    fn state(&self, i: usize) -> (&[f64], &[f64], &[f64]) {
        let r = i * 3..(i + 1) * 3;
        (&self.truth.q[r.clone()], &self.truth.qd[r.clone()], &self.truth.qdd[r])
    }

    /// `Y(q, q̇, q̈) π` at the true state of cycle `i`, under the plant's Coulomb law.
    fn model_torque(&self, i: usize, params: &[f64]) -> [f64; 3] {
        let (q, qd, qdd) = self.state(i);
        let mut data = Data::new(&self.truth_model);
        let mut y = vec![0.0; 3 * params.len()];
        regressor(&self.truth_model, &mut data, q, qd, qdd, &mut y);
        std::array::from_fn(|k| {
            y[k * params.len()..(k + 1) * params.len()].iter().zip(params).map(|(a, b)| a * b).sum()
        })
    }

    /// `τ_motor − Y π_true` at cycle `i`: what the declared model does not explain.
    fn residual(&self, i: usize) -> [f64; 3] {
        let tau = self.model_torque(i, &self.params);
        std::array::from_fn(|k| self.truth.tau_motor[i * 3 + k] - tau[k])
    }

    fn tau_scale(&self) -> [f64; 3] {
        std::array::from_fn(|k| (0..self.rows()).map(|i| self.truth.tau_motor[i * 3 + k].abs()).fold(0.0, f64::max))
    }
}

/// Checks `residual(i) == expected(i)` for every cycle, to `tolerance` relative to the torque.
fn assert_effect(run: &Run, name: &str, tolerance: f64, expected: impl Fn(&Run, usize, usize) -> f64) {
    let scale = run.tau_scale();
    let mut worst: f64 = 0.0;
    let mut size: f64 = 0.0;
    for i in 0..run.rows() {
        let r = run.residual(i);
        for k in 0..3 {
            let e = expected(run, i, k);
            worst = worst.max((r[k] - e).abs() / scale[k]);
            size = size.max(e.abs() / scale[k]);
        }
    }
    println!("{name}: effect up to {size:.3} of the torque, equation matched to {worst:.1e}");
    assert!(size > 0.01, "{name}: the effect is too small to test ({size:.2e})");
    assert!(worst < tolerance, "{name}: residual differs from the equation by {worst:.3e}");
}

fn with(effects: Effects) -> Scenario {
    Scenario { effects, ..Scenario::default() }
}

#[test]
fn nominal_torques_equal_the_regressor_times_the_true_parameters() {
    let run = run(&Scenario::default(), 3.0);
    assert_eq!(run.truth_model.coulomb_laws.common(), Some(CoulombShape::Tanh { epsilon: 1e-3 }));
    let scale = run.tau_scale();
    for i in 0..run.rows() {
        let r = run.residual(i);
        for k in 0..3 {
            assert!(r[k].abs() < 1e-9 * scale[k], "cycle {i} joint {k}: τ − Yπ = {}", r[k]);
        }
    }
    // The current sensor adds the documented noise and nothing else.
    let noise = Scenario::default().sensors.torque_noise;
    for k in 0..3 {
        let d: Vec<f64> =
            (0..run.rows()).map(|i| run.cycles.tau_meas[i * 3 + k] - run.truth.tau_motor[i * 3 + k]).collect();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let sd = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt();
        assert!((sd / noise[k] - 1.0).abs() < 0.05, "joint {k}: noise sd {sd} against {}", noise[k]);
        assert!(mean.abs() < 4.0 * noise[k] / (d.len() as f64).sqrt(), "joint {k}: noise mean {mean}");
    }
}

#[test]
fn joint_side_effects_follow_their_equations() {
    let eps = Scenario::default().truth.coulomb_epsilon;
    let s = Stribeck::default();
    let run1 = run(&with(Effects { stribeck: Some(s.clone()), ..Default::default() }), 3.0);
    assert_effect(&run1, "stribeck", 1e-9, |r, i, k| {
        let qd = r.state(i).1[k];
        s.static_excess[k] * (-(qd / s.velocity_scale[k]).powi(2)).exp() * (qd / eps).tanh()
    });
    let a = CoulombAsymmetry::default();
    let run2 = run(&with(Effects { coulomb_asymmetry: Some(a.clone()), ..Default::default() }), 3.0);
    assert_effect(&run2, "coulomb_asymmetry", 1e-9, |r, i, k| a.delta[k] * (r.state(i).1[k] / eps).tanh().abs());
    let d = ConfigurationDisturbance::default();
    let run3 = run(&with(Effects { configuration_disturbance: Some(d.clone()), ..Default::default() }), 3.0);
    assert_effect(&run3, "configuration_disturbance", 1e-9, |r, i, k| {
        d.amplitude[k] * (2.0 * std::f64::consts::PI * r.state(i).0[k] / d.period[k] + d.phase[k]).sin()
    });
    let c = Cogging::default();
    let transmission = Scenario::default().sensors.transmission;
    let run4 = run(&with(Effects { cogging: Some(c.clone()), ..Default::default() }), 3.0);
    assert_effect(&run4, "cogging", 1e-9, |r, i, k| {
        c.amplitude[k] * (c.periods_per_rev[k] * r.state(i).0[k] / transmission[k] + c.phase[k]).sin()
    });
    let v = ViscousNonlinear::default();
    let run5 = run(&with(Effects { viscous_nonlinear: Some(v.clone()), ..Default::default() }), 3.0);
    assert_effect(&run5, "viscous_nonlinear", 1e-9, |r, i, k| {
        let qd = r.state(i).1[k];
        v.coefficient[k] * qd * qd.abs()
    });
    let p = PositionFriction::default();
    let run6 = run(&with(Effects { position_friction: Some(p.clone()), ..Default::default() }), 3.0);
    assert_effect(&run6, "position_friction", 1e-9, |r, i, k| {
        let joint = &r.model.joints[k];
        let x = (2.0 * r.state(i).0[k] - joint.upper - joint.lower) / (joint.upper - joint.lower);
        p.amplitude[k] * x * (r.state(i).1[k] / eps).tanh()
    });
}

/// Dahl friction, integrated here independently from the true positions at cycle starts. Within
/// a cycle the plant integrates it over its substeps; the exponential law composes exactly while
/// the direction holds, so only cycles with a reversal inside differ (hence the looser bound).
#[test]
fn hysteresis_follows_the_dahl_law() {
    let h = Hysteresis::default();
    let run = run(&with(Effects { hysteresis: Some(h.clone()), ..Default::default() }), 3.0);
    let mut z = [0.0; 3];
    let mut expected = vec![[0.0; 3]; run.rows()];
    for i in 0..run.rows() {
        expected[i] = std::array::from_fn(|k| h.amplitude[k] * z[k]);
        if i + 1 < run.rows() {
            for k in 0..3 {
                let dq = run.state(i + 1).0[k] - run.state(i).0[k];
                if dq != 0.0 {
                    z[k] = dq.signum() + (z[k] - dq.signum()) * (-dq.abs() / h.travel[k]).exp();
                }
            }
        }
    }
    assert_effect(&run, "hysteresis", 1e-5, |_, i, k| expected[i][k]);
}

#[test]
fn inertial_effects_follow_their_equations() {
    let a = Armature::default();
    let run1 = run(&with(Effects { armature: Some(a.clone()), ..Default::default() }), 3.0);
    assert_effect(&run1, "armature", 1e-9, |r, i, k| a.inertia[k] * r.state(i).2[k]);

    let p = Payload { at_s: 1.0, ..Payload::default() };
    let run2 = run(&with(Effects { payload: Some(p.clone()), ..Default::default() }), 3.0);
    let body = run2.model.bodies.iter().position(|b| b.name == p.body).unwrap();
    let mut delta = vec![0.0; run2.params.len()];
    delta[body * 10..body * 10 + 10].copy_from_slice(&params_from_com(p.mass, &Vec3::from(p.position), &Mat3::zeros()));
    assert_effect(
        &run2,
        "payload",
        1e-9,
        |r, i, k| if r.truth.t[i] < p.at_s { 0.0 } else { r.model_torque(i, &delta)[k] },
    );

    let drift = FrictionDrift { time_constant_s: 1.0, ..FrictionDrift::default() };
    let run3 = run(&with(Effects { friction_drift: Some(drift.clone()), ..Default::default() }), 3.0);
    let truth = Scenario::default().truth;
    assert_effect(&run3, "friction_drift", 1e-9, |r, i, k| {
        let factor = drift.amplitude * (1.0 - (-r.truth.t[i] / drift.time_constant_s).exp());
        let qd = r.state(i).1[k];
        factor * (truth.viscous[k] * qd + truth.coulomb[k] * (qd / truth.coulomb_epsilon).tanh())
    });
}

#[test]
fn cable_compliance_is_a_two_mass_system() {
    let c = Compliance::default();
    let run = run(&with(Effects { compliance: Some(c.clone()), ..Default::default() }), 3.0);
    // The joint moves under the spring and damper, not under the motor torque.
    let scale = run.tau_scale();
    let mut stretch: f64 = 0.0;
    for i in 0..run.rows() {
        let tau = run.model_torque(i, &run.params);
        for k in 0..3 {
            let j = i * 3 + k;
            let (dq, dqd) = (run.truth.motor_q[j] - run.truth.q[j], run.truth.motor_qd[j] - run.truth.qd[j]);
            let spring = c.stiffness[k] * dq + c.damping[k] * dqd;
            assert!(
                (tau[k] - spring).abs() < 1e-9 * scale[k],
                "cycle {i} joint {k}: Yπ {} against spring {spring}",
                tau[k]
            );
            stretch = stretch.max(dq.abs());
        }
    }
    assert!(stretch > 1e-5, "the cable never stretched ({stretch:.2e})");
    // The encoder is on the motor.
    let quantum = 2.0 * std::f64::consts::PI * Scenario::default().sensors.transmission[0] / 8192.0;
    let i = run.rows() / 2;
    assert!((run.cycles.q[i * 3] - run.truth.motor_q[i * 3]).abs() <= 0.5 * quantum + 1e-15);
}

#[test]
fn measurement_effects_shift_and_delay_the_measured_torque() {
    let o = TorqueOffset::default();
    let run1 = run(&with(Effects { torque_offset: Some(o.clone()), ..Default::default() }), 3.0);
    let n = run1.rows();
    let noise = Scenario::default().sensors.torque_noise;
    for k in 0..3 {
        let mean =
            (0..n).map(|i| run1.cycles.tau_meas[i * 3 + k] - run1.truth.tau_motor[i * 3 + k]).sum::<f64>() / n as f64;
        assert!((mean - o.offset[k]).abs() < 4.0 * noise[k] / (n as f64).sqrt(), "joint {k}: offset {mean}");
    }
    let drift = TorqueDrift::default();
    let run3 = run(&with(Effects { torque_drift: Some(drift.clone()), ..Default::default() }), 3.0);
    for k in 0..3 {
        let v: Vec<f64> = (0..n)
            .map(|i| {
                run3.cycles.tau_meas[i * 3 + k] - run3.truth.tau_motor[i * 3 + k] - drift.rate[k] * run3.truth.t[i]
            })
            .collect();
        let mean = v.iter().sum::<f64>() / n as f64;
        assert!(mean.abs() < 4.0 * noise[k] / (n as f64).sqrt(), "joint {k}: drift residual {mean}");
    }
    let d = Delay { samples: 4 };
    let run2 = run(&with(Effects { delay: Some(d.clone()), ..Default::default() }), 3.0);
    // Against the applied torque d cycles earlier, only noise is left; against the same cycle,
    // the change of torque over d ms is.
    for k in 0..3 {
        let spread = |lag: usize| {
            let v: Vec<f64> =
                (lag..n).map(|i| run2.cycles.tau_meas[i * 3 + k] - run2.truth.tau_motor[(i - lag) * 3 + k]).collect();
            (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
        };
        assert!((spread(d.samples) / noise[k] - 1.0).abs() < 0.05, "joint {k}: {}", spread(d.samples));
        for lag in [0, d.samples - 1, d.samples + 1] {
            assert!(spread(lag) > spread(d.samples), "joint {k}: lag {lag} fits as well as the true delay");
        }
    }
}

#[test]
fn runs_are_deterministic_for_a_seed() {
    let mut scenario = with(Effects { stribeck: Some(Stribeck::default()), ..Default::default() });
    let a = run(&scenario, 0.5);
    let b = run(&scenario, 0.5);
    assert_eq!(a.cycles, b.cycles);
    scenario.seed = 7;
    let c = run(&scenario, 0.5);
    assert_ne!(a.cycles.tau_meas, c.cycles.tau_meas);
}

#[test]
fn the_amplifiers_saturate_at_their_limit() {
    let mut scenario = Scenario::default();
    scenario.actuators.torque_limit = vec![0.02, 0.25, 0.9];
    let run = run(&scenario, 2.0);
    let mut saturated = [false; 3];
    for i in 0..run.rows() {
        for k in 0..3 {
            let limit = scenario.actuators.torque_limit[k];
            assert!(run.truth.tau_motor[i * 3 + k].abs() <= limit, "cycle {i} joint {k}");
            saturated[k] |=
                run.cycles.tau_cmd[i * 3 + k].abs() > limit && run.truth.tau_motor[i * 3 + k].abs() == limit;
        }
    }
    assert!(saturated.iter().any(|s| *s), "no command reached the limits {saturated:?}");
}
