//! `arash daemon`: run the rig (see docs/daemon.md).

use std::path::PathBuf;

use arash_daemon::config::DaemonConfig;
use arash_daemon::daemon::{run as run_daemon, DaemonOptions};
use arash_daemon::rt::clock::RtPolicy;

#[derive(clap::Args)]
pub struct Args {
    /// Configuration file (TOML); every key has a default.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Serial port of the motor drives (overrides link.port).
    #[arg(long)]
    port: Option<String>,
    /// Real-time set-up: `require` refuses to start without SCHED_FIFO and mlockall; `ignore`
    /// runs without them and logs that it does.
    #[arg(long)]
    rt: Option<RtPolicy>,
    /// Operator socket (overrides socket.path).
    #[arg(long)]
    socket: Option<PathBuf>,
    /// Log directory (overrides log.dir).
    #[arg(long)]
    log_dir: Option<PathBuf>,
    /// pd, idc or robust (overrides control.controller).
    #[arg(long)]
    controller: Option<String>,
    /// Model file from `arash identify` (overrides control.model).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Stream the rig live to Foxglove (read-only WebSocket) on ADDR, default live.address
    /// (127.0.0.1:8765); sets live.enabled.
    #[arg(long, value_name = "ADDR")]
    live: Option<Option<String>>,
    /// Allow --live on an address other than loopback (sets live.allow_remote).
    #[arg(long)]
    live_allow_remote: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (mut config, text) = match &args.config {
        Some(path) => (DaemonConfig::load(path)?, std::fs::read_to_string(path)?),
        None => (DaemonConfig::default(), String::new()),
    };
    if let Some(p) = args.port {
        config.link.port = p;
    }
    if let Some(rt) = args.rt {
        config.rt.policy = rt;
    }
    if let Some(s) = args.socket {
        config.socket.path = s;
    }
    if let Some(d) = args.log_dir {
        config.log.dir = d;
    }
    if let Some(c) = args.controller {
        config.control.controller = c;
    }
    if let Some(m) = args.model {
        config.control.model = Some(m);
    }
    if let Some(address) = args.live {
        config.live.enabled = true;
        if let Some(address) = address {
            config.live.address = address;
        }
    }
    config.live.allow_remote |= args.live_allow_remote;
    let (model, urdf) = super::load_robot(config.robot.as_deref())?;
    // The effective configuration goes into every log, overrides included.
    let effective =
        format!("# as loaded{}\n{}", if text.is_empty() { " (defaults)" } else { "" }, toml::to_string(&config)?);
    run_daemon(DaemonOptions { config, config_text: effective, model, urdf })
}
