//! The sampled rig: the plant behind encoders, current sensing and saturating amplifiers, run by
//! a controller at the control rate. One [`Rig::step`] is one control cycle:
//!
//! 1. encoders read the motor position, quantised to whole counts;
//! 2. the velocity estimator differentiates it;
//! 3. the controller computes a torque for the reference at `t_k`;
//! 4. the safety gate checks and limits it; the amplifier saturates it;
//! 5. the motor current gives the measured torque: applied torque + noise (+ offset, + delay);
//! 6. the plant integrates over the cycle with that torque held.

use super::drive::Drive;
use super::plant::{Plant, PlantError};
use super::scenario::Scenario;
use crate::control::{Controller, Desired, SafetyGate, SafetyLimits, Trajectory, VelocityEstimator};
use crate::model::Model;
use crate::record::{CycleRecord, Mode, TruthRecord};

/// The simulated rig and its last cycle.
pub struct Rig {
    drive: Drive,
    controller: Box<dyn Controller>,
    gate: SafetyGate,
    estimator: VelocityEstimator,
    trajectory: Trajectory,
    dt: f64,
    tau_gated: Vec<f64>,
    record: CycleRecord,
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
        let mut drive = Drive::new(model, scenario)?;
        let n = model.dof();
        let mut record = CycleRecord::new(n);
        trajectory.eval(0.0, &mut record.q_des, &mut record.qd_des, &mut record.qdd_des);
        drive.start_at(&record.q_des, &record.qd_des, &record.qdd_des);
        let mut estimator = VelocityEstimator::new(n, scenario.sensors.velocity_cutoff_hz);
        let q_read: Vec<f64> = (0..n).map(|k| drive.encoder_position(k)).collect();
        estimator.prime(&q_read, &record.qd_des);
        record.controller = controller.kind();
        Ok(Self {
            drive,
            controller,
            gate: SafetyGate::new(SafetyLimits::from_model(model)),
            estimator,
            trajectory,
            dt: 1.0 / scenario.physics.rate_hz,
            tau_gated: vec![0.0; n],
            record,
            cycles: 0,
        })
    }

    /// Replace the default safety limits (from the URDF).
    pub fn set_safety_limits(&mut self, limits: SafetyLimits) {
        self.gate = SafetyGate::new(limits);
    }

    pub fn plant(&self) -> &Plant {
        self.drive.plant()
    }

    /// The last cycle, as the flight log records it.
    pub fn record(&self) -> &CycleRecord {
        &self.record
    }

    /// The truth behind the last cycle.
    pub fn truth(&self) -> &TruthRecord {
        self.drive.truth()
    }

    /// Control period (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Run one control cycle. Never allocates.
    pub fn step(&mut self) -> Result<(), PlantError> {
        let n = self.record.q.len();
        let t = self.drive.plant().time();
        let r = &mut self.record;
        r.cycle = self.cycles;
        r.t = t;
        for k in 0..n {
            r.q[k] = self.drive.encoder_position(k);
        }
        r.qd.copy_from_slice(self.estimator.update(self.dt, &r.q));
        self.trajectory.eval(t, &mut r.q_des, &mut r.qd_des, &mut r.qdd_des);
        let desired = Desired { q: &r.q_des, qd: &r.qd_des, qdd: &r.qdd_des };
        self.controller.step(self.dt, &r.q, &r.qd, &desired, &mut r.tau_cmd);
        r.faults = self.gate.apply(self.dt, &r.q, &r.qd, &r.tau_cmd, &mut self.tau_gated);
        r.mode = if r.faults.is_empty() { Mode::Enabled } else { Mode::Faulted };
        self.drive.apply(self.dt, &self.tau_gated)?;
        self.record.tau_meas.copy_from_slice(self.drive.measured_torque());
        self.cycles += 1;
        Ok(())
    }
}
