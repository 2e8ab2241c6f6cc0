//! The live stream: a read-only Foxglove WebSocket server on the daemon's non-real-time side
//! (see docs/daemon.md, "Watching the rig live").
//!
//! - [`window`]: the display window, which thins the cycles to the display rate and keeps the
//!   extremes of the tracking error in between; the logger writes its output to every daemon log
//!   and hands it to the stream, so that one Foxglove layout opens both;
//! - [`scene`]: the 3D panel's links and the hand's force arrow at the displayed cycle;
//! - [`server`]: the server. The logger thread publishes into per-client bounded queues and
//!   never waits; a client that does not read loses messages, which are counted.
//!
//! Off by default, on loopback by default; another address needs `live.allow_remote`.

pub mod scene;
pub mod server;
pub mod window;

use std::net::SocketAddr;

/// The `[live]` table.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LiveConfig {
    /// Serve the stream (`arash daemon --live`).
    pub enabled: bool,
    /// Address and port to listen on.
    pub address: String,
    /// Allow an address other than loopback: anyone who can reach it sees the rig's data.
    pub allow_remote: bool,
    /// Display rate (Hz): cycles are streamed at this rate, with the tracking error's extremes
    /// over each window; daemon logs carry the same windows on `/arash/error`. Above the
    /// control rate, every cycle is a window.
    pub rate_hz: f64,
    /// Messages queued per client before its newest are dropped (and counted).
    pub client_queue: usize,
}

/// Where `--live` listens when given no address.
pub const DEFAULT_ADDRESS: &str = "127.0.0.1:8765";

impl Default for LiveConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            address: DEFAULT_ADDRESS.into(),
            allow_remote: false,
            rate_hz: 100.0,
            client_queue: 1024,
        }
    }
}

/// Why a `[live]` table cannot be served; each names the key.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum LiveConfigError {
    #[error("live.address must be an IP address and port, like \"{DEFAULT_ADDRESS}\", not {0:?}")]
    Address(String),
    #[error(
        "live.address {0} is not a loopback address: the stream would be visible to anyone who can reach it; \
         set live.allow_remote = true (or pass --live-allow-remote) to allow it"
    )]
    Remote(SocketAddr),
    #[error("live.rate_hz must be positive and finite, not {0}")]
    Rate(f64),
    #[error("live.client_queue must be at least 16 messages, not {0}")]
    Queue(usize),
}

impl LiveConfig {
    /// The listening address, checked against `allow_remote`.
    pub fn socket_addr(&self) -> Result<SocketAddr, LiveConfigError> {
        let addr: SocketAddr = self.address.parse().map_err(|_| LiveConfigError::Address(self.address.clone()))?;
        if !addr.ip().is_loopback() && !self.allow_remote {
            return Err(LiveConfigError::Remote(addr));
        }
        Ok(addr)
    }

    /// Checks every key, whether or not the stream is on: the display rate also sets the log's
    /// `/arash/error` windows.
    pub fn validate(&self) -> Result<(), LiveConfigError> {
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return Err(LiveConfigError::Rate(self.rate_hz));
        }
        if self.client_queue < 16 {
            return Err(LiveConfigError::Queue(self.client_queue));
        }
        self.socket_addr().map(|_| ())
    }

    /// Cycles per display window at `control_rate_hz`.
    pub fn window_cycles(&self, control_rate_hz: f64) -> u32 {
        (control_rate_hz / self.rate_hz).round().max(1.0) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_is_the_default_and_another_address_needs_the_flag() {
        let mut c = LiveConfig::default();
        assert!(c.socket_addr().unwrap().ip().is_loopback());
        c.address = "0.0.0.0:8765".into();
        assert_eq!(c.validate(), Err(LiveConfigError::Remote("0.0.0.0:8765".parse().unwrap())));
        c.allow_remote = true;
        c.validate().unwrap();
        c.address = "[::1]:9000".into();
        c.allow_remote = false;
        c.validate().unwrap();
    }

    #[test]
    fn bad_values_are_named() {
        let c = LiveConfig { address: "localhost".into(), ..Default::default() };
        assert!(c.validate().unwrap_err().to_string().contains("live.address"));
        let c = LiveConfig { rate_hz: 0.0, ..Default::default() };
        assert!(c.validate().unwrap_err().to_string().contains("live.rate_hz"));
        let c = LiveConfig { client_queue: 1, ..Default::default() };
        assert!(c.validate().unwrap_err().to_string().contains("live.client_queue"));
    }

    #[test]
    fn the_window_spans_the_control_cycles_of_one_display_sample() {
        let c = LiveConfig::default();
        assert_eq!(c.window_cycles(1000.0), 10);
        assert_eq!(c.window_cycles(250.0), 3);
        assert_eq!(LiveConfig { rate_hz: 1000.0, ..c.clone() }.window_cycles(1000.0), 1);
        assert_eq!(LiveConfig { rate_hz: 100.0, ..c }.window_cycles(50.0), 1);
    }
}
