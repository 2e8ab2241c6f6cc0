//! The flight-log message schema (protobuf, package `arash`), with its descriptor written into
//! each file so that Foxglove and the `mcap-protobuf-support` Python decoder read the messages
//! without any `.proto` file.
//!
//! Fields are flat numbers: scalars, or one repeated double per joint vector (index k is
//! joint k, in the order of the `joint_names` metadata).

use prost_types::field_descriptor_proto::{Label, Type};
use prost_types::{DescriptorProto, FieldDescriptorProto, FileDescriptorProto, FileDescriptorSet};

/// One control cycle on topic `/arash/cycle`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Cycle {
    #[prost(uint64, tag = "1")]
    pub cycle: u64,
    /// Seconds since the start of the run.
    #[prost(double, tag = "2")]
    pub t: f64,
    #[prost(double, repeated, tag = "3")]
    pub q: Vec<f64>,
    #[prost(double, repeated, tag = "4")]
    pub qd: Vec<f64>,
    /// Empty when the acceleration is not estimated.
    #[prost(double, repeated, tag = "5")]
    pub qdd: Vec<f64>,
    #[prost(double, repeated, tag = "6")]
    pub tau_cmd: Vec<f64>,
    #[prost(double, repeated, tag = "7")]
    pub tau_meas: Vec<f64>,
    #[prost(double, repeated, tag = "8")]
    pub q_des: Vec<f64>,
    #[prost(double, repeated, tag = "9")]
    pub qd_des: Vec<f64>,
    #[prost(double, repeated, tag = "10")]
    pub qdd_des: Vec<f64>,
    /// 0 none, 1 PD, 2 inverse dynamics, 3 robust.
    #[prost(uint32, tag = "11")]
    pub controller: u32,
    /// 0 disabled, 1 enabled, 2 faulted.
    #[prost(uint32, tag = "12")]
    pub mode: u32,
    /// Fault bits (see `docs/flightlog.md`).
    #[prost(uint32, tag = "13")]
    pub faults: u32,
    /// The hand's force observer: the external joint torque, and the force at its frame (base
    /// frame, N); empty when the daemon runs none.
    #[prost(double, repeated, tag = "14")]
    pub tau_ext: Vec<f64>,
    #[prost(double, repeated, tag = "15")]
    pub frame_force: Vec<f64>,
}

impl Cycle {
    /// Copy `r` into this message, reusing its vectors.
    pub fn fill(&mut self, r: &crate::record::CycleRecord) {
        self.cycle = r.cycle;
        self.t = r.t;
        for (dst, src) in [
            (&mut self.q, &r.q),
            (&mut self.qd, &r.qd),
            (&mut self.qdd, &r.qdd),
            (&mut self.tau_cmd, &r.tau_cmd),
            (&mut self.tau_meas, &r.tau_meas),
            (&mut self.q_des, &r.q_des),
            (&mut self.qd_des, &r.qd_des),
            (&mut self.qdd_des, &r.qdd_des),
            (&mut self.tau_ext, &r.tau_ext),
            (&mut self.frame_force, &r.frame_force),
        ] {
            dst.clear();
            dst.extend_from_slice(src);
        }
        self.controller = r.controller as u32;
        self.mode = r.mode as u32;
        self.faults = r.faults.0;
    }
}

/// The tracking error `q_des − q` over one display window of the daemon, on topic
/// `/arash/error`: the last cycle's error and the extremes over the window, so that a spike
/// between two displayed samples is not hidden. In display units, the only place the flight log
/// leaves SI: degrees for a revolute joint, micrometres for a prismatic one (the channel's
/// `units` metadata names them).
#[derive(Clone, PartialEq, prost::Message)]
pub struct TrackingError {
    /// The window's last cycle.
    #[prost(uint64, tag = "1")]
    pub cycle: u64,
    /// Seconds since the start of the file, as `/arash/cycle`'s `t`.
    #[prost(double, tag = "2")]
    pub t: f64,
    #[prost(double, repeated, tag = "3")]
    pub error: Vec<f64>,
    #[prost(double, repeated, tag = "4")]
    pub error_min: Vec<f64>,
    #[prost(double, repeated, tag = "5")]
    pub error_max: Vec<f64>,
    /// Cycles in the window.
    #[prost(uint32, tag = "6")]
    pub cycles: u32,
}

/// The simulator's ground truth on topic `/arash/truth`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Truth {
    #[prost(uint64, tag = "1")]
    pub cycle: u64,
    #[prost(double, tag = "2")]
    pub t: f64,
    #[prost(double, repeated, tag = "3")]
    pub q: Vec<f64>,
    #[prost(double, repeated, tag = "4")]
    pub qd: Vec<f64>,
    #[prost(double, repeated, tag = "5")]
    pub qdd: Vec<f64>,
    #[prost(double, repeated, tag = "6")]
    pub tau_motor: Vec<f64>,
    #[prost(double, repeated, tag = "7")]
    pub motor_q: Vec<f64>,
    #[prost(double, repeated, tag = "8")]
    pub motor_qd: Vec<f64>,
    #[prost(double, repeated, tag = "9")]
    pub hand_force: Vec<f64>,
    #[prost(double, repeated, tag = "10")]
    pub tau_hand: Vec<f64>,
}

/// (name, tag, type, repeated) of each field of the structs above. Files carry the descriptor
/// built from this table; the Python tests decode them with it and compare against the Rust
/// reader (which uses the structs), so a mismatch between the two fails there.
const CYCLE_FIELDS: &[(&str, i32, Type, bool)] = &[
    ("cycle", 1, Type::Uint64, false),
    ("t", 2, Type::Double, false),
    ("q", 3, Type::Double, true),
    ("qd", 4, Type::Double, true),
    ("qdd", 5, Type::Double, true),
    ("tau_cmd", 6, Type::Double, true),
    ("tau_meas", 7, Type::Double, true),
    ("q_des", 8, Type::Double, true),
    ("qd_des", 9, Type::Double, true),
    ("qdd_des", 10, Type::Double, true),
    ("controller", 11, Type::Uint32, false),
    ("mode", 12, Type::Uint32, false),
    ("faults", 13, Type::Uint32, false),
    ("tau_ext", 14, Type::Double, true),
    ("frame_force", 15, Type::Double, true),
];

const TRUTH_FIELDS: &[(&str, i32, Type, bool)] = &[
    ("cycle", 1, Type::Uint64, false),
    ("t", 2, Type::Double, false),
    ("q", 3, Type::Double, true),
    ("qd", 4, Type::Double, true),
    ("qdd", 5, Type::Double, true),
    ("tau_motor", 6, Type::Double, true),
    ("motor_q", 7, Type::Double, true),
    ("motor_qd", 8, Type::Double, true),
    ("hand_force", 9, Type::Double, true),
    ("tau_hand", 10, Type::Double, true),
];

const ERROR_FIELDS: &[(&str, i32, Type, bool)] = &[
    ("cycle", 1, Type::Uint64, false),
    ("t", 2, Type::Double, false),
    ("error", 3, Type::Double, true),
    ("error_min", 4, Type::Double, true),
    ("error_max", 5, Type::Double, true),
    ("cycles", 6, Type::Uint32, false),
];

pub const CYCLE_SCHEMA: &str = "arash.Cycle";
pub const ERROR_SCHEMA: &str = "arash.TrackingError";
pub const TRUTH_SCHEMA: &str = "arash.Truth";

fn message(name: &str, fields: &[(&str, i32, Type, bool)]) -> DescriptorProto {
    DescriptorProto {
        name: Some(name.into()),
        field: fields
            .iter()
            .map(|&(field, number, kind, repeated)| FieldDescriptorProto {
                name: Some(field.into()),
                number: Some(number),
                label: Some(if repeated { Label::Repeated } else { Label::Optional } as i32),
                r#type: Some(kind as i32),
                json_name: Some(field.into()),
                ..Default::default()
            })
            .collect(),
        ..Default::default()
    }
}

/// The serialised `FileDescriptorSet` holding message `name` (`arash.Cycle`, `arash.Truth` or
/// `arash.TrackingError`),
/// as MCAP's `protobuf` schema encoding requires.
pub fn descriptor_set(name: &str) -> Vec<u8> {
    use prost::Message;
    let (short, fields) = match name {
        CYCLE_SCHEMA => ("Cycle", CYCLE_FIELDS),
        TRUTH_SCHEMA => ("Truth", TRUTH_FIELDS),
        ERROR_SCHEMA => ("TrackingError", ERROR_FIELDS),
        other => panic!("no schema {other}"),
    };
    let file = FileDescriptorProto {
        name: Some(format!("arash/{}.proto", short.to_lowercase())),
        package: Some("arash".into()),
        message_type: vec![message(short, fields)],
        syntax: Some("proto3".into()),
        ..Default::default()
    };
    FileDescriptorSet { file: vec![file] }.encode_to_vec()
}
