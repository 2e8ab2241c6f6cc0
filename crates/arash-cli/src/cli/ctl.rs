//! `arash ctl`: command a running daemon over its Unix socket.

use std::path::PathBuf;
use std::time::Duration;

use arash_daemon::ctl::{call, CtlRequest};

#[derive(clap::Args)]
pub struct Args {
    /// The daemon's socket.
    #[arg(long, default_value = "/run/arash/arash.sock")]
    socket: PathBuf,
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
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
    /// Approach the start of a trajectory file and play it.
    Run {
        trajectory: PathBuf,
        /// Seconds to play; default: the trajectory's natural length.
        #[arg(long)]
        duration: Option<f64>,
        /// Name for the run's log file.
        #[arg(long)]
        label: Option<String>,
        /// Wait until the run ends and print its log file.
        #[arg(long)]
        wait: bool,
    },
    /// Switch the control law.
    Controller {
        /// pd, idc or robust.
        kind: String,
        /// Model file from `arash identify`; default: CAD parameters.
        #[arg(long)]
        model: Option<PathBuf>,
    },
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let request = match &args.command {
        Command::Status => CtlRequest::Status,
        Command::Enable => CtlRequest::Enable,
        Command::Disable => CtlRequest::Disable,
        Command::Reset => CtlRequest::Reset,
        Command::Hold => CtlRequest::Hold,
        Command::Run { trajectory, duration, label, .. } => CtlRequest::Run {
            trajectory: std::fs::canonicalize(trajectory)
                .map_err(|e| anyhow::anyhow!("trajectory {}: {e}", trajectory.display()))?
                .display()
                .to_string(),
            duration_s: *duration,
            label: label.clone().or_else(|| trajectory.file_stem().map(|s| s.to_string_lossy().into_owned())),
        },
        Command::Controller { kind, model } => CtlRequest::Controller {
            kind: kind.clone(),
            model: model
                .as_ref()
                .map(|m| std::fs::canonicalize(m).map(|p| p.display().to_string()))
                .transpose()
                .map_err(|e| anyhow::anyhow!("model file: {e}"))?,
        },
    };
    let answer = call(&args.socket, &request)?;
    if let Command::Run { wait: true, .. } = args.command {
        let id = answer["run_id"].as_u64().unwrap_or(0);
        let duration = answer["duration_s"].as_f64().unwrap_or(0.0);
        eprintln!("run {id}: approaching the start, then {duration:.1} s");
        return wait_for_run(&args.socket, id);
    }
    println!("{}", serde_json::to_string_pretty(&answer)?);
    Ok(())
}

/// Wait for run `id`, printing its state as it changes, then the log's path.
fn wait_for_run(socket: &std::path::Path, id: u64) -> anyhow::Result<()> {
    let mut last_state = String::new();
    let log = arash_daemon::ctl::wait_for_run(socket, id, Duration::from_millis(200), |status| {
        let state = status["runs"][id.to_string()]["state"].as_str().unwrap_or("").to_string();
        if state != last_state {
            eprintln!("run {id}: {state}");
            last_state = state;
        }
        Ok(())
    })?;
    println!("{}", log.display());
    Ok(())
}
