//! Start-up: the command line and configuration, the robot, the model file and its controller,
//! the motor link and the live stream's socket, each checked before the control thread starts.

use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::Arc;

use arash_core::control::{controller_with_effects, Controller, ControllerError, ControllerKind, RobustGains};
use arash_core::model_file::{DriveGains, ModelFile, ModelFileError};
use arash_core::urdf::UrdfError;
use arash_core::Model;

use crate::config::{ConfigError, DaemonConfig, LinkKind};
use crate::drive_config::{DriveConfigError, TorqueConstants};
use crate::link::MotorLink;
use crate::live::server::LiveServer;
use crate::live::LiveConfigError;
use arash_core::control::logged::LoggedController;

use super::DaemonOptions;
use crate::rt::clock::{Pace, RtPolicy};

/// Why the daemon cannot start. Each names the file, setting or device concerned, and the daemon
/// has enabled nothing when it says so. The cause, where there is one, is the error's `source`:
/// the binaries print the chain on one line, as the control socket's answers do. (The operator's requests reuse the file and controller
/// cases: a model file named at run time is read and checked alike.)
#[derive(Debug, thiserror::Error)]
pub enum StartupError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error("invalid configuration")]
    Live(#[from] LiveConfigError),
    #[error("opening {path}")]
    Open { path: PathBuf, source: std::io::Error },
    #[error("{0} is not a regular file")]
    NotAFile(PathBuf),
    #[error("{path} is larger than {max} bytes")]
    TooLarge { path: PathBuf, max: usize },
    #[error("{0} is not UTF-8 text")]
    NotUtf8(PathBuf),
    #[error("loading {path}")]
    ModelFile { path: PathBuf, source: ModelFileError },
    #[error("{path} refused for the {kind:?} controller")]
    Refused { path: PathBuf, kind: ControllerKind, source: ModelFileError },
    #[error(transparent)]
    Controller(#[from] ControllerError),
    #[error("control.model {model:?}")]
    TorqueConstants { model: Option<PathBuf>, source: DriveConfigError },
    #[error("the motor link: {0}")]
    Link(std::io::Error),
    #[error("link.kind = \"can\" needs Linux SocketCAN")]
    NoSocketCan,
    #[error("the CANopen drives: {0}")]
    Drives(#[from] crate::link::drive_setup::StartupError),
    #[error("binding the live stream to live.address {address}")]
    LiveBind { address: std::net::SocketAddr, source: std::io::Error },
    #[error("the live stream's socket: {0}")]
    LiveSocket(std::io::Error),
    #[error("the live stream: {0}")]
    LiveServer(String),
    #[error("reading URDF {path}")]
    ReadRobot { path: PathBuf, source: std::io::Error },
    #[error("loading {path}")]
    Robot { path: PathBuf, source: UrdfError },
    #[error("writing the effective configuration: {0}")]
    Effective(String),
    /// A model file the helper process refused, with its message (the causes included), or the
    /// helper itself failing.
    #[error("{0}")]
    ModelHelper(String),
}

/// What the daemon takes from a model file, as the model helper resolved it
/// ([`super::model_helper`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ResolvedModel {
    /// The standard parameters the controller uses: the file's own for PD; for a law that
    /// inverts M(q), ones checked physically consistent.
    pub params: Vec<f64>,
    /// The effects a diagnosis added, which the model-based laws compensate.
    pub effects: Vec<arash_core::effects::EffectTerm>,
    pub drive_gains: Option<DriveGains>,
    /// The file's residual on held-out data and its force observer's run there.
    #[serde(default)]
    pub held_out: Option<arash_core::model_file::HeldOut>,
}

/// Build a controller of `kind` for `model` with the parameters a model file resolved to (or
/// CAD). The model-based laws also compensate the effects a diagnosis added to the file.
/// Returns it with its description, which each run's log carries (`controller.json`) so that a
/// closed-loop estimator can simulate the loop.
pub fn build_controller(
    model: &Model,
    kind: ControllerKind,
    resolved: Option<&ResolvedModel>,
    gains: Option<&RobustGains>,
) -> Result<(Box<dyn Controller>, LoggedController), StartupError> {
    let (params, effects) = match resolved {
        None => (model.cad_parameters(), vec![]),
        Some(r) => (r.params.clone(), r.effects.clone()),
    };
    let controller = controller_with_effects(kind, model, &params, &effects, gains)?;
    Ok((controller, LoggedController::Standard { kind, params, effects, gains: gains.cloned() }))
}

/// Read a model file named by the configuration or an operator (in the model helper, or a tool).
pub fn read_model_file(path: &Path) -> Result<ModelFile, StartupError> {
    let text = read_file(path, MAX_INPUT_FILE_BYTES)?;
    ModelFile::from_json(&text).map_err(|source| StartupError::ModelFile { path: path.into(), source })
}

/// The torque constants the daemon runs with ([`TorqueConstants::choose`]): the start-up model's
/// gains where it has them, else the configuration's. Printed per joint with where it came from.
pub(super) fn torque_constants(
    config: &DaemonConfig,
    model: &Model,
    gains: Option<&DriveGains>,
) -> Result<TorqueConstants, StartupError> {
    let chosen = TorqueConstants::choose(&config.drive, gains, &model.joint_names())
        .map_err(|source| StartupError::TorqueConstants { model: config.control.model.clone(), source })?;
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
pub(super) fn read_file(path: &Path, max: usize) -> Result<String, StartupError> {
    use std::io::Read;
    let open = |source| StartupError::Open { path: path.into(), source };
    let file = std::fs::File::open(path).map_err(open)?;
    if !file.metadata().map_err(open)?.is_file() {
        return Err(StartupError::NotAFile(path.into()));
    }
    let mut bytes = Vec::new();
    file.take(max as u64 + 1).read_to_end(&mut bytes).map_err(open)?;
    if bytes.len() > max {
        return Err(StartupError::TooLarge { path: path.into(), max });
    }
    String::from_utf8(bytes).map_err(|_| StartupError::NotUtf8(path.into()))
}

pub(super) fn open_link(config: &DaemonConfig, dof: usize) -> Result<Box<dyn MotorLink>, StartupError> {
    match config.link.kind {
        LinkKind::Serial => {
            let port =
                crate::link::serial::open_port(&config.link.port, config.link.baud).map_err(StartupError::Link)?;
            Ok(Box::new(crate::link::serial::SerialLink::on_port(port, dof)))
        }
        LinkKind::Can => {
            #[cfg(target_os = "linux")]
            {
                let bus = crate::link::can::SocketCan::open(&config.link.interface).map_err(StartupError::Link)?;
                Ok(Box::new(crate::link::can::CanLink::new(bus, dof)))
            }
            #[cfg(not(target_os = "linux"))]
            Err(StartupError::NoSocketCan)
        }
        LinkKind::Canopen => open_canopen(config),
    }
}

/// The CiA 402 master on the transport `[canopen]` names, with its drives configured.
fn open_canopen(config: &DaemonConfig) -> Result<Box<dyn MotorLink>, StartupError> {
    use crate::link::master::Transport;
    use crate::link::slcan::SlcanBus;
    let c = &config.canopen;
    match c.transport {
        Transport::Slcan => {
            let port =
                crate::link::serial::open_port(&config.link.port, config.link.baud).map_err(StartupError::Link)?;
            let bus = SlcanBus::on_port(port, c.bit_rate).map_err(StartupError::Link)?;
            if !bus.health().reports_status {
                eprintln!(
                    "arash-daemon: WARNING: the slcan adapter on {} does not report its status flags (`F`): an error \
                     passive or bus-off adapter is seen only when it refuses frames",
                    config.link.port
                );
            }
            start_drives(bus, config)
        }
        #[cfg(target_os = "linux")]
        Transport::Socketcan => {
            let bus = crate::link::can::SocketCan::open(&config.link.interface).map_err(StartupError::Link)?;
            start_drives(bus, config)
        }
        #[cfg(not(target_os = "linux"))]
        Transport::Socketcan => Err(StartupError::NoSocketCan),
    }
}

/// The master over `bus`, its drives disabled at once; the rest of their start-up runs on the
/// control thread ([`MotorLink::start`]).
fn start_drives<B: crate::link::can::CanBus + 'static>(
    bus: B,
    config: &DaemonConfig,
) -> Result<Box<dyn MotorLink>, StartupError> {
    let period = std::time::Duration::from_secs_f64(1.0 / config.control.rate_hz);
    Ok(Box::new(crate::link::master::CanopenLink::open(bus, &config.canopen, period)?))
}

/// Bind the live stream's socket (before the control thread starts, so that a taken port stops
/// the daemon at once) and build its server, which draws the hand's force at `force_frame` (the
/// observer's, as resolved).
pub(super) fn open_live(
    config: &DaemonConfig,
    urdf: &str,
    scales: &[(f64, &'static str)],
    force_frame: Option<&str>,
) -> Result<(Arc<LiveServer>, std::net::TcpListener), StartupError> {
    let addr = config.live.socket_addr()?;
    let listener =
        std::net::TcpListener::bind(addr).map_err(|source| StartupError::LiveBind { address: addr, source })?;
    listener.set_nonblocking(true).map_err(StartupError::LiveSocket)?;
    limit_send_buffer(&listener).map_err(StartupError::LiveSocket)?;
    let addr = listener.local_addr().map_err(StartupError::LiveSocket)?;
    if !addr.ip().is_loopback() {
        eprintln!(
            "arash-daemon: WARNING: the live stream listens on {addr}, not on loopback: anyone who can reach it \
             sees the rig's data (it cannot command the robot)"
        );
    }
    eprintln!("arash-daemon: live stream on ws://{addr} (Foxglove: open connection, Foxglove WebSocket)");
    let units: Vec<&str> = scales.iter().map(|s| s.1).collect();
    let server = LiveServer::new(addr, urdf, &units, config.live.client_queue, force_frame)
        .map_err(|e| StartupError::LiveServer(format!("{e:#}")))?;
    Ok((Arc::new(server), listener))
}

/// Kernel send buffer of each live client's socket (accepted sockets inherit the listener's).
/// About a second of the stream at 100 Hz: without a bound, Linux lets a client that does not
/// read hold megabytes of it, minutes old by the time they arrive, before anything is dropped.
const LIVE_SEND_BUFFER_BYTES: libc::c_int = 64 * 1024;

fn limit_send_buffer(listener: &std::net::TcpListener) -> std::io::Result<()> {
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
    match rc {
        0 => Ok(()),
        _ => Err(std::io::Error::other(format!("setting its send buffer: {}", std::io::Error::last_os_error()))),
    }
}

/// The daemon's command line: `arash-daemon` (what systemd runs) and `arash daemon` take the
/// same arguments. Each overrides its key of the configuration file.
#[derive(clap::Args, Debug, Default)]
pub struct DaemonArgs {
    /// Configuration file (TOML); every key has a default.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Serial port of the motor drives, or of the slcan adapter (overrides link.port).
    #[arg(long)]
    pub port: Option<String>,
    /// The motor link: serial, can or canopen (overrides link.kind).
    #[arg(long, value_enum)]
    pub link: Option<LinkKind>,
    /// Real-time set-up: `require` refuses to start without SCHED_FIFO and mlockall; `ignore`
    /// runs without them and logs that it does.
    #[arg(long, value_parser = RtPolicy::from_str)]
    pub rt: Option<RtPolicy>,
    /// `deadline` (the rig), or `lockstep` for a simulated rig: each cycle as soon as the link
    /// answers the last, as fast as the host goes (overrides rt.pace; needs --rt ignore).
    #[arg(long, value_parser = Pace::from_str)]
    pub pace: Option<Pace>,
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
pub fn options(args: DaemonArgs) -> Result<DaemonOptions, StartupError> {
    let (mut config, text) = match &args.config {
        Some(path) => {
            let config = DaemonConfig::load(path)?;
            let text =
                std::fs::read_to_string(path).map_err(|source| StartupError::Open { path: path.clone(), source })?;
            (config, text)
        }
        None => (DaemonConfig::default(), String::new()),
    };
    if let Some(p) = args.port {
        config.link.port = p;
    }
    if let Some(kind) = args.link {
        config.link.kind = kind;
    }
    if let Some(rt) = args.rt {
        config.rt.policy = rt;
    }
    if let Some(pace) = args.pace {
        config.rt.pace = pace;
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
    let effective = toml::to_string(&config).map_err(|e| StartupError::Effective(e.to_string()))?;
    let config_text = format!("# as loaded{}\n{effective}", if text.is_empty() { " (defaults)" } else { "" });
    Ok(DaemonOptions { config, config_text, model, urdf })
}

/// Load a robot model and keep its URDF text (model files and logs embed it). `None` is the
/// ARASH:ASiST description built into the binary. The URDF's warnings go to stderr.
pub fn load_robot(path: Option<&Path>) -> Result<(Model, String), StartupError> {
    let Some(path) = path else {
        return Ok((arash_core::arash_asist(), arash_core::ARASH_ASIST_URDF.to_string()));
    };
    let text = std::fs::read_to_string(path).map_err(|source| StartupError::ReadRobot { path: path.into(), source })?;
    let model = arash_core::parse_urdf(&text).map_err(|source| StartupError::Robot { path: path.into(), source })?;
    for warning in &model.warnings {
        eprintln!("warning: {}: {warning}", path.display());
    }
    Ok((model, text))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("arash-startup-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_file_the_daemon_must_not_read_is_refused_by_name() {
        let dir = scratch("files");
        let named = |e: StartupError, what: &str| {
            let text = format!("{:#}", anyhow::Error::from(e));
            assert!(text.contains(&dir.display().to_string()) && text.contains(what), "{text}");
        };
        named(read_file(&dir, 100).unwrap_err(), "is not a regular file");
        named(read_file(&dir.join("missing.json"), 100).unwrap_err(), "missing.json: No such file");
        let big = dir.join("big.json");
        std::fs::write(&big, vec![b'x'; 101]).unwrap();
        assert!(matches!(read_file(&big, 100), Err(StartupError::TooLarge { max: 100, .. })));
        let binary = dir.join("binary.json");
        std::fs::write(&binary, [0xff, 0xfe]).unwrap();
        assert!(matches!(read_file(&binary, 100), Err(StartupError::NotUtf8(_))));
        std::fs::write(dir.join("model.json"), "{").unwrap();
        assert!(matches!(read_model_file(&dir.join("model.json")), Err(StartupError::ModelFile { .. })));
        std::fs::write(dir.join("robot.urdf"), "<robot>").unwrap();
        assert!(matches!(load_robot(Some(&dir.join("robot.urdf"))), Err(StartupError::Robot { .. })));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_bad_override_is_refused_before_anything_opens() {
        let dir = scratch("override");
        let config = dir.join("daemon.toml");
        std::fs::write(&config, "[link]\nbogus = 1\n").unwrap();
        let args = DaemonArgs { config: Some(config), ..Default::default() };
        let e = options(args).err().expect("an unknown key is refused");
        assert!(matches!(e, StartupError::Config(_)) && e.to_string().contains("bogus"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
