//! What one control cycle records: the content of the flight log, shared by the simulator and
//! the daemon. Buffers are sized once; filling a record never allocates.

use crate::control::{ControllerKind, Faults};

/// Whether the motors may receive torque.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[repr(u32)]
pub enum Mode {
    /// Motors disabled: zero torque (the daemon's start-up state).
    Disabled = 0,
    /// Motors enabled, the controller's (gated) torque is applied.
    Enabled = 1,
    /// A fault latched: zero torque until an operator clears it.
    Faulted = 2,
}

impl Mode {
    pub fn from_u32(v: u32) -> Option<Mode> {
        [Mode::Disabled, Mode::Enabled, Mode::Faulted].into_iter().find(|m| *m as u32 == v)
    }
}

impl ControllerKind {
    pub fn from_u32(v: u32) -> Option<ControllerKind> {
        [ControllerKind::None, ControllerKind::Pd, ControllerKind::Idc, ControllerKind::Robust]
            .into_iter()
            .find(|m| *m as u32 == v)
    }
}

/// One control cycle (SI). `qdd` is empty when the acceleration is not estimated.
#[derive(Clone, Debug, PartialEq)]
pub struct CycleRecord {
    pub cycle: u64,
    /// Seconds since the start of the run.
    pub t: f64,
    /// Measured position (encoders).
    pub q: Vec<f64>,
    /// Estimated velocity.
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
    /// Torque the controller asked for, before the safety gate.
    pub tau_cmd: Vec<f64>,
    /// Torque measured from motor current.
    pub tau_meas: Vec<f64>,
    pub q_des: Vec<f64>,
    pub qd_des: Vec<f64>,
    pub qdd_des: Vec<f64>,
    pub controller: ControllerKind,
    pub mode: Mode,
    pub faults: Faults,
    /// The hand's force observer: the external joint torque (N·m, N), and the force at its
    /// frame (base frame, N). Empty when no observer runs (and `frame_force` without a frame).
    pub tau_ext: Vec<f64>,
    pub frame_force: Vec<f64>,
}

impl CycleRecord {
    pub fn new(dof: usize) -> Self {
        Self {
            cycle: 0,
            t: 0.0,
            q: vec![0.0; dof],
            qd: vec![0.0; dof],
            qdd: Vec::new(),
            tau_cmd: vec![0.0; dof],
            tau_meas: vec![0.0; dof],
            q_des: vec![0.0; dof],
            qd_des: vec![0.0; dof],
            qdd_des: vec![0.0; dof],
            controller: ControllerKind::None,
            mode: Mode::Disabled,
            faults: Faults::NONE,
            tau_ext: Vec::new(),
            frame_force: Vec::new(),
        }
    }
}

/// The simulator's ground truth for one cycle, beside the [`CycleRecord`].
#[derive(Clone, Debug, PartialEq)]
pub struct TruthRecord {
    pub t: f64,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    /// Joint acceleration at the start of the cycle.
    pub qdd: Vec<f64>,
    /// Torque the motors applied over the cycle (after saturation).
    pub tau_motor: Vec<f64>,
    /// Motor position in joint units (differs from q with cable compliance).
    pub motor_q: Vec<f64>,
    /// Motor velocity in joint units.
    pub motor_qd: Vec<f64>,
    /// The operator's hand over the cycle: its force at its frame (base frame, N; zero without
    /// a hand) and the joint torque it exerts at the cycle's start.
    pub hand_force: Vec<f64>,
    pub tau_hand: Vec<f64>,
}

impl TruthRecord {
    pub fn new(dof: usize) -> Self {
        Self {
            t: 0.0,
            q: vec![0.0; dof],
            qd: vec![0.0; dof],
            qdd: vec![0.0; dof],
            tau_motor: vec![0.0; dof],
            motor_q: vec![0.0; dof],
            motor_qd: vec![0.0; dof],
            hand_force: vec![0.0; 3],
            tau_hand: vec![0.0; dof],
        }
    }
}

/// The `/arash/cycle` messages as columns; joint vectors are row-major `N × dof`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Columns {
    pub cycle: Vec<u64>,
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    /// Empty when no cycle carried an acceleration estimate.
    pub qdd: Vec<f64>,
    pub tau_cmd: Vec<f64>,
    pub tau_meas: Vec<f64>,
    pub q_des: Vec<f64>,
    pub qd_des: Vec<f64>,
    pub qdd_des: Vec<f64>,
    pub controller: Vec<u32>,
    pub mode: Vec<u32>,
    pub faults: Vec<u32>,
    /// Empty when no cycle carried the observer's estimate (`N × dof`, and `N × 3`).
    pub tau_ext: Vec<f64>,
    pub frame_force: Vec<f64>,
}

/// The `/arash/truth` messages as columns (simulated logs only).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TruthColumns {
    pub cycle: Vec<u64>,
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
    pub tau_motor: Vec<f64>,
    pub motor_q: Vec<f64>,
    pub motor_qd: Vec<f64>,
    /// `N × 3`, row-major.
    pub hand_force: Vec<f64>,
    pub tau_hand: Vec<f64>,
}

impl Columns {
    /// The joint vectors every cycle carries (`N × dof`, row-major), by field name; `qdd`, which
    /// may be absent, is not among them.
    pub fn joint_vectors(&self) -> [(&'static str, &Vec<f64>); 7] {
        [
            ("q", &self.q),
            ("qd", &self.qd),
            ("tau_cmd", &self.tau_cmd),
            ("tau_meas", &self.tau_meas),
            ("q_des", &self.q_des),
            ("qd_des", &self.qd_des),
            ("qdd_des", &self.qdd_des),
        ]
    }

    /// Append one cycle.
    pub fn push(&mut self, r: &CycleRecord) {
        self.cycle.push(r.cycle);
        self.t.push(r.t);
        self.q.extend(&r.q);
        self.qd.extend(&r.qd);
        self.qdd.extend(&r.qdd);
        self.tau_cmd.extend(&r.tau_cmd);
        self.tau_meas.extend(&r.tau_meas);
        self.q_des.extend(&r.q_des);
        self.qd_des.extend(&r.qd_des);
        self.qdd_des.extend(&r.qdd_des);
        self.controller.push(r.controller as u32);
        self.mode.push(r.mode as u32);
        self.faults.push(r.faults.0);
        self.tau_ext.extend(&r.tau_ext);
        self.frame_force.extend(&r.frame_force);
    }
}

impl TruthColumns {
    /// The joint vectors (`N × dof`, row-major), by field name.
    pub fn joint_vectors(&self) -> [(&'static str, &Vec<f64>); 7] {
        [
            ("q", &self.q),
            ("qd", &self.qd),
            ("qdd", &self.qdd),
            ("tau_motor", &self.tau_motor),
            ("motor_q", &self.motor_q),
            ("motor_qd", &self.motor_qd),
            ("tau_hand", &self.tau_hand),
        ]
    }

    /// Append the truth of cycle `cycle`.
    pub fn push(&mut self, cycle: u64, r: &TruthRecord) {
        self.cycle.push(cycle);
        self.t.push(r.t);
        self.q.extend(&r.q);
        self.qd.extend(&r.qd);
        self.qdd.extend(&r.qdd);
        self.tau_motor.extend(&r.tau_motor);
        self.motor_q.extend(&r.motor_q);
        self.motor_qd.extend(&r.motor_qd);
        self.hand_force.extend(&r.hand_force);
        self.tau_hand.extend(&r.tau_hand);
    }
}
