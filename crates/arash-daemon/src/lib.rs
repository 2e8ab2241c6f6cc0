//! The ARASH:ASiST rig: everything the daemon runs, and nothing else. The `arash` binary's
//! command-line front (`src/cli/`) and its reports and figures (`src/report/`) sit beside this
//! library, in the binary, so that the rig's code path carries no plotting.
//!
//! - [`link`]: the motor link (serial protocol and CAN) behind one trait;
//! - [`drive_config`]: drive units (counts, amperes) to joint units;
//! - [`mock`]: the mock motor, the simulated plant behind the protocol;
//! - [`rt`]: the control cycle and the real-time loop;
//! - [`live`]: the live stream (a read-only Foxglove WebSocket server);
//! - [`logger`]: the logger thread (segments, rotation, crash recovery, black box, timing);
//! - [`daemon`]: the daemon itself (link, loop, logger and control socket together);
//! - [`ctl`]: the control socket's client;
//! - [`config`]: the daemon's configuration file.

pub mod config;
pub mod ctl;
pub mod daemon;
pub mod drive_config;
pub mod link;
pub mod live;
pub mod logger;
pub mod mock;
pub mod rt;
