//! The operator's requests: each queued to the control thread, waited for until applied, and
//! answered with the daemon's status.

use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::Context;
use arash_core::control::{ControllerKind, Faults, PlanLimits, RobustGains, Trajectory};
use arash_core::model_file::DriveGains;
use arash_core::record::{Code, Mode};
use arash_core::Model;

use crate::ctl::CtlRequest;
use crate::drive_config::TorqueConstants;
use crate::live::server::LiveServer;
use crate::logger::{RunInfo, RunRegistry};
use arash_core::control::logged::LoggedController;

use super::model_helper;
use super::startup::{build_controller, read_file, ResolvedModel, MAX_INPUT_FILE_BYTES};
use crate::rt::cycle::Request;
use crate::rt::force::{ForceMonitor, ForceSetup};
use crate::rt::haptic::{parse_fixtures, HapticConfig, HapticMode};
use crate::rt::reference::RunRequest;
use crate::rt::runner::Shared;

/// The operator side's handles.
pub(super) struct Operator {
    pub(super) model: Model,
    /// The robust gains; `None` for a robot the paper's gains do not fit (PD only).
    pub(super) gains: Option<RobustGains>,
    /// The request queue and the number of requests pushed into it so far.
    pub(super) requests: Mutex<(rtrb::Producer<Request>, u64)>,
    pub(super) shared: Arc<Shared>,
    pub(super) runs: RunRegistry,
    /// The live stream, when it is on.
    pub(super) live: Option<Arc<LiveServer>>,
    pub(super) next_run: Mutex<u32>,
    /// The controller last sent to the cycle, as each run's log describes it.
    pub(super) controller: Mutex<LoggedController>,
    /// What a trajectory may ask of the joints, checked before a run is queued.
    pub(super) plan_limits: PlanLimits,
    /// Control period (s): the spacing at which a trajectory is checked.
    pub(super) dt: f64,
    /// The configured drive, and the torque constants the cycle runs with (fixed at start-up).
    pub(super) drive: crate::drive_config::DriveConfig,
    pub(super) torque_constant: TorqueConstants,
    /// The robot's URDF as configured (`None`: the built-in one): the model helper checks files
    /// against it.
    pub(super) robot: Option<PathBuf>,
    /// The `[force]` table, and the hand's force observer as set up at start or by the last
    /// switch to a model file (None: `force.enabled = false`).
    pub(super) force_config: crate::rt::force::ForceConfig,
    pub(super) force: Mutex<Option<crate::rt::force::ForceSetup>>,
    /// `[haptic]`, and the parameters and effects of the model in use (the start's, or the last
    /// switch's): the haptic mode compensates with them, and its damping left comes from them.
    pub(super) haptic_config: HapticConfig,
    pub(super) in_use: Mutex<(Vec<f64>, Vec<arash_core::effects::EffectTerm>)>,
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

pub(super) async fn handle(operator: &Operator, request: CtlRequest) -> anyhow::Result<serde_json::Value> {
    let mode = |s: &Shared| Mode::from_code(s.mode.load(Ordering::Relaxed));
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
            let controller = ControllerKind::from_code(operator.shared.controller.load(Ordering::Relaxed))
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
            let resolved = match model.map(PathBuf::from) {
                Some(path) => {
                    let resolved = model_helper::resolve(&path, kind, operator.robot.as_deref()).await?;
                    if let Some(gains) = &resolved.drive_gains {
                        same_torque_constants(operator, &path, gains)?;
                    }
                    Some(resolved)
                }
                None => None,
            };
            let (controller, logged) =
                build_controller(&operator.model, kind, resolved.as_ref(), operator.gains.as_ref())?;
            let observer = match &resolved {
                Some(r) => observer_for(operator, r).context("the hand's force observer on the new model")?,
                None => None,
            };
            let (monitor, setup) = observer.unzip();
            applied(operator, send(operator, Request::Controller(controller, monitor))?).await?;
            *operator.controller.lock().expect("controller lock") = logged;
            if let Some(setup) = setup {
                *operator.force.lock().expect("force lock") = Some(setup);
            }
            *operator.in_use.lock().expect("model lock") = match &resolved {
                Some(r) => (r.params.clone(), r.effects.clone()),
                None => (operator.model.cad_parameters(), Vec::new()),
            };
            Ok(status(operator))
        }
        CtlRequest::Haptic { fixtures } => haptic(operator, fixtures.as_deref()).await,
    }
}

/// Enter the haptic mode with the fixtures of file `path` (none: free space), checked against the
/// passivity bound of the loop on the model in use before anything is queued.
async fn haptic(operator: &Operator, path: Option<&str>) -> anyhow::Result<serde_json::Value> {
    let mode = Mode::from_code(operator.shared.mode.load(Ordering::Relaxed));
    anyhow::ensure!(mode == Some(Mode::Enabled), "enable the motors before the haptic mode");
    let fixtures = match path {
        Some(p) => {
            let text = read_file(std::path::Path::new(p), MAX_INPUT_FILE_BYTES).context("reading the fixture file")?;
            parse_fixtures(&text).map_err(|e| anyhow::anyhow!("{p}: {e}"))?
        }
        None => Default::default(),
    };
    let (params, effects) = operator.in_use.lock().expect("model lock").clone();
    let built =
        HapticMode::build(&operator.model, (&params, &effects), &operator.haptic_config, &fixtures, operator.dt)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.unwrap_or("the haptic mode")))?;
    let passivity = serde_json::to_value(&built.passivity)?;
    applied(operator, send(operator, Request::Haptic(Box::new(built)))?).await?;
    let phase = operator.shared.phase.load(Ordering::Relaxed);
    anyhow::ensure!(
        phase == 3,
        "the haptic mode was refused: it starts from hold (`arash ctl hold` ends a run), with no collision latched"
    );
    let mut answer = status(operator);
    answer["haptic"] = serde_json::json!({ "fixtures": path, "passivity": passivity });
    Ok(answer)
}

/// The hand's force observer on a model switched to at run time, set up as at start-up from the
/// daemon's `[force]` and the model file's held-out data; None when the daemon runs none.
fn observer_for(
    operator: &Operator,
    resolved: &ResolvedModel,
) -> anyhow::Result<Option<(Box<ForceMonitor>, ForceSetup)>> {
    if !operator.force_config.enabled {
        return Ok(None);
    }
    let held_out = resolved.held_out.as_ref();
    let rate_hz = 1.0 / operator.dt;
    let (setup, monitor) = ForceSetup::monitor(
        &operator.model,
        &operator.force_config,
        held_out,
        rate_hz,
        &resolved.params,
        &resolved.effects,
    )
    .map_err(|e| anyhow::anyhow!(e))?;
    Ok(Some((Box::new(monitor), setup)))
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

pub(super) fn status(operator: &Operator) -> serde_json::Value {
    let s = &operator.shared;
    let load = |a: &std::sync::atomic::AtomicU64| a.load(Ordering::Relaxed);
    let faults = Faults(s.faults.load(Ordering::Relaxed));
    let q: Vec<f64> = s.q[..operator.model.dof()].iter().map(|a| f64::from_bits(a.load(Ordering::Relaxed))).collect();
    let runs = operator.runs.lock().expect("registry lock").clone();
    let phase = ["hold", "approach", "run", "haptic"][s.phase.load(Ordering::Relaxed).min(3) as usize];
    let level = ["free", "contact", "collision"][s.force_level.load(Ordering::Relaxed).min(2) as usize];
    serde_json::json!({
        "cycle": load(&s.cycle),
        "mode": Mode::from_code(s.mode.load(Ordering::Relaxed)),
        "faults": faults.names(),
        "controller": ControllerKind::from_code(s.controller.load(Ordering::Relaxed)),
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
        "link": *s.link.lock().expect("link stats lock"),
        "runs": runs,
        "force": operator.force.lock().expect("force lock").as_ref().map(|f| serde_json::json!({
            "setup": f,
            "level": level,
            "collision_reaction": "float: the run stops, the joints float under the model's compensation until reset",
        })),
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
