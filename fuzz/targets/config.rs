//! Any text as the daemon's configuration file: parsed, validated and turned into the cycle's
//! settings without a panic; whatever validates gives a cycle configuration.

use arash_daemon::config::DaemonConfig;

use crate::robot::model;

pub fn check(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(config) = DaemonConfig::parse(text) else { return };
    if config.validate(model()).is_ok() {
        let cycle = config.cycle_config(model()).expect("a validated configuration gives a cycle configuration");
        assert!(cycle.dt.is_finite() && cycle.dt > 0.0);
        let _ = config.controller();
    }
}
