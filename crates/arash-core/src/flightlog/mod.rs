//! The flight log: one MCAP file per run, written by the simulator and the daemon, read by
//! identification and by `arash.read_log`. `docs/flightlog.md` documents the format.
//!
//! - one protobuf message per control cycle on `/arash/cycle` (and, from the simulator, the
//!   ground truth on `/arash/truth`), zstd-compressed chunks;
//! - the robot URDF and the run's configuration as attachments, and an `arash` metadata record
//!   (format, software version, scenario, seed, controller, joint names);
//! - a chunk is closed and flushed to disk every second of log, so a file cut off by a crash reads
//!   back at least up to its last flushed second (and any whole messages after it that reached
//!   the disk).

mod reader;
mod recover;
pub mod schema;
mod uniform;
mod writer;

pub use reader::{read_log, FlightLog};
pub use recover::rewrite_complete;
pub use uniform::{on_uniform_grid, Uniform};
pub use writer::{LogHeader, LogWriter};

/// The value of the `format` metadata key.
pub const FORMAT: &str = "arash-log/1";
pub const CYCLE_TOPIC: &str = "/arash/cycle";
pub const TRUTH_TOPIC: &str = "/arash/truth";
/// The daemon's tracking error over each display window (`arash.TrackingError`), in daemon logs
/// and the live stream.
pub const ERROR_TOPIC: &str = "/arash/error";
/// The daemon's loop timing, once a second (JSON).
pub const TIMING_TOPIC: &str = "/arash/timing";
/// The daemon's events: enables, faults, runs, link errors (JSON).
pub const EVENT_TOPIC: &str = "/arash/event";
/// The robot's URDF as `{"data": "<urdf>"}` (JSON), the shape Foxglove's URDF layer reads from a
/// topic; once at the start of each daemon log, and to every live subscriber.
pub const ROBOT_DESCRIPTION_TOPIC: &str = "/robot_description";
/// Name of the metadata record.
pub const METADATA_NAME: &str = "arash";

/// Why a log could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("{path}: not an MCAP file, or cut off before its first record ({source})")]
    NotMcap { path: String, source: mcap::McapError },
    #[error("{path}: MCAP error: {source}")]
    Mcap { path: String, source: mcap::McapError },
    #[error("{path}: message {index} on {topic} does not decode: {source}")]
    Decode { path: String, topic: String, index: usize, source: prost::DecodeError },
    #[error("{path}: not an arash flight log: {problem}")]
    NotFlightLog { path: String, problem: String },
}
