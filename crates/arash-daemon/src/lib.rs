//! The ARASH:ASiST rig: everything the daemon runs, and nothing else. Its binary, `arash-daemon`,
//! is what systemd runs. The `arash` command-line tool (crates/arash-cli) uses this library for
//! `arash daemon` and `ctl`; its reports and figures live there, so that the rig's dependency
//! tree carries no plotting. It links arash-core without its identification and simulation
//! (no SDP, optimiser, statistics, FFT or simulated plant): the mock motor behind `arash
//! mock-motor` is crates/arash-mock, which the tests link.
//!
//! - [`link`]: the motor link (serial protocol and CAN) behind one trait;
//! - [`drive_config`]: drive units (counts, amperes) to joint units;
//! - [`rt`]: the control cycle and the real-time loop;
//! - [`live`]: the live stream (a read-only Foxglove WebSocket server);
//! - [`logger`]: the logger thread (segments, rotation, crash recovery, black box, timing);
//! - [`daemon`]: the daemon itself (link, loop, logger and control socket together);
//! - [`ctl`]: the control socket's client;
//! - [`config`]: the daemon's configuration file;
//! - [`exit`]: how the binaries report errors and panics.

pub mod config;
pub mod ctl;
pub mod daemon;
pub mod drive_config;
pub mod exit;
pub mod link;
pub mod live;
pub mod logger;
pub mod rt;
