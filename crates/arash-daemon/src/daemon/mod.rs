//! The daemon: wires the motor link, the control thread, the logger thread and the operator
//! interface together, and speaks to systemd.
//!
//! Threads: the control thread (real-time, [`crate::rt::runner`]); the logger thread; and the
//! main thread running a single-threaded tokio runtime for the Unix socket, housekeeping
//! (dropping what the control thread hands back), signals and the systemd notifications. tokio
//! never touches the control cycle.
//!
//! - [`startup`]: the command line, the configuration and everything checked before the
//!   control thread starts;
//! - [`requests`]: the operator's requests and the status they are answered with;
//! - [`server`]: the operator's socket and the tokio loop's housekeeping.

pub mod model_helper;
pub mod requests;
pub mod server;
pub mod startup;

pub use startup::{build_controller, read_model_file, DaemonArgs};

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::Context;
use arash_core::control::{PlanLimits, RobustGains};
use arash_core::Model;

use crate::config::DaemonConfig;
use crate::live::window::display_scales;
use crate::logger::{LogContext, Logger, RunRegistry};

use crate::rt::clock::{setup_realtime, Pace, RtStatus};
use crate::rt::cycle::ControlCycle;
use crate::rt::runner::{self, Queues, Shared};
use requests::Operator;
use server::serve;
use startup::{open_link, open_live, torque_constants};

/// Everything the daemon needs, resolved from the configuration and the command line.
pub struct DaemonOptions {
    pub config: DaemonConfig,
    pub config_text: String,
    pub model: Model,
    pub urdf: String,
}

/// Run the daemon until SIGTERM or SIGINT.
pub fn run(options: DaemonOptions) -> anyhow::Result<()> {
    let DaemonOptions { config, config_text, model, urdf } = options;
    config.validate(&model).context("invalid configuration")?;
    crate::rt::memory::one_malloc_arena();
    let dof = model.dof();
    // First of all, before anything slow: a drive left powered by a crashed daemon keeps applying
    // its last current until told otherwise. The control cycle goes on sending DISABLE until an
    // operator enables. (A CANopen master disables its drives as it opens, and sends nothing
    // more until the control thread starts it.)
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
    let robot = config.robot.as_deref();
    let start_model =
        config.control.model.as_deref().map(|p| model_helper::resolve_blocking(p, kind, robot)).transpose()?;
    let (controller, logged_controller) = build_controller(&model, kind, start_model.as_ref(), gains.as_ref())?;
    let torque_constant = torque_constants(&config, &model, start_model.as_ref().and_then(|r| r.drive_gains.as_ref()))?;
    let mut cycle_config = config.cycle_config(&model)?;
    cycle_config.drive.torque_constant.clone_from(&torque_constant.values);
    let cycle = ControlCycle::new(cycle_config, controller);
    let in_use = match &start_model {
        Some(r) => (r.params.clone(), r.effects.clone()),
        None => (model.cad_parameters(), Vec::new()),
    };
    let (cycle, force) = with_force(cycle, &config, &model, start_model.as_ref())?;

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
        true => Some(open_live(&config, &urdf, &scales, force.as_ref().and_then(|f| f.frame.as_deref()))?),
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
    let (priority, policy, pace) = (config.rt.priority, config.rt.policy, config.rt.pace);
    let period = Duration::from_secs_f64(1.0 / config.control.rate_hz);
    let control_thread = std::thread::Builder::new()
        .name("arash-control".into())
        .stack_size(crate::rt::memory::CONTROL_STACK_BYTES)
        .spawn(move || {
            // The link's start-up runs here, just before the first cycle: a CANopen master's
            // heartbeat, which the drives watch from its first beat, then never pauses.
            // A lockstep run has no deadline to keep, and at SCHED_FIFO a loop that goes as fast
            // as the rig answers would starve the host's other work.
            let realtime = match pace {
                Pace::Deadline => setup_realtime(priority, policy),
                Pace::Lockstep => Ok(RtStatus {
                    fifo: false,
                    mlocked: false,
                    problems: vec!["the lockstep pace runs at ordinary priority".into()],
                }),
            };
            let ready = realtime.and_then(|status| {
                let found = link.start().map_err(|e| format!("{e}"))?;
                Ok((status, found))
            });
            let failed = ready.is_err();
            let _ = rt_tx.send(ready);
            if failed {
                return;
            }
            let queues = Queues { requests: request_rx, garbage: garbage_tx, log: log_tx };
            runner::run(cycle, link.as_mut(), queues, &rt_shared, period, pace);
        })?;
    let rt_status = rt_rx.recv().context("the control thread died during set-up")?;
    let rt_status = match rt_status {
        Ok((status, found)) => {
            for line in found {
                eprintln!("arash-daemon: {line}");
            }
            status
        }
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
        robot: config.robot.clone(),
        force_config: config.force.clone(),
        force: Mutex::new(force),
        haptic_config: config.haptic.clone(),
        in_use: Mutex::new(in_use),
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

/// The hand's force observer on the model the daemon starts with (`[force]`), printed with what
/// chose its settings; the cycle unchanged when it is switched off.
fn with_force(
    cycle: ControlCycle,
    config: &DaemonConfig,
    model: &Model,
    resolved: Option<&startup::ResolvedModel>,
) -> anyhow::Result<(ControlCycle, Option<crate::rt::force::ForceSetup>)> {
    if !config.force.enabled {
        return Ok((cycle, None));
    }
    let held_out = resolved.and_then(|r| r.held_out.as_ref());
    let params = resolved.map_or_else(|| model.cad_parameters(), |r| r.params.clone());
    let effects = resolved.map(|r| r.effects.clone()).unwrap_or_default();
    let (setup, monitor) = crate::rt::force::ForceSetup::monitor(
        model,
        &config.force,
        held_out,
        config.control.rate_hz,
        &params,
        &effects,
    )
    .map_err(|e| anyhow::anyhow!(e))?;
    for reason in &setup.reasons {
        eprintln!("arash-daemon: force observer: {reason}");
    }
    Ok((cycle.with_force(monitor), Some(setup)))
}
