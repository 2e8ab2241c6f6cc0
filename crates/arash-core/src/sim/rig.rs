//! The sampled rig: the plant behind encoders, current sensing and saturating amplifiers, run by
//! a controller at the control rate. One [`Rig::step`] is one control cycle:
//!
//! 1. encoders read the motor position, quantised to whole counts;
//! 2. the velocity estimator differentiates it;
//! 3. the controller computes a torque for the reference at `t_k`;
//! 4. the safety gate checks and limits it; the amplifier saturates it;
//! 5. the motor current gives the measured torque: applied torque + noise (+ offset, + delay);
//! 6. the plant integrates over the cycle with that torque held.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::plant::{Plant, PlantError};
use super::scenario::Scenario;
use crate::control::{Controller, Desired, SafetyGate, SafetyLimits, Trajectory, VelocityEstimator};
use crate::dynamics::inverse_dynamics;
use crate::model::Model;
use crate::record::{CycleRecord, Mode, TruthRecord};

/// The simulated rig and its last cycle.
pub struct Rig {
    plant: Plant,
    controller: Box<dyn Controller>,
    gate: SafetyGate,
    estimator: VelocityEstimator,
    trajectory: Trajectory,
    scenario: Scenario,
    rng: ChaCha8Rng,
    noise: Vec<Normal<f64>>,
    dt: f64,
    resolution: Vec<f64>,
    saturation: Vec<f64>,
    /// Ring of measured torques for the delay effect: `(samples + 1) × dof`.
    delay_ring: Vec<f64>,
    tau_gated: Vec<f64>,
    record: CycleRecord,
    truth: TruthRecord,
    cycles: u64,
}

impl Rig {
    /// A rig following `trajectory` with `controller`, starting on the trajectory at `t = 0`.
    pub fn new(
        model: &Model,
        scenario: &Scenario,
        trajectory: Trajectory,
        controller: Box<dyn Controller>,
    ) -> Result<Self, PlantError> {
        let mut plant = Plant::new(model, scenario)?;
        let n = model.dof();
        let s = &scenario.sensors;
        let resolution: Vec<f64> =
            (0..n).map(|k| 2.0 * std::f64::consts::PI * s.transmission[k] / s.counts_per_rev[k]).collect();
        let saturation = if scenario.actuators.torque_limit.is_empty() {
            model.joints.iter().map(|j| j.effort).collect()
        } else {
            scenario.actuators.torque_limit.clone()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(scenario.seed);
        rng.set_stream(1);
        let noise = s.torque_noise.iter().map(|&sd| Normal::new(0.0, sd).expect("validated: finite, ≥ 0")).collect();
        let delay = scenario.effects.delay.as_ref().map_or(0, |d| d.samples);

        let mut record = CycleRecord::new(n);
        trajectory.eval(0.0, &mut record.q_des, &mut record.qd_des, &mut record.qdd_des);
        let mut hold = vec![0.0; n];
        let mut data = crate::Data::new(plant.model());
        let params = plant.params().to_vec();
        inverse_dynamics(plant.model(), &mut data, &record.q_des, &record.qd_des, &record.qdd_des, &params, &mut hold);
        plant.reset(&record.q_des, &record.qd_des, &hold);
        let mut estimator = VelocityEstimator::new(n, s.velocity_cutoff_hz);
        let q_read: Vec<f64> = (0..n).map(|k| quantise(plant.motor_position()[k], resolution[k])).collect();
        estimator.prime(&q_read, &record.qd_des);
        record.controller = controller.kind();
        Ok(Self {
            plant,
            controller,
            gate: SafetyGate::new(SafetyLimits::from_model(model)),
            estimator,
            trajectory,
            scenario: scenario.clone(),
            rng,
            noise,
            dt: 1.0 / scenario.physics.rate_hz,
            resolution,
            saturation,
            delay_ring: vec![f64::NAN; (delay + 1) * n],
            tau_gated: vec![0.0; n],
            record,
            truth: TruthRecord::new(n),
            cycles: 0,
        })
    }

    /// Replace the default safety limits (from the URDF).
    pub fn set_safety_limits(&mut self, limits: SafetyLimits) {
        self.gate = SafetyGate::new(limits);
    }

    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The last cycle, as the flight log records it.
    pub fn record(&self) -> &CycleRecord {
        &self.record
    }

    /// The truth behind the last cycle.
    pub fn truth(&self) -> &TruthRecord {
        &self.truth
    }

    /// Control period (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Run one control cycle. Never allocates.
    pub fn step(&mut self) -> Result<(), PlantError> {
        let n = self.record.q.len();
        let t = self.plant.time();
        let r = &mut self.record;
        r.cycle = self.cycles;
        r.t = t;
        for k in 0..n {
            r.q[k] = quantise(self.plant.motor_position()[k], self.resolution[k]);
        }
        r.qd.copy_from_slice(self.estimator.update(self.dt, &r.q));
        self.trajectory.eval(t, &mut r.q_des, &mut r.qd_des, &mut r.qdd_des);
        let desired = Desired { q: &r.q_des, qd: &r.qd_des, qdd: &r.qdd_des };
        self.controller.step(self.dt, &r.q, &r.qd, &desired, &mut r.tau_cmd);
        r.faults = self.gate.apply(self.dt, &r.q, &r.qd, &r.tau_cmd, &mut self.tau_gated);
        r.mode = if r.faults.is_empty() { Mode::Enabled } else { Mode::Faulted };

        let tr = &mut self.truth;
        tr.t = t;
        tr.q.copy_from_slice(self.plant.q());
        tr.qd.copy_from_slice(self.plant.qd());
        tr.motor_q.copy_from_slice(self.plant.motor_position());
        tr.motor_qd.copy_from_slice(self.plant.motor_velocity());
        for k in 0..n {
            tr.tau_motor[k] = self.tau_gated[k].clamp(-self.saturation[k], self.saturation[k]);
        }
        self.measure_torque();
        self.plant.advance(self.dt, &self.truth.tau_motor)?;
        self.truth.qdd.copy_from_slice(self.plant.qdd());
        self.cycles += 1;
        Ok(())
    }

    /// Current-sensed torque: applied + noise + offset, then delayed.
    fn measure_torque(&mut self) {
        let n = self.record.q.len();
        let slots = self.delay_ring.len() / n;
        let now = (self.record.cycle as usize % slots) * n;
        for k in 0..n {
            let offset = self.scenario.effects.torque_offset.as_ref().map_or(0.0, |o| o.offset[k]);
            self.delay_ring[now + k] = self.truth.tau_motor[k] + self.noise[k].sample(&mut self.rng) + offset;
        }
        if self.record.cycle == 0 {
            // Before the first delayed sample exists, the sensor reads the first value.
            for slot in 1..slots {
                self.delay_ring.copy_within(0..n, slot * n);
            }
        }
        let oldest = ((self.record.cycle as usize + 1) % slots) * n;
        self.record.tau_meas.copy_from_slice(&self.delay_ring[oldest..oldest + n]);
    }
}

/// An encoder reading: the position rounded to whole counts of `resolution`.
fn quantise(position: f64, resolution: f64) -> f64 {
    (position / resolution).round() * resolution
}
