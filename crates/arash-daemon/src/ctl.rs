//! The operator interface: newline-delimited JSON over a Unix domain socket. Each request is one
//! line, `{"cmd": "...", ...}`; each answer is one line, `{"ok": true, ...}` or
//! `{"ok": false, "error": "..."}`. `arash ctl` is the client; docs/daemon.md lists the commands.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::time::Duration;

/// A request to the daemon: its JSON line on the socket (serde) and the `arash ctl` subcommand
/// that sends it (clap), declared once. Paths are sent absolute ([`CtlRequest::absolute`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, clap::Subcommand)]
#[serde(tag = "cmd", rename_all = "kebab-case", deny_unknown_fields)]
pub enum CtlRequest {
    /// Print the daemon's state as JSON.
    Status,
    /// Enable the motors (holding the present position).
    Enable,
    /// Disable the motors.
    Disable,
    /// Clear latched faults; the motors stay disabled.
    Reset,
    /// Hold the present reference, abandoning a run.
    Hold,
    /// Approach the start of a trajectory file (an `arash-trajectory/1` document) and play it.
    Run {
        /// The trajectory file (`arash excite -o`); the daemon gets its absolute path.
        trajectory: String,
        /// Seconds to play; default: the trajectory's natural length.
        #[arg(long = "duration", value_name = "SECONDS")]
        #[serde(default)]
        duration_s: Option<f64>,
        /// Name for the run's log file; default: the trajectory file's name.
        #[arg(long)]
        #[serde(default)]
        label: Option<String>,
    },
    /// Switch the control law.
    Controller {
        /// pd, idc or robust.
        kind: String,
        /// Model file from `arash identify`; default: CAD parameters. The daemon gets its
        /// absolute path.
        #[arg(long)]
        #[serde(default)]
        model: Option<String>,
    },
    /// Let the trainee move the instrument: the model's compensation and, with a file, its
    /// virtual fixtures (docs/haptics.md). Only from hold with the motors enabled; `hold` and
    /// `run` leave it.
    Haptic {
        /// Fixture file (TOML: depth walls, cones, viscous fields, springs); none: free space.
        /// The daemon gets its absolute path.
        #[arg(long)]
        #[serde(default)]
        fixtures: Option<String>,
    },
}

impl CtlRequest {
    /// The request with its files named by absolute path, as the daemon (which runs elsewhere)
    /// needs them, and a run's label defaulted to its trajectory file's name.
    pub fn absolute(self) -> anyhow::Result<Self> {
        let absolute = |what: &str, path: &str| -> anyhow::Result<String> {
            Ok(std::fs::canonicalize(path).map_err(|e| anyhow::anyhow!("{what} {path}: {e}"))?.display().to_string())
        };
        Ok(match self {
            CtlRequest::Run { trajectory, duration_s, label } => CtlRequest::Run {
                label: label.or_else(|| Path::new(&trajectory).file_stem().map(|s| s.to_string_lossy().into_owned())),
                trajectory: absolute("trajectory", &trajectory)?,
                duration_s,
            },
            CtlRequest::Controller { kind, model } => {
                CtlRequest::Controller { kind, model: model.map(|m| absolute("model file", &m)).transpose()? }
            }
            CtlRequest::Haptic { fixtures } => {
                CtlRequest::Haptic { fixtures: fixtures.map(|f| absolute("fixture file", &f)).transpose()? }
            }
            other => other,
        })
    }
}

/// Send one request and read the answer.
pub fn call(socket: &Path, request: &CtlRequest) -> anyhow::Result<serde_json::Value> {
    let mut stream = UnixStream::connect(socket)
        .map_err(|e| anyhow::anyhow!("connecting to the daemon at {}: {e} (is it running?)", socket.display()))?;
    stream.set_read_timeout(Some(Duration::from_secs(10)))?;
    let mut line = serde_json::to_string(request)?;
    line.push('\n');
    stream.write_all(line.as_bytes())?;
    let mut answer = String::new();
    BufReader::new(stream).read_line(&mut answer)?;
    let value: serde_json::Value = serde_json::from_str(&answer)
        .map_err(|e| anyhow::anyhow!("the daemon's answer is not JSON ({e}): {answer:?}"))?;
    if value["ok"] != serde_json::Value::Bool(true) {
        anyhow::bail!("{}", value["error"].as_str().unwrap_or("the daemon refused without a reason"));
    }
    Ok(value)
}

/// Poll the daemon every `period` until run `id` has ended and its log is finished; return the
/// log's path. `on_status` sees every status document first (for progress, or to give up with
/// an error); a fault of the daemon ends the wait with an error.
pub fn wait_for_run(
    socket: &Path,
    id: u64,
    period: Duration,
    mut on_status: impl FnMut(&serde_json::Value) -> anyhow::Result<()>,
) -> anyhow::Result<std::path::PathBuf> {
    loop {
        std::thread::sleep(period);
        let status = call(socket, &CtlRequest::Status)?;
        on_status(&status)?;
        if status["mode"] == "faulted" {
            anyhow::bail!("run {id}: the daemon faulted ({}); the motors are off", status["faults"]);
        }
        if let Some(log) = status["runs"][id.to_string()]["log"].as_str() {
            return Ok(log.into());
        }
    }
}
