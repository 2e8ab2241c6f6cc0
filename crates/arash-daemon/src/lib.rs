//! The ARASH:ASiST rig daemon and the `arash` command-line tool.
//!
//! - [`link`]: the motor link (serial protocol and CAN) behind one trait;

pub mod link;
