//! The flight-log message schema (protobuf, package `arash`), with its descriptor written into
//! each file so that Foxglove and the `mcap-protobuf-support` Python decoder read the messages
//! without any `.proto` file.
//!
//! Fields are flat numbers: scalars, or one repeated double per joint vector (index k is
//! joint k, in the order of the `joint_names` metadata).

use prost_types::field_descriptor_proto::{Label, Type};
use prost_types::{DescriptorProto, FieldDescriptorProto, FileDescriptorProto, FileDescriptorSet};

use crate::record::{cycle_fields, truth_fields, Code, CycleRecord, TruthRecord};

/// A message from a list of a record's fields (`record::cycle_fields`, `record::truth_fields`):
/// its struct, the copies to and from the record, and its descriptor's table.
macro_rules! message {
    (
        names {
            $(#[$rdoc:meta])* record $record:ident,
            $(#[$cldoc:meta])* columns $columns:ident,
            $(#[$mdoc:meta])* message $message:ident,
            table $table:ident,
            $($(#[$fdoc:meta])* snapshot $snapshot:ident,)?
        }
        scalars { $($(#[$sdoc:meta])* $scalar:ident: $stype:ty as $sproto:ident = $stag:literal,)* }
        joints { $($(#[$jdoc:meta])* $joint:ident = $jtag:literal,)* }
        optional { $($(#[$odoc:meta])* $optional:ident: $width:tt = $otag:literal,)* }
        codes { $($(#[$cdoc:meta])* $code:ident: $ctype:ty = $ctag:literal,)* }
    ) => {
        $(#[$mdoc])*
        #[derive(Clone, PartialEq, prost::Message)]
        pub struct $message {
            $($(#[$sdoc])* #[prost($sproto, tag = $stag)] pub $scalar: $stype,)*
            $($(#[$jdoc])* #[prost(double, repeated, tag = $jtag)] pub $joint: Vec<f64>,)*
            $($(#[$odoc])* #[prost(double, repeated, tag = $otag)] pub $optional: Vec<f64>,)*
            $($(#[$cdoc])* #[prost(uint32, tag = $ctag)] pub $code: u32,)*
        }

        impl $message {
            /// Copy `r` into this message, reusing its vectors.
            pub fn fill(&mut self, r: &$record) {
                $(self.$scalar = r.$scalar;)*
                $(self.$joint.clear(); self.$joint.extend_from_slice(&r.$joint);)*
                $(self.$optional.clear(); self.$optional.extend_from_slice(&r.$optional);)*
                $(self.$code = Code::code(r.$code);)*
            }

            /// Copy this message into `r`, reusing its vectors; an error names a typed field whose
            /// code no version wrote.
            pub fn to_record(&self, r: &mut $record) -> Result<(), String> {
                $(r.$scalar = self.$scalar;)*
                $(r.$joint.clear(); r.$joint.extend_from_slice(&self.$joint);)*
                $(r.$optional.clear(); r.$optional.extend_from_slice(&self.$optional);)*
                $(r.$code = Code::from_code(self.$code)
                    .ok_or_else(|| format!("unknown {} code {}", stringify!($code), self.$code))?;)*
                Ok(())
            }
        }

        /// (name, tag, type, repeated) of each field of the message, for its descriptor.
        const $table: &[(&str, i32, Type, bool)] = &[
            $((stringify!($scalar), tag($stag), proto_type!($sproto), false),)*
            $((stringify!($joint), tag($jtag), Type::Double, true),)*
            $((stringify!($optional), tag($otag), Type::Double, true),)*
            $((stringify!($code), tag($ctag), Type::Uint32, false),)*
        ];
    };
}

/// The descriptor's type of a scalar field, from its prost type.
macro_rules! proto_type {
    (uint64) => {
        Type::Uint64
    };
    (double) => {
        Type::Double
    };
}

/// A field number written as prost's attribute wants it (`"12"`), as a number.
const fn tag(text: &str) -> i32 {
    let (digits, mut i, mut n) = (text.as_bytes(), 0, 0);
    while i < digits.len() {
        assert!(digits[i].is_ascii_digit(), "a field number is decimal digits");
        n = 10 * n + (digits[i] - b'0') as i32;
        i += 1;
    }
    n
}

cycle_fields!(message);
truth_fields!(message);

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

/// (name, tag, type, repeated) of each field of the tracking error's message. Files carry the
/// descriptors built from these tables; the Python tests decode them with it and compare against
/// the Rust reader (which uses the structs), so a mismatch between the two fails there.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::{ControllerKind, Faults};
    use crate::record::Mode;
    use prost::Message;

    /// A record with every field set, each vector to values of its own.
    fn full_record() -> CycleRecord {
        let mut r = CycleRecord::new(3);
        let mut next = 0.0;
        let mut fresh = |n: usize| -> Vec<f64> {
            (0..n)
                .map(|_| {
                    next += 1.25;
                    next
                })
                .collect()
        };
        (r.cycle, r.t) = (41, 0.041);
        (r.q, r.qd, r.qdd, r.tau_cmd, r.tau_meas) = (fresh(3), fresh(3), fresh(3), fresh(3), fresh(3));
        (r.q_des, r.qd_des, r.qdd_des, r.tau_ext, r.frame_force) = (fresh(3), fresh(3), fresh(3), fresh(3), fresh(3));
        (r.controller, r.mode, r.faults) = (ControllerKind::Robust, Mode::Faulted, Faults(0b1010));
        r
    }

    /// Every field survives the message: record → bytes → record.
    #[test]
    fn a_record_goes_through_the_message_unchanged() {
        let record = full_record();
        let mut message = Cycle::default();
        message.fill(&record);
        let decoded = Cycle::decode(&*message.encode_to_vec()).unwrap();
        let mut back = CycleRecord::new(0);
        decoded.to_record(&mut back).unwrap();
        assert_eq!(back, record);
    }

    /// The fixed-size copy the daemon queues keeps every field, with and without the optional
    /// vectors, and fills a record without growing it.
    #[test]
    fn a_record_goes_through_its_snapshot_unchanged() {
        let mut record = full_record();
        let mut back = CycleRecord::new(3);
        let capacity = back.tau_ext.capacity();
        crate::record::CycleSnapshot::<8>::of(&record).write_into(&mut back);
        assert_eq!(back, record);
        assert_eq!(back.tau_ext.capacity(), capacity);
        (record.tau_ext, record.frame_force) = (vec![], vec![]);
        let snapshot = crate::record::CycleSnapshot::<8>::of(&record);
        assert!(snapshot.tau_ext.is_none() && snapshot.frame_force.is_none());
        snapshot.write_into(&mut back);
        assert_eq!(back, record);
    }

    /// The truth's message is written from its list as the cycle's is: every field survives.
    #[test]
    fn a_truth_goes_through_its_message_unchanged() {
        let mut truth = TruthRecord::new(2);
        let fields = [
            &mut truth.q,
            &mut truth.qd,
            &mut truth.qdd,
            &mut truth.tau_motor,
            &mut truth.motor_q,
            &mut truth.motor_qd,
            &mut truth.tau_hand,
        ];
        for (k, v) in fields.into_iter().enumerate() {
            *v = vec![k as f64 + 0.5, -(k as f64)];
        }
        (truth.cycle, truth.t, truth.hand_force) = (7, 0.007, vec![1.0, -2.0, 3.0]);
        let mut message = Truth::default();
        message.fill(&truth);
        let decoded = Truth::decode(&*message.encode_to_vec()).unwrap();
        let mut back = TruthRecord::new(0);
        decoded.to_record(&mut back).unwrap();
        assert_eq!(back, truth);
        let numbers: std::collections::BTreeSet<i32> = TRUTH_FIELDS.iter().map(|f| f.1).collect();
        assert_eq!(numbers, (1..=10).collect(), "the truth's field numbers");
    }

    /// The descriptor names each field of the message once, with the number prost encodes it
    /// under: a message holding only one field encodes that number in its first key.
    #[test]
    fn the_descriptor_numbers_the_fields_as_prost_encodes_them() {
        let names: Vec<&str> = CYCLE_FIELDS.iter().map(|f| f.0).collect();
        let unique: std::collections::BTreeSet<&str> = names.iter().copied().collect();
        assert_eq!(unique.len(), names.len(), "{names:?}");
        let numbers: std::collections::BTreeSet<i32> = CYCLE_FIELDS.iter().map(|f| f.1).collect();
        assert_eq!(numbers, (1..=16).collect(), "the flight log's field numbers");
        let only_q = Cycle { q: vec![1.0], ..Default::default() };
        let key = only_q.encode_to_vec()[0];
        assert_eq!(i32::from(key >> 3), CYCLE_FIELDS.iter().find(|f| f.0 == "q").unwrap().1);
    }

    #[test]
    fn a_code_no_version_wrote_is_refused_by_its_field() {
        let mut message = Cycle::default();
        message.fill(&full_record());
        message.mode = 7;
        let err = message.to_record(&mut CycleRecord::new(0)).unwrap_err();
        assert_eq!(err, "unknown mode code 7");
    }
}
