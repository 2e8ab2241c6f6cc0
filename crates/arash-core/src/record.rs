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

/// A field of the cycle record stored as a number code: its value in the flight log's message
/// and in [`Columns`], and back (`None` for a code no version wrote).
pub trait Code: Sized + Copy {
    /// What a new record holds.
    const INITIAL: Self;
    fn code(self) -> u32;
    fn from_code(code: u32) -> Option<Self>;
}

impl Code for ControllerKind {
    const INITIAL: Self = ControllerKind::None;
    fn code(self) -> u32 {
        self as u32
    }
    fn from_code(code: u32) -> Option<Self> {
        [ControllerKind::None, ControllerKind::Pd, ControllerKind::Idc, ControllerKind::Robust]
            .into_iter()
            .find(|k| *k as u32 == code)
    }
}

impl Code for Mode {
    const INITIAL: Self = Mode::Disabled;
    fn code(self) -> u32 {
        self as u32
    }
    fn from_code(code: u32) -> Option<Self> {
        [Mode::Disabled, Mode::Enabled, Mode::Faulted].into_iter().find(|m| *m as u32 == code)
    }
}

impl Code for Faults {
    const INITIAL: Self = Faults::NONE;
    fn code(self) -> u32 {
        self.0
    }
    fn from_code(code: u32) -> Option<Self> {
        Some(Faults(code))
    }
}

/// The fields of one control cycle, listed once: [`CycleRecord`] and [`Columns`] here, and the
/// flight log's protobuf message, its descriptor and its decoding (`flightlog::schema`), are all
/// written from this list by the macro it is handed. Each field is one of:
/// - `scalars`: one number a cycle, with its protobuf type;
/// - `joints`: a joint vector every cycle carries (`dof` values);
/// - `optional`: a vector some runs leave empty (`width` values when present);
/// - `codes`: a typed value stored as a number ([`Code`]).
///
/// The number after `=` is the protobuf field number: never reuse or renumber one, or older logs
/// decode wrongly.
macro_rules! cycle_fields {
    ($then:ident) => {
        $then! {
            scalars {
                /// The cycle's number in the run.
                cycle: u64 as uint64 = "1",
                /// Seconds since the start of the run.
                t: f64 as double = "2",
            }
            joints {
                /// Measured position (encoders).
                q = "3",
                /// Estimated velocity.
                qd = "4",
                /// Torque the controller asked for, before the safety gate.
                tau_cmd = "6",
                /// Torque measured from motor current.
                tau_meas = "7",
                q_des = "8",
                qd_des = "9",
                qdd_des = "10",
            }
            optional {
                /// Estimated acceleration; empty when it is not estimated.
                qdd: dof = "5",
                /// The hand's force observer: the external joint torque (N·m, N); empty when no
                /// observer runs.
                tau_ext: dof = "14",
                /// The force at the observer's frame (base frame, N); empty without a frame.
                frame_force: 3 = "15",
            }
            codes {
                /// 0 none, 1 PD, 2 inverse dynamics, 3 robust.
                controller: ControllerKind = "11",
                /// 0 disabled, 1 enabled, 2 faulted.
                mode: Mode = "12",
                /// Fault bits (docs/flightlog.md).
                faults: Faults = "13",
            }
        }
    };
}
pub(crate) use cycle_fields;

/// An optional vector's width per cycle: `dof` (the joints) or a number.
macro_rules! width {
    ($dof:ident, dof) => {
        $dof
    };
    ($dof:ident, $n:literal) => {
        $n
    };
}

/// [`CycleRecord`] and [`Columns`] from the list of [`cycle_fields`].
macro_rules! record_and_columns {
    (
        scalars { $($(#[$sdoc:meta])* $scalar:ident: $stype:ty as $sproto:ident = $stag:literal,)* }
        joints { $($(#[$jdoc:meta])* $joint:ident = $jtag:literal,)* }
        optional { $($(#[$odoc:meta])* $optional:ident: $width:tt = $otag:literal,)* }
        codes { $($(#[$cdoc:meta])* $code:ident: $ctype:ty = $ctag:literal,)* }
    ) => {
        /// One control cycle (SI), as the flight log stores it (its fields are listed once, in `record.rs`'s `cycle_fields!`).
        #[derive(Clone, Debug, PartialEq)]
        pub struct CycleRecord {
            $($(#[$sdoc])* pub $scalar: $stype,)*
            $($(#[$jdoc])* pub $joint: Vec<f64>,)*
            $($(#[$odoc])* pub $optional: Vec<f64>,)*
            $($(#[$cdoc])* pub $code: $ctype,)*
        }

        impl CycleRecord {
            /// A record of `dof` joints: zero, the typed fields at their initial values
            /// (disabled, no controller, no faults), and the optional vectors empty.
            pub fn new(dof: usize) -> Self {
                Self {
                    $($scalar: Default::default(),)*
                    $($joint: vec![0.0; dof],)*
                    $($optional: Vec::new(),)*
                    $($code: <$ctype as Code>::INITIAL,)*
                }
            }
        }

        /// The `/arash/cycle` messages as columns; joint vectors are row-major `N × dof`, the
        /// typed fields their codes ([`Code`]).
        #[derive(Clone, Debug, Default, PartialEq)]
        pub struct Columns {
            $($(#[$sdoc])* pub $scalar: Vec<$stype>,)*
            $($(#[$jdoc])* pub $joint: Vec<f64>,)*
            $($(#[$odoc])* pub $optional: Vec<f64>,)*
            $($(#[$cdoc])* pub $code: Vec<u32>,)*
        }

        impl Columns {
            /// The joint vectors every cycle carries (`N × dof`, row-major), by field name.
            pub fn joint_vectors(&self) -> Vec<(&'static str, &Vec<f64>)> {
                vec![$((stringify!($joint), &self.$joint)),*]
            }

            /// The vectors some runs leave empty, by field name, with their width per cycle
            /// for `dof` joints: all cycles carry one or none does.
            pub fn optional_vectors(&self, dof: usize) -> Vec<(&'static str, &Vec<f64>, usize)> {
                vec![$((stringify!($optional), &self.$optional, width!(dof, $width))),*]
            }

            /// The typed fields' codes ([`Code`]), by field name.
            pub fn codes(&self) -> Vec<(&'static str, &Vec<u32>)> {
                vec![$((stringify!($code), &self.$code)),*]
            }

            /// Append one cycle.
            pub fn push(&mut self, r: &CycleRecord) {
                $(self.$scalar.push(r.$scalar);)*
                $(self.$joint.extend(&r.$joint);)*
                $(self.$optional.extend(&r.$optional);)*
                $(self.$code.push(Code::code(r.$code));)*
            }
        }
    };
}
cycle_fields!(record_and_columns);

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
