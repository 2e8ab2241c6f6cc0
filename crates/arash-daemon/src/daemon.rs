//! The daemon: wires the motor link, the control thread, the logger thread and the operator
//! interface together, and speaks to systemd.
//!
//! Threads: the control thread (real-time, [`crate::rt::runner`]); the logger thread; and the
//! main thread running a single-threaded tokio runtime for the Unix socket, housekeeping
//! (dropping what the control thread hands back), signals and the systemd notifications. tokio
//! never touches the control cycle.

use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use arash_core::control::{
    controller_with_effects, Controller, ControllerKind, Faults, PlanLimits, RobustGains, Trajectory,
};
use arash_core::model_file::{DriveGains, ModelFile};
use arash_core::record::Mode;
use arash_core::Model;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::UnixListener;

use crate::config::{DaemonConfig, LinkKind};
use crate::ctl::CtlRequest;
use crate::drive_config::TorqueConstants;
use crate::link::MotorLink;
use crate::live::server::LiveServer;
use crate::live::window::display_scales;
use crate::logger::{LogContext, Logger, RunInfo, RunRegistry};
use arash_core::identify::closed_loop::LoggedController;

use crate::rt::clock::setup_realtime;
use crate::rt::cycle::{ControlCycle, Garbage, Request};
use crate::rt::reference::RunRequest;
use crate::rt::runner::{self, Queues, Shared};

/// Everything the daemon needs, resolved from the configuration and the command line.
pub struct DaemonOptions {
    pub config: DaemonConfig,
    pub config_text: String,
    pub model: Model,
    pub urdf: String,
}

/// The operator side's handles.
struct Operator {
    model: Model,
    /// The robust gains; `None` for a robot the paper's gains do not fit (PD only).
    gains: Option<RobustGains>,
    /// The request queue and the number of requests pushed into it so far.
    requests: Mutex<(rtrb::Producer<Request>, u64)>,
    shared: Arc<Shared>,
    runs: RunRegistry,
    /// The live stream, when it is on.
    live: Option<Arc<LiveServer>>,
    next_run: Mutex<u32>,
    /// The controller last sent to the cycle, as each run's log describes it.
    controller: Mutex<LoggedController>,
    /// What a trajectory may ask of the joints, checked before a run is queued.
    plan_limits: PlanLimits,
    /// Control period (s): the spacing at which a trajectory is checked.
    dt: f64,
    /// The configured drive, and the torque constants the cycle runs with (fixed at start-up).
    drive: crate::drive_config::DriveConfig,
    torque_constant: TorqueConstants,
}

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
fn torque_constants(config: &DaemonConfig, model: &Model, file: Option<&ModelFile>) -> anyhow::Result<TorqueConstants> {
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
const MAX_INPUT_FILE_BYTES: usize = 64 << 20;

/// Read a regular file of at most `max` bytes as UTF-8: a device, a FIFO or an oversized file
/// named by an operator must not stall the daemon's operator interface.
fn read_file(path: &std::path::Path, max: usize) -> anyhow::Result<String> {
    use std::io::Read;
    let file = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let meta = file.metadata().with_context(|| format!("reading {}", path.display()))?;
    anyhow::ensure!(meta.is_file(), "{} is not a regular file", path.display());
    let mut bytes = Vec::new();
    file.take(max as u64 + 1).read_to_end(&mut bytes).with_context(|| format!("reading {}", path.display()))?;
    anyhow::ensure!(bytes.len() <= max, "{} is larger than {max} bytes", path.display());
    String::from_utf8(bytes).map_err(|_| anyhow::anyhow!("{} is not UTF-8 text", path.display()))
}

fn open_link(config: &DaemonConfig, dof: usize) -> anyhow::Result<Box<dyn MotorLink>> {
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
fn open_live(
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

/// Run the daemon until SIGTERM or SIGINT.
pub fn run(options: DaemonOptions) -> anyhow::Result<()> {
    let DaemonOptions { config, config_text, model, urdf } = options;
    config.validate(&model).context("invalid configuration")?;
    crate::rt::memory::one_malloc_arena();
    let dof = model.dof();
    // First of all, before anything slow: a drive left powered by a crashed daemon keeps applying
    // its last current until told otherwise. The control cycle goes on sending DISABLE until an
    // operator enables.
    let mut link = open_link(&config, dof)?;
    let _ = link.send(&crate::link::Command::Disable);

    for (path, cycles) in crate::logger::recover(&config.log.dir) {
        match cycles {
            Ok(n) => eprintln!(
                "arash-daemon: found an unfinished log from a crash; kept as {} ({n} cycles readable)",
                path.display()
            ),
            Err(e) => eprintln!("arash-daemon: found an unfinished log {} that does not read: {e}", path.display()),
        }
    }

    let units = config.control.gain_units.parse().map_err(anyhow::Error::msg)?;
    let gains = RobustGains::from_paper(&model, units).ok();
    let kind = config.controller()?;
    let start_model = config.control.model.as_deref().map(|p| read_model_file(p).map(|f| (p, f))).transpose()?;
    let (controller, logged_controller) =
        build_controller(&model, kind, start_model.as_ref().map(|(p, f)| (*p, f)), gains.as_ref())?;
    let torque_constant = torque_constants(&config, &model, start_model.as_ref().map(|(_, f)| f))?;
    let mut cycle_config = config.cycle_config(&model)?;
    cycle_config.drive.torque_constant.clone_from(&torque_constant.values);
    let cycle = ControlCycle::new(cycle_config, controller);

    let (request_tx, request_rx) = rtrb::RingBuffer::new(64);
    let (garbage_tx, mut garbage_rx) = rtrb::RingBuffer::new(64);
    let (log_tx, log_rx) = rtrb::RingBuffer::new(config.log.queue);
    let shared = Arc::new(Shared::default());
    let runs: RunRegistry = Arc::default();

    let mut metadata = std::collections::BTreeMap::new();
    metadata.insert("controller_at_start".into(), config.control.controller.clone());
    metadata.insert("rate_hz".into(), config.control.rate_hz.to_string());
    // What turns the logged torques back into the drive's currents (`arash identify --loaded`).
    metadata.insert("torque_constant".into(), serde_json::to_string(&torque_constant.values)?);
    metadata.insert("torque_constant_source".into(), serde_json::to_string(&torque_constant.sources)?);
    let scales = display_scales(&model);
    let live = match config.live.enabled {
        true => Some(open_live(&config, &urdf, &scales)?),
        false => None,
    };
    let context = LogContext {
        urdf,
        joint_names: model.joint_names(),
        config_toml: config_text,
        metadata,
        rate_hz: config.control.rate_hz,
        window_cycles: config.live.window_cycles(config.control.rate_hz),
        error_scales: scales.iter().map(|s| s.0).collect(),
    };
    let mut logger = Logger::new(config.log.clone(), context, runs.clone(), shared.clone())?;
    if let Some((server, _)) = &live {
        logger = logger.with_live(server.clone());
    }
    let logger_shared = shared.clone();
    let logger_thread = std::thread::Builder::new()
        .name("arash-logger".into())
        .stack_size(crate::rt::memory::LOGGER_STACK_BYTES)
        .spawn(move || {
            let result = logger.run(log_rx);
            if let Err(e) = &result {
                // The control loop goes on (stopping it could drop the robot); the operator sees this
                // here, in `ctl status`, and in the growing log_dropped count.
                eprintln!("arash-daemon: ERROR: logging stopped: {e:#}");
                logger_shared.logging_failed.store(true, Ordering::Release);
            }
            result
        })?;

    let (rt_tx, rt_rx) = std::sync::mpsc::channel();
    let rt_shared = shared.clone();
    let (priority, policy) = (config.rt.priority, config.rt.policy);
    let period = Duration::from_secs_f64(1.0 / config.control.rate_hz);
    let control_thread = std::thread::Builder::new()
        .name("arash-control".into())
        .stack_size(crate::rt::memory::CONTROL_STACK_BYTES)
        .spawn(move || {
            match setup_realtime(priority, policy) {
                Ok(status) => {
                    let _ = rt_tx.send(Ok(status));
                }
                Err(e) => {
                    let _ = rt_tx.send(Err(e));
                    return;
                }
            }
            let queues = Queues { requests: request_rx, garbage: garbage_tx, log: log_tx };
            runner::run(cycle, link.as_mut(), queues, &rt_shared, period);
        })?;
    let rt_status = rt_rx.recv().context("the control thread died during set-up")?;
    let rt_status = match rt_status {
        Ok(s) => s,
        Err(e) => {
            let _ = control_thread.join();
            let _ = logger_thread.join();
            anyhow::bail!(e);
        }
    };
    if rt_status.problems.is_empty() {
        eprintln!("arash-daemon: control thread at SCHED_FIFO priority {priority}, memory locked");
    } else {
        eprintln!(
            "arash-daemon: WARNING --rt=ignore: running without full real-time set-up ({})",
            rt_status.problems.join("; ")
        );
    }
    if policy == crate::rt::clock::RtPolicy::Ignore {
        eprintln!("arash-daemon: --rt=ignore in effect: a refused real-time set-up would not stop the daemon");
    }

    let operator = Arc::new(Operator {
        plan_limits: PlanLimits::from_model(&model),
        dt: 1.0 / config.control.rate_hz,
        model,
        gains,
        requests: Mutex::new((request_tx, 0)),
        shared: shared.clone(),
        runs,
        live: live.as_ref().map(|(server, _)| server.clone()),
        next_run: Mutex::new(0),
        controller: Mutex::new(logged_controller),
        drive: config.drive.clone(),
        torque_constant,
    });
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
    let served = runtime.block_on(async {
        if let Some((server, listener)) = live {
            let listener = tokio::net::TcpListener::from_std(listener).context("the live stream's socket")?;
            tokio::spawn(server.serve(listener));
        }
        serve(&config, operator, &mut garbage_rx, rt_status.problems.is_empty()).await
    });
    shared.stop.store(true, Ordering::Release);
    let _ = control_thread.join();
    drop(garbage_rx);
    let summary = logger_thread.join().map_err(|_| anyhow::anyhow!("the logger thread panicked"))??;
    eprintln!("arash-daemon: stopped; timing {}", serde_json::to_string(&summary)?);
    let _ = sd_notify::notify(&[sd_notify::NotifyState::Stopping]);
    served
}

/// The tokio side: socket, housekeeping, signals, systemd.
async fn serve(
    config: &DaemonConfig,
    operator: Arc<Operator>,
    garbage: &mut rtrb::Consumer<Garbage>,
    realtime: bool,
) -> anyhow::Result<()> {
    let socket = &config.socket.path;
    if let Some(dir) = socket.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    if std::os::unix::net::UnixStream::connect(socket).is_ok() {
        anyhow::bail!("another daemon is already listening on {}", socket.display());
    }
    let _ = std::fs::remove_file(socket); // left by a crash
    let listener = UnixListener::bind(socket).with_context(|| format!("binding {}", socket.display()))?;
    let mode = config.socket.mode_bits().expect("validated");
    std::fs::set_permissions(socket, std::os::unix::fs::PermissionsExt::from_mode(mode))?;
    eprintln!("arash-daemon: listening on {} (mode {:o}); motors disabled", socket.display(), mode);

    let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())?;
    let mut interrupt = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::interrupt())?;
    let mut tick = tokio::time::interval(Duration::from_millis(10));
    let started = Instant::now();
    let startup_timeout = Duration::from_secs_f64(config.link.startup_timeout_ms / 1000.0);
    let watchdog = sd_notify::watchdog_enabled();
    let mut ready = false;
    let mut last_beat = (0u64, Instant::now());
    let result = loop {
        tokio::select! {
            _ = term.recv() => { eprintln!("arash-daemon: SIGTERM, stopping"); break Ok(()) }
            _ = interrupt.recv() => { eprintln!("arash-daemon: SIGINT, stopping"); break Ok(()) }
            accepted = listener.accept() => {
                if let Ok((stream, _)) = accepted {
                    tokio::spawn(client(stream, operator.clone()));
                }
            }
            _ = tick.tick() => {
                while let Ok(g) = garbage.pop() { drop(g); }
                let shared = &operator.shared;
                if !shared.running.load(Ordering::Acquire) && ready {
                    break Err(anyhow::anyhow!("the control thread stopped"));
                }
                if !ready {
                    if shared.have_telemetry.load(Ordering::Relaxed) && shared.running.load(Ordering::Acquire) {
                        ready = true;
                        eprintln!("arash-daemon: first telemetry after {:.0} ms; ready{}",
                            started.elapsed().as_secs_f64() * 1e3,
                            if realtime { "" } else { " (without real-time scheduling)" });
                        let _ = sd_notify::notify(&[sd_notify::NotifyState::Ready]);
                    } else if started.elapsed() > startup_timeout {
                        break Err(anyhow::anyhow!(
                            "no valid telemetry from the motor link within link.startup_timeout_ms = {} ms \
                             (link.port = {}); motors were never enabled",
                            config.link.startup_timeout_ms, config.link.port));
                    }
                }
                // The watchdog is fed only while the control loop's heartbeat advances.
                if let Some(period) = watchdog {
                    let beat = shared.cycle.load(Ordering::Acquire);
                    if beat != last_beat.0 && last_beat.1.elapsed() >= period / 2 {
                        let _ = sd_notify::notify(&[sd_notify::NotifyState::Watchdog]);
                        last_beat = (beat, Instant::now());
                    }
                }
            }
        }
    };
    let _ = std::fs::remove_file(socket);
    result
}

/// Longest request line the control socket reads; a longer one is refused and the connection
/// closed, so that a client cannot make the daemon buffer without bound.
pub const MAX_REQUEST_BYTES: usize = 64 * 1024;

/// One operator connection: a JSON request per line, a JSON answer per line. Only complete lines
/// are requests: a client that disconnects mid-line has asked for nothing.
async fn client(stream: tokio::net::UnixStream, operator: Arc<Operator>) {
    use tokio::io::AsyncReadExt;
    let (read, mut write) = stream.into_split();
    let mut reader = BufReader::new(read);
    let mut line = Vec::new();
    loop {
        line.clear();
        let limit = MAX_REQUEST_BYTES as u64 + 1;
        match (&mut reader).take(limit).read_until(b'\n', &mut line).await {
            Ok(0) | Err(_) => return,
            Ok(_) => {}
        }
        let complete = line.last() == Some(&b'\n');
        if !complete && line.len() <= MAX_REQUEST_BYTES {
            return; // end of stream in the middle of a line
        }
        let answer = if complete {
            answer(&operator, &line).await
        } else {
            serde_json::json!({ "ok": false, "error": format!("request longer than {MAX_REQUEST_BYTES} bytes; closing") })
        };
        let mut text = answer.to_string();
        text.push('\n');
        if write.write_all(text.as_bytes()).await.is_err() || !complete {
            return;
        }
    }
}

/// The answer to one request line.
async fn answer(operator: &Operator, line: &[u8]) -> serde_json::Value {
    let request = std::str::from_utf8(line)
        .map_err(|_| "bad request: not UTF-8".to_string())
        .and_then(|text| serde_json::from_str::<CtlRequest>(text).map_err(|e| format!("bad request: {e}")));
    match request {
        Ok(request) => match handle(operator, request).await {
            Ok(mut value) => {
                value["ok"] = true.into();
                value
            }
            Err(e) => serde_json::json!({ "ok": false, "error": format!("{e:#}") }),
        },
        Err(e) => serde_json::json!({ "ok": false, "error": e }),
    }
}

/// Queue `request` for the control thread; the ticket it returns is what [`applied`] waits for.
fn send(operator: &Operator, request: Request) -> anyhow::Result<u64> {
    let mut queue = operator.requests.lock().expect("request queue lock");
    queue.0.push(request).map_err(|_| anyhow::anyhow!("the control thread is not taking requests"))?;
    queue.1 += 1;
    Ok(queue.1)
}

/// Wait until the control thread has applied request `ticket` and published its effect. A
/// fixed wait is not enough: on a loaded machine without real-time priority the thread can be
/// descheduled for longer than any short guess (CI once refused an enable after 200 ms).
async fn applied(operator: &Operator, ticket: u64) -> anyhow::Result<()> {
    let shared = &operator.shared;
    for _ in 0..1000 {
        if shared.requests_handled.load(Ordering::Acquire) >= ticket {
            return Ok(());
        }
        if !shared.running.load(Ordering::Acquire) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
    anyhow::bail!("the control thread did not answer within 2 s")
}

async fn handle(operator: &Operator, request: CtlRequest) -> anyhow::Result<serde_json::Value> {
    let mode = |s: &Shared| Mode::from_u32(s.mode.load(Ordering::Relaxed));
    match request {
        CtlRequest::Status => Ok(status(operator)),
        CtlRequest::Enable => {
            applied(operator, send(operator, Request::Enable)?).await?;
            if mode(&operator.shared) != Some(Mode::Enabled) {
                let faults = Faults(operator.shared.faults.load(Ordering::Relaxed));
                anyhow::bail!(
                    "enable refused: mode {:?}, faults [{}], telemetry {}",
                    mode(&operator.shared),
                    faults.names().join(", "),
                    if operator.shared.have_telemetry.load(Ordering::Relaxed) { "ok" } else { "none yet" }
                );
            }
            Ok(status(operator))
        }
        CtlRequest::Disable => {
            applied(operator, send(operator, Request::Disable)?).await?;
            Ok(status(operator))
        }
        CtlRequest::Reset => {
            applied(operator, send(operator, Request::ResetFault)?).await?;
            Ok(status(operator))
        }
        CtlRequest::Hold => {
            applied(operator, send(operator, Request::Hold)?).await?;
            Ok(status(operator))
        }
        CtlRequest::Run { trajectory, duration_s, label } => {
            if mode(&operator.shared) != Some(Mode::Enabled) {
                anyhow::bail!("enable the motors before running a trajectory");
            }
            let text = if trajectory.trim_start().starts_with('{') {
                trajectory
            } else {
                read_file(std::path::Path::new(&trajectory), MAX_INPUT_FILE_BYTES).context("reading the trajectory")?
            };
            let parsed = Trajectory::from_json(&text, operator.model.dof())?;
            let duration_s = duration_s.unwrap_or_else(|| parsed.default_duration());
            if !(duration_s.is_finite() && duration_s > 0.0) {
                anyhow::bail!("duration_s must be positive, not {duration_s}");
            }
            parsed.check_limits(&operator.plan_limits, duration_s, operator.dt)?;
            let id = {
                let mut next = operator.next_run.lock().expect("run counter lock");
                *next += 1;
                *next
            };
            let controller = ControllerKind::from_u32(operator.shared.controller.load(Ordering::Relaxed))
                .map_or("unknown".to_string(), |k| format!("{k:?}").to_lowercase());
            operator.runs.lock().expect("registry lock").insert(
                id,
                RunInfo {
                    label: label.unwrap_or_else(|| "trajectory".into()),
                    trajectory_json: text,
                    controller_json: operator.controller.lock().expect("controller lock").to_json(),
                    controller,
                    log: None,
                    state: "approaching".into(),
                },
            );
            let ticket = send(operator, Request::Run(Box::new(RunRequest { id, trajectory: parsed, duration_s })))?;
            applied(operator, ticket).await?;
            Ok(serde_json::json!({ "run_id": id, "duration_s": duration_s }))
        }
        CtlRequest::Controller { kind, model } => {
            let kind = crate::config::controller_kind(&kind).context("controller kind")?;
            let path = model.map(PathBuf::from);
            let file = path.as_deref().map(|p| read_model_file(p).map(|f| (p, f))).transpose()?;
            if let Some((p, gains)) = file.as_ref().and_then(|(p, f)| Some((p, f.drive_gains.as_ref()?))) {
                same_torque_constants(operator, p, gains)?;
            }
            let (controller, logged) =
                build_controller(&operator.model, kind, file.as_ref().map(|(p, f)| (*p, f)), operator.gains.as_ref())?;
            applied(operator, send(operator, Request::Controller(controller))?).await?;
            *operator.controller.lock().expect("controller lock") = logged;
            Ok(status(operator))
        }
    }
}

/// A model switched to at run time must drive the currents as the running cycle does: its gains
/// turn the same torque into the same current, or the daemon is restarted with it.
fn same_torque_constants(operator: &Operator, path: &std::path::Path, gains: &DriveGains) -> anyhow::Result<()> {
    let names = operator.model.joint_names();
    let wanted =
        TorqueConstants::choose(&operator.drive, Some(gains), &names).with_context(|| format!("{}", path.display()))?;
    let running = &operator.torque_constant.values;
    anyhow::ensure!(
        wanted.values == *running,
        "{} has drive gains {:?} per ampere, and the daemon runs with {running:?}: the torque constants are fixed at \
         start-up; restart the daemon with it as control.model",
        path.display(),
        wanted.values
    );
    Ok(())
}

fn status(operator: &Operator) -> serde_json::Value {
    let s = &operator.shared;
    let load = |a: &std::sync::atomic::AtomicU64| a.load(Ordering::Relaxed);
    let faults = Faults(s.faults.load(Ordering::Relaxed));
    let q: Vec<f64> = s.q[..operator.model.dof()].iter().map(|a| f64::from_bits(a.load(Ordering::Relaxed))).collect();
    let runs = operator.runs.lock().expect("registry lock").clone();
    let phase = ["hold", "approach", "run"][s.phase.load(Ordering::Relaxed).min(2) as usize];
    serde_json::json!({
        "cycle": load(&s.cycle),
        "mode": Mode::from_u32(s.mode.load(Ordering::Relaxed)),
        "faults": faults.names(),
        "controller": ControllerKind::from_u32(s.controller.load(Ordering::Relaxed)),
        "phase": phase,
        "run_id": s.run_id.load(Ordering::Relaxed),
        "last_run_ended": s.last_run_ended.load(Ordering::Relaxed),
        "telemetry": s.have_telemetry.load(Ordering::Relaxed),
        "drive": drive_status(s.drive.load(Ordering::Relaxed)),
        "torque_constant": operator.torque_constant.values,
        "torque_constant_source": operator.torque_constant.sources,
        "q": q,
        "missed_cycles": load(&s.missed),
        "log_dropped": load(&s.log_dropped),
        "logging": !s.logging_failed.load(Ordering::Acquire),
        "memory": crate::rt::memory::MemoryUse::of_self(),
        "live": operator.live.as_ref().map(|l| l.status()),
        "link": {
            "frames_received": load(&s.frames_received),
            "crc_errors": load(&s.crc_errors),
            "framing_errors": load(&s.framing_errors),
            "lost": load(&s.lost),
            "stale": load(&s.stale),
            "send_errors": load(&s.send_errors),
        },
        "runs": runs,
    })
}

/// The drive's own report: whether its power stage is on, and its latched faults.
fn drive_status(bits: u32) -> serde_json::Value {
    use crate::link::frame::{drive_fault, status};
    let (state, faults) = (bits as u8, (bits >> 8) as u8);
    serde_json::json!({
        "powered": state & status::ENABLED != 0,
        "brake": state & status::BRAKE != 0,
        "faults": drive_fault::names(faults),
    })
}
