//! Start-up: the command line and configuration, the robot, the model file and its controller,
//! the motor link and the live stream's socket, each checked before the control thread starts.

use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::Arc;

use anyhow::Context;
use arash_core::control::{controller_with_effects, Controller, ControllerKind, RobustGains};
use arash_core::model_file::ModelFile;
use arash_core::Model;

use crate::config::{DaemonConfig, LinkKind};
use crate::drive_config::TorqueConstants;
use crate::link::MotorLink;
use crate::live::server::LiveServer;
use arash_core::identify::closed_loop::LoggedController;

use super::DaemonOptions;
use crate::rt::clock::RtPolicy;

/// Build a controller of `kind` for `model` with parameters from `model_file` (or CAD). The
/// model-based laws also compensate the effects a diagnosis added to the file. Returns it with
/// its description, which each run's log carries (`controller.json`) so that a closed-loop
/// estimator can simulate the loop.
pub fn build_controller(
    model: &Model,
    kind: ControllerKind,
    model_file: Option<(&std::path::Path, &ModelFile)>,
    gains: Option<&RobustGains>,
) -> anyhow::Result<(Box<dyn Controller>, LoggedController)> {
    let (params, effects) = match model_file {
        None => (model.cad_parameters(), vec![]),
        Some((path, id)) => {
            let params = if kind == ControllerKind::Pd {
                id.controller_parameters(model)
            } else {
                id.consistent_controller_parameters(model)
            };
            let params = params.with_context(|| format!("{} refused for the {kind:?} controller", path.display()))?;
            (params, id.effects.clone())
        }
    };
    let controller = controller_with_effects(kind, model, &params, &effects, gains)?;
    Ok((controller, LoggedController::Standard { kind, params, effects, gains: gains.cloned() }))
}

/// Read a model file named by the configuration or an operator.
pub fn read_model_file(path: &std::path::Path) -> anyhow::Result<ModelFile> {
    let text = read_file(path, MAX_INPUT_FILE_BYTES).context("reading the model file")?;
    ModelFile::from_json(&text).with_context(|| format!("loading {}", path.display()))
}

/// The torque constants the daemon runs with ([`TorqueConstants::choose`]): the start-up model's
/// gains where it has them, else the configuration's. Printed per joint with where it came from.
pub(super) fn torque_constants(
    config: &DaemonConfig,
    model: &Model,
    file: Option<&ModelFile>,
) -> anyhow::Result<TorqueConstants> {
    let gains = file.and_then(|f| f.drive_gains.as_ref());
    let chosen = TorqueConstants::choose(&config.drive, gains, &model.joint_names())
        .with_context(|| format!("control.model {:?}", config.control.model))?;
    for ((name, k), source) in model.joint_names().iter().zip(&chosen.values).zip(&chosen.sources) {
        eprintln!("arash-daemon: {name}: {k:.5} per ampere, {source}");
    }
    Ok(chosen)
}

/// Largest model or trajectory file the daemon reads: a model file embeds its URDF (15 kB for
/// ARASH:ASiST) and an excitation from `arash excite` carries a sampled copy of one period (3 MB
/// for the paper's 15 s at 1 kHz); both are far below this.
pub(super) const MAX_INPUT_FILE_BYTES: usize = 64 << 20;

/// Read a regular file of at most `max` bytes as UTF-8: a device, a FIFO or an oversized file
/// named by an operator must not stall the daemon's operator interface.
pub(super) fn read_file(path: &std::path::Path, max: usize) -> anyhow::Result<String> {
    use std::io::Read;
    let file = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let meta = file.metadata().with_context(|| format!("reading {}", path.display()))?;
    anyhow::ensure!(meta.is_file(), "{} is not a regular file", path.display());
    let mut bytes = Vec::new();
    file.take(max as u64 + 1).read_to_end(&mut bytes).with_context(|| format!("reading {}", path.display()))?;
    anyhow::ensure!(bytes.len() <= max, "{} is larger than {max} bytes", path.display());
    String::from_utf8(bytes).map_err(|_| anyhow::anyhow!("{} is not UTF-8 text", path.display()))
}

pub(super) fn open_link(config: &DaemonConfig, dof: usize) -> anyhow::Result<Box<dyn MotorLink>> {
    match config.link.kind {
        LinkKind::Serial => {
            let port = crate::link::serial::open_port(&config.link.port, config.link.baud)?;
            Ok(Box::new(crate::link::serial::SerialLink::new(port, dof)))
        }
        LinkKind::Can => {
            #[cfg(target_os = "linux")]
            {
                let bus = crate::link::can::SocketCan::open(&config.link.interface)?;
                Ok(Box::new(crate::link::can::CanLink::new(bus, dof)))
            }
            #[cfg(not(target_os = "linux"))]
            anyhow::bail!("link.kind = \"can\" needs Linux SocketCAN")
        }
    }
}

/// Bind the live stream's socket (before the control thread starts, so that a taken port stops
/// the daemon at once) and build its server.
pub(super) fn open_live(
    config: &DaemonConfig,
    urdf: &str,
    scales: &[(f64, &'static str)],
) -> anyhow::Result<(Arc<LiveServer>, std::net::TcpListener)> {
    let addr = config.live.socket_addr()?;
    let listener =
        std::net::TcpListener::bind(addr).with_context(|| format!("binding the live stream to live.address {addr}"))?;
    listener.set_nonblocking(true)?;
    limit_send_buffer(&listener)?;
    let addr = listener.local_addr()?;
    if !addr.ip().is_loopback() {
        eprintln!(
            "arash-daemon: WARNING: the live stream listens on {addr}, not on loopback: anyone who can reach it \
             sees the rig's data (it cannot command the robot)"
        );
    }
    eprintln!("arash-daemon: live stream on ws://{addr} (Foxglove: open connection, Foxglove WebSocket)");
    let units: Vec<&str> = scales.iter().map(|s| s.1).collect();
    let server = LiveServer::new(addr, urdf, &units, config.live.client_queue)?;
    Ok((Arc::new(server), listener))
}

/// Kernel send buffer of each live client's socket (accepted sockets inherit the listener's).
/// About a second of the stream at 100 Hz: without a bound, Linux lets a client that does not
/// read hold megabytes of it, minutes old by the time they arrive, before anything is dropped.
const LIVE_SEND_BUFFER_BYTES: libc::c_int = 64 * 1024;

fn limit_send_buffer(listener: &std::net::TcpListener) -> anyhow::Result<()> {
    use std::os::fd::AsRawFd;
    let size = LIVE_SEND_BUFFER_BYTES;
    // SAFETY: a valid socket descriptor, and a pointer to a c_int with its size, as SO_SNDBUF takes.
    let rc = unsafe {
        libc::setsockopt(
            listener.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_SNDBUF,
            (&size as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    anyhow::ensure!(rc == 0, "setting the live stream's send buffer: {}", std::io::Error::last_os_error());
    Ok(())
}

/// The daemon's command line: `arash-daemon` (what systemd runs) and `arash daemon` take the
/// same arguments. Each overrides its key of the configuration file.
#[derive(clap::Args, Debug, Default)]
pub struct DaemonArgs {
    /// Configuration file (TOML); every key has a default.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Serial port of the motor drives (overrides link.port).
    #[arg(long)]
    pub port: Option<String>,
    /// Real-time set-up: `require` refuses to start without SCHED_FIFO and mlockall; `ignore`
    /// runs without them and logs that it does.
    #[arg(long, value_parser = RtPolicy::from_str)]
    pub rt: Option<RtPolicy>,
    /// Operator socket (overrides socket.path).
    #[arg(long)]
    pub socket: Option<PathBuf>,
    /// Log directory (overrides log.dir).
    #[arg(long)]
    pub log_dir: Option<PathBuf>,
    /// pd, idc or robust (overrides control.controller).
    #[arg(long)]
    pub controller: Option<String>,
    /// Model file from `arash identify` (overrides control.model).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Stream the rig live to Foxglove (read-only WebSocket) on ADDR, default live.address
    /// (127.0.0.1:8765); sets live.enabled.
    #[arg(long, value_name = "ADDR")]
    pub live: Option<Option<String>>,
    /// Allow --live on an address other than loopback (sets live.allow_remote).
    #[arg(long)]
    pub live_allow_remote: bool,
}

/// The configuration file with the command line's overrides, the robot it names, and the
/// effective configuration as every log records it.
pub fn options(args: DaemonArgs) -> anyhow::Result<DaemonOptions> {
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
    let (model, urdf) = load_robot(config.robot.as_deref())?;
    // The effective configuration goes into every log, overrides included.
    let config_text =
        format!("# as loaded{}\n{}", if text.is_empty() { " (defaults)" } else { "" }, toml::to_string(&config)?);
    Ok(DaemonOptions { config, config_text, model, urdf })
}

/// Load a robot model and keep its URDF text (model files and logs embed it). `None` is the
/// ARASH:ASiST description built into the binary. The URDF's warnings go to stderr.
pub fn load_robot(path: Option<&Path>) -> anyhow::Result<(Model, String)> {
    let Some(path) = path else {
        return Ok((arash_core::arash_asist(), arash_core::ARASH_ASIST_URDF.to_string()));
    };
    let text = std::fs::read_to_string(path).with_context(|| format!("reading URDF {}", path.display()))?;
    let model = arash_core::parse_urdf(&text).with_context(|| format!("loading {}", path.display()))?;
    for warning in &model.warnings {
        eprintln!("warning: {}: {warning}", path.display());
    }
    Ok((model, text))
}
