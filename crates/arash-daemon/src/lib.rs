//! The ARASH:ASiST rig daemon and the `arash` command-line tool.
//!
//! - [`link`]: the motor link (serial protocol and CAN) behind one trait;
//! - [`drive_config`]: drive units (counts, amperes) to joint units;
//! - [`mock`]: the mock motor, the simulated plant behind the protocol;
//! - [`rt`]: the control cycle and the real-time loop;
//! - [`logger`]: the logger thread (segments, rotation, crash recovery, black box, timing);

pub mod config;
pub mod ctl;
pub mod daemon;
pub mod drive_config;
pub mod figures;
pub mod link;
pub mod logger;
pub mod mock;
pub mod rt;
