//! The motor side of the simulated rig: amplifiers, encoders and current sensors around the
//! plant. The in-process [`Rig`](super::Rig) and the daemon's mock motor share it, so a run over
//! the motor link sees exactly the physics and sensor effects of `arash simulate`.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::plant::{Plant, PlantError};
use super::scenario::Scenario;
use crate::dynamics::inverse_dynamics;
use crate::model::Model;
use crate::record::TruthRecord;

/// Plant, amplifiers (saturation), encoders (whole counts) and torque sensing (noise, offset,
/// delay). One [`Drive::apply`] is one control cycle with the torque held.
pub struct Drive {
    plant: Plant,
    scenario: Scenario,
    rng: ChaCha8Rng,
    noise: Vec<Normal<f64>>,
    /// Joint motion per encoder count (rad or m).
    resolution: Vec<f64>,
    saturation: Vec<f64>,
    /// Ring of measured torques for the delay effect: `(samples + 1) × dof`.
    delay_ring: Vec<f64>,
    tau_meas: Vec<f64>,
    truth: TruthRecord,
    cycles: u64,
}

impl Drive {
    /// The drive for `model` (CAD) under `scenario`, at rest at the zero configuration.
    pub fn new(model: &Model, scenario: &Scenario) -> Result<Self, PlantError> {
        let plant = Plant::new(model, scenario)?;
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
        let mut drive = Self {
            plant,
            scenario: scenario.clone(),
            rng,
            noise,
            resolution,
            saturation,
            delay_ring: vec![f64::NAN; (delay + 1) * n],
            tau_meas: vec![0.0; n],
            truth: TruthRecord::new(n),
            cycles: 0,
        };
        let zero = vec![0.0; n];
        drive.start_at(&zero, &zero, &zero);
        Ok(drive)
    }

    /// Place the robot at `q` moving at `qd`, with the cables stretched to hold the inverse
    /// dynamics for `qdd` there, and restart the clock.
    pub fn start_at(&mut self, q: &[f64], qd: &[f64], qdd: &[f64]) {
        let n = q.len();
        let mut hold = vec![0.0; n];
        let mut data = crate::Data::new(self.plant.model());
        let params = self.plant.params().to_vec();
        inverse_dynamics(self.plant.model(), &mut data, q, qd, qdd, &params, &mut hold);
        self.plant.reset(q, qd, &hold);
        self.delay_ring.fill(f64::NAN);
        self.cycles = 0;
    }

    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// Joint motion per encoder count (rad or m).
    pub fn resolution(&self) -> &[f64] {
        &self.resolution
    }

    /// Amplifier limits (N·m or N).
    pub fn saturation(&self) -> &[f64] {
        &self.saturation
    }

    /// Encoder reading of joint `k` in whole counts (the encoder sits on the motor).
    pub fn encoder_counts(&self, k: usize) -> i64 {
        (self.plant.motor_position()[k] / self.resolution[k]).round() as i64
    }

    /// Encoder reading of joint `k` in joint units.
    pub fn encoder_position(&self, k: usize) -> f64 {
        self.encoder_counts(k) as f64 * self.resolution[k]
    }

    /// The torque sensed from motor current during the last [`apply`](Self::apply).
    pub fn measured_torque(&self) -> &[f64] {
        &self.tau_meas
    }

    /// The truth behind the last cycle.
    pub fn truth(&self) -> &TruthRecord {
        &self.truth
    }

    /// The header of [`Self::truth_csv_row`]'s table: a simulator serving the rig behind a link
    /// (`arash mock-motor --truth`, `python -m arash.cia402_sim --truth`) writes the truth a run
    /// through the daemon is judged by, the same columns whichever link serves it.
    pub fn truth_csv_header(&self) -> String {
        let n = self.tau_meas.len();
        let mut columns = vec!["t".to_string()];
        for name in ["q", "qd", "tau_motor", "tau_hand"] {
            columns.extend((1..=n).map(|k| format!("{name}{k}")));
        }
        columns.extend(["hand_x", "hand_y", "hand_z"].map(String::from));
        columns.join(",")
    }

    /// The last cycle's truth as a CSV row (no newline) into `out`, cleared first: SI units, the
    /// hand's force at its frame in the base frame (zeros without a hand).
    pub fn truth_csv_row(&self, out: &mut String) {
        use std::fmt::Write;
        let tr = &self.truth;
        out.clear();
        let _ = write!(out, "{:.6}", tr.t);
        for v in tr.q.iter().chain(&tr.qd).chain(&tr.tau_motor).chain(&tr.tau_hand) {
            let _ = write!(out, ",{v:.9e}");
        }
        for a in 0..3 {
            let _ = write!(out, ",{:.9e}", tr.hand_force.get(a).copied().unwrap_or(0.0));
        }
    }

    /// One cycle of `dt` seconds with `tau` commanded: the amplifiers saturate it, the current
    /// sensors measure it, and the plant integrates with it held. Never allocates.
    pub fn apply(&mut self, dt: f64, tau: &[f64]) -> Result<(), PlantError> {
        let tr = &mut self.truth;
        tr.cycle = self.cycles;
        tr.t = self.plant.time();
        tr.q.copy_from_slice(self.plant.q());
        tr.qd.copy_from_slice(self.plant.qd());
        tr.motor_q.copy_from_slice(self.plant.motor_position());
        tr.motor_qd.copy_from_slice(self.plant.motor_velocity());
        for ((out, &t), &limit) in tr.tau_motor.iter_mut().zip(tau).zip(&self.saturation) {
            *out = t.clamp(-limit, limit);
        }
        self.measure_torque();
        self.plant.advance(dt, &self.truth.tau_motor)?;
        self.truth.qdd.copy_from_slice(self.plant.qdd());
        self.truth.hand_force.clear();
        self.truth.hand_force.extend_from_slice(self.plant.hand_force());
        self.truth.tau_hand.copy_from_slice(self.plant.hand_torque());
        self.cycles += 1;
        Ok(())
    }

    /// Current-sensed torque: applied + noise + offset, then delayed.
    fn measure_torque(&mut self) {
        let n = self.tau_meas.len();
        let slots = self.delay_ring.len() / n;
        let now = (self.cycles as usize % slots) * n;
        for k in 0..n {
            let offset = self.scenario.effects.torque_offset.as_ref().map_or(0.0, |o| o.offset[k])
                + self.scenario.effects.torque_drift.as_ref().map_or(0.0, |d| d.rate[k] * self.truth.t);
            self.delay_ring[now + k] = self.truth.tau_motor[k] + self.noise[k].sample(&mut self.rng) + offset;
        }
        if self.cycles == 0 {
            // Before the first delayed sample exists, the sensor reads the first value.
            for slot in 1..slots {
                self.delay_ring.copy_within(0..n, slot * n);
            }
        }
        let oldest = ((self.cycles as usize + 1) % slots) * n;
        self.tau_meas.copy_from_slice(&self.delay_ring[oldest..oldest + n]);
    }
}
