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
        [ControllerKind::None, ControllerKind::Pd, ControllerKind::Idc, ControllerKind::Robust, ControllerKind::Haptic]
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
/// written from this list by the macro it is handed. After the `names` of what is written, each
/// field is one of:
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
            names {
                /// One control cycle (SI), as the flight log stores it (its fields are listed
                /// once, in `record.rs`'s `cycle_fields!`).
                record CycleRecord,
                /// The `/arash/cycle` messages as columns; joint vectors are row-major `N × dof`,
                /// the typed fields their codes ([`Code`]).
                columns Columns,
                /// One control cycle on topic `/arash/cycle`.
                message Cycle,
                table CYCLE_FIELDS,
                /// One control cycle in fixed-size storage, for at most `MAX` joints: `Copy`, so
                /// it crosses a real-time queue without allocating.
                snapshot CycleSnapshot,
            }
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
                /// The force the haptic mode's fixtures rendered at the instrument (base frame,
                /// N): zeros outside the mode; empty where nothing can render any (the
                /// simulator's logs).
                fixture_force: 3 = "16",
            }
            codes {
                /// 0 none, 1 PD, 2 inverse dynamics, 3 robust, 4 the haptic mode.
                controller: ControllerKind = "11",
                /// 0 disabled, 1 enabled, 2 faulted.
                mode: Mode = "12",
                /// Fault bits (docs/flightlog.md).
                faults: Faults = "13",
            }
        }
    };
}
#[cfg(feature = "flightlog")]
pub(crate) use cycle_fields;

/// The simulator's ground truth for one cycle, beside the [`CycleRecord`]: its fields listed
/// once, as [`cycle_fields`] lists the cycle's, and written by the same macros.
macro_rules! truth_fields {
    ($then:ident) => {
        $then! {
            names {
                /// The simulator's ground truth for one cycle (its fields are listed once, in
                /// `record.rs`'s `truth_fields!`).
                record TruthRecord,
                /// The `/arash/truth` messages as columns (simulated logs only).
                columns TruthColumns,
                /// The simulator's ground truth on topic `/arash/truth`.
                message Truth,
                table TRUTH_FIELDS,
            }
            scalars {
                /// The cycle's number in the run.
                cycle: u64 as uint64 = "1",
                t: f64 as double = "2",
            }
            joints {
                q = "3",
                qd = "4",
                /// Joint acceleration at the start of the cycle.
                qdd = "5",
                /// Torque the motors applied over the cycle (after saturation).
                tau_motor = "6",
                /// Motor position in joint units (differs from q with cable compliance).
                motor_q = "7",
                /// Motor velocity in joint units.
                motor_qd = "8",
                /// The joint torque the operator's hand exerts at the cycle's start.
                tau_hand = "10",
            }
            optional {
                /// The hand's force at its frame (base frame, N; zero without a hand).
                hand_force: 3 = "9",
            }
            codes {}
        }
    };
}
#[cfg(feature = "flightlog")]
pub(crate) use truth_fields;

/// An optional vector's width per cycle: `dof` (the joints) or a number.
macro_rules! width {
    ($dof:ident, dof) => {
        $dof
    };
    // `dof` is named still, so a list whose widths are all numbers leaves no argument unused.
    ($dof:ident, $n:literal) => {{
        let _ = $dof;
        $n
    }};
}

/// A record and its columns from a list of fields ([`cycle_fields`], [`truth_fields`]).
macro_rules! record_and_columns {
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
        $(#[$rdoc])*
        #[derive(Clone, Debug, PartialEq)]
        pub struct $record {
            $($(#[$sdoc])* pub $scalar: $stype,)*
            $($(#[$jdoc])* pub $joint: Vec<f64>,)*
            $($(#[$odoc])* pub $optional: Vec<f64>,)*
            $($(#[$cdoc])* pub $code: $ctype,)*
        }

        impl $record {
            /// A record of `dof` joints: zero, the typed fields at their initial values
            /// (disabled, no controller, no faults), and the optional vectors empty, with room
            /// for their width so that filling them never allocates.
            pub fn new(dof: usize) -> Self {
                Self {
                    $($scalar: Default::default(),)*
                    $($joint: vec![0.0; dof],)*
                    $($optional: Vec::with_capacity(width!(dof, $width)),)*
                    $($code: <$ctype as Code>::INITIAL,)*
                }
            }
        }

        $(#[$cldoc])*
        #[derive(Clone, Debug, Default, PartialEq)]
        pub struct $columns {
            $($(#[$sdoc])* pub $scalar: Vec<$stype>,)*
            $($(#[$jdoc])* pub $joint: Vec<f64>,)*
            $($(#[$odoc])* pub $optional: Vec<f64>,)*
            $($(#[$cdoc])* pub $code: Vec<u32>,)*
        }

        impl $columns {
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
            pub fn push(&mut self, r: &$record) {
                $(self.$scalar.push(r.$scalar);)*
                $(self.$joint.extend(&r.$joint);)*
                $(self.$optional.extend(&r.$optional);)*
                $(self.$code.push(Code::code(r.$code));)*
            }
        }
    };
}
cycle_fields!(record_and_columns);
truth_fields!(record_and_columns);

/// A record's fixed-size copy, from a list of fields that names a `snapshot` ([`cycle_fields`]).
macro_rules! snapshot {
    (
        names {
            $(#[$rdoc:meta])* record $record:ident,
            $(#[$cldoc:meta])* columns $columns:ident,
            $(#[$mdoc:meta])* message $message:ident,
            table $table:ident,
            $(#[$fdoc:meta])* snapshot $snapshot:ident,
        }
        scalars { $($(#[$sdoc:meta])* $scalar:ident: $stype:ty as $sproto:ident = $stag:literal,)* }
        joints { $($(#[$jdoc:meta])* $joint:ident = $jtag:literal,)* }
        optional { $($(#[$odoc:meta])* $optional:ident: $width:tt = $otag:literal,)* }
        codes { $($(#[$cdoc:meta])* $code:ident: $ctype:ty = $ctag:literal,)* }
    ) => {
        $(#[$fdoc])*
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct $snapshot<const MAX: usize> {
            /// The joints in use: the first `dof` entries of each joint vector.
            pub dof: usize,
            $($(#[$sdoc])* pub $scalar: $stype,)*
            $($(#[$jdoc])* pub $joint: [f64; MAX],)*
            $($(#[$odoc])* pub $optional: Option<[f64; MAX]>,)*
            $($(#[$cdoc])* pub $code: $ctype,)*
        }

        impl<const MAX: usize> $snapshot<MAX> {
            /// A copy of `r`, its empty optional vectors `None`. Panics when a vector of `r`
            /// is longer than `MAX`.
            pub fn of(r: &$record) -> Self {
                let fixed = |v: &[f64]| {
                    let mut a = [0.0; MAX];
                    a[..v.len()].copy_from_slice(v);
                    a
                };
                Self {
                    dof: [$(r.$joint.len()),*][0],
                    $($scalar: r.$scalar,)*
                    $($joint: fixed(&r.$joint),)*
                    $($optional: (!r.$optional.is_empty()).then(|| fixed(&r.$optional)),)*
                    $($code: r.$code,)*
                }
            }

            /// Fill `r` from this copy, in place once its vectors have room (a record made by
            /// `new(dof)` has).
            pub fn write_into(&self, r: &mut $record) {
                let dof = self.dof;
                $(r.$scalar = self.$scalar;)*
                $(r.$joint.clear(); r.$joint.extend_from_slice(&self.$joint[..dof]);)*
                $(
                    r.$optional.clear();
                    if let Some(v) = &self.$optional {
                        r.$optional.extend_from_slice(&v[..width!(dof, $width)]);
                    }
                )*
                $(r.$code = self.$code;)*
            }
        }
    };
}
cycle_fields!(snapshot);
