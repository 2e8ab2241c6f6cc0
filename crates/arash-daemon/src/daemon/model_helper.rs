//! Model files are read, checked and turned into a controller's parameters in a helper process:
//! a run of the daemon's own binary that serves one request and exits.
//!
//! Why not in the daemon: under `mlockall` every page the daemon maps stays locked and resident.
//! Resolving a file that carries only base parameters means computing the robot's base
//! parameters and the standard parameters nearest CAD (the consistency check of a model-based
//! law), and faer's matrix products keep a buffer of twice the L3 cache per thread that runs
//! them (private-gemm-x86): 64 MB on each of three threads on this machine. A model switch took
//! the daemon from 28 to 234 MB resident, all of it locked (issue 57). A model file can also be
//! up to 64 MB of JSON, parsed into a tree. The helper's memory is its own and is gone when it
//! exits; the daemon receives a few hundred numbers.
//!
//! The request goes on the helper's standard input and the answer comes on its standard output,
//! both JSON; [`HELPER_ENV`] in its environment tells either binary to serve it
//! ([`serve_if_asked`], the first call of each `main`).

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use arash_core::control::ControllerKind;

use super::startup::{load_robot, read_model_file, ResolvedModel, StartupError};

/// Set in the helper's environment: serve one request from standard input.
pub const HELPER_ENV: &str = "ARASH_MODEL_HELPER";

/// What the daemon asks: the parameters of `path` for a controller of `kind`, checked against
/// the robot at `robot` (`None`: the built-in ARASH:ASiST).
#[derive(Debug, serde::Serialize, serde::Deserialize)]
struct Request {
    path: PathBuf,
    kind: ControllerKind,
    robot: Option<PathBuf>,
}

#[derive(Debug, serde::Serialize, serde::Deserialize)]
enum Answer {
    Resolved(Box<ResolvedModel>),
    /// The file was refused: the message the daemon reports, its causes included.
    Refused(String),
}

/// In the helper: resolve one request.
fn serve(request: &Request) -> Result<ResolvedModel, StartupError> {
    let (model, _) = load_robot(request.robot.as_deref())?;
    let file = read_model_file(&request.path)?;
    let params = match request.kind {
        ControllerKind::Pd => file.controller_parameters(&model),
        _ => file.consistent_controller_parameters(&model),
    }
    .map_err(|source| StartupError::Refused { path: request.path.clone(), kind: request.kind, source })?;
    Ok(ResolvedModel { params, effects: file.effects, drive_gains: file.drive_gains, held_out: file.held_out })
}

/// The first call of each binary's `main`: when started as the helper, serve the request on
/// standard input and exit; otherwise return at once.
pub fn serve_if_asked() {
    if std::env::var_os(HELPER_ENV).is_none() {
        return;
    }
    let mut text = String::new();
    let answer =
        match std::io::stdin().read_to_string(&mut text).map_err(|e| e.to_string()).and_then(|_| {
            serde_json::from_str::<Request>(&text).map_err(|e| format!("the model helper's request: {e}"))
        }) {
            Ok(request) => match serve(&request) {
                Ok(resolved) => Answer::Resolved(Box::new(resolved)),
                Err(e) => Answer::Refused(format!("{:#}", anyhow::Error::from(e))),
            },
            Err(e) => Answer::Refused(e),
        };
    let json = serde_json::to_string(&answer).expect("an answer serialises");
    let written = std::io::stdout().write_all(json.as_bytes());
    std::process::exit(if written.is_ok() { 0 } else { 1 });
}

/// The helper's command for one request: this binary, with [`HELPER_ENV`] set.
fn helper_command(request: &Request) -> Result<(std::process::Command, Vec<u8>), StartupError> {
    let exe =
        std::env::current_exe().map_err(|e| StartupError::ModelHelper(format!("finding the daemon's binary: {e}")))?;
    let mut command = std::process::Command::new(exe);
    command
        .env(HELPER_ENV, "1")
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped());
    let input = serde_json::to_vec(request).expect("a request serialises");
    Ok((command, input))
}

/// The helper's output read back.
fn answered(output: std::process::Output) -> Result<ResolvedModel, StartupError> {
    match serde_json::from_slice::<Answer>(&output.stdout) {
        Ok(Answer::Resolved(resolved)) => Ok(*resolved),
        Ok(Answer::Refused(message)) => Err(StartupError::ModelHelper(message)),
        Err(_) => Err(StartupError::ModelHelper(format!(
            "the model helper ended with {} and no answer: {}",
            output.status,
            String::from_utf8_lossy(&output.stderr).trim()
        ))),
    }
}

/// Resolve `path` for `kind` in a helper, waiting for it (the daemon's start-up).
pub fn resolve_blocking(
    path: &Path,
    kind: ControllerKind,
    robot: Option<&Path>,
) -> Result<ResolvedModel, StartupError> {
    let request = Request { path: path.into(), kind, robot: robot.map(Into::into) };
    let (mut command, input) = helper_command(&request)?;
    let spawn = |e: std::io::Error| StartupError::ModelHelper(format!("starting the model helper: {e}"));
    let mut child = command.spawn().map_err(spawn)?;
    child.stdin.take().expect("piped").write_all(&input).map_err(spawn)?;
    answered(child.wait_with_output().map_err(spawn)?)
}

/// Resolve `path` for `kind` in a helper without blocking the operator side's runtime (a model
/// switch at run time).
pub async fn resolve(path: &Path, kind: ControllerKind, robot: Option<&Path>) -> Result<ResolvedModel, StartupError> {
    use tokio::io::AsyncWriteExt;
    let request = Request { path: path.into(), kind, robot: robot.map(Into::into) };
    let (command, input) = helper_command(&request)?;
    let spawn = |e: std::io::Error| StartupError::ModelHelper(format!("starting the model helper: {e}"));
    let mut child = tokio::process::Command::from(command).kill_on_drop(true).spawn().map_err(spawn)?;
    let mut stdin = child.stdin.take().expect("piped");
    stdin.write_all(&input).await.map_err(spawn)?;
    drop(stdin);
    answered(child.wait_with_output().await.map_err(spawn)?)
}
