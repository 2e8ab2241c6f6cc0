//! `arash ctl`: command a running daemon over its Unix socket.

use std::path::PathBuf;
use std::time::Duration;

use arash_daemon::ctl::{call, CtlRequest};

#[derive(clap::Args)]
pub struct Args {
    /// The daemon's socket.
    #[arg(long, default_value = "/run/arash/arash.sock")]
    socket: PathBuf,
    /// With `run`: wait until the run ends and print its log file.
    #[arg(long, global = true)]
    wait: bool,
    #[command(subcommand)]
    request: CtlRequest,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.wait && !matches!(args.request, CtlRequest::Run { .. }) {
        anyhow::bail!("--wait waits for a run: it goes with `arash ctl run`");
    }
    let answer = call(&args.socket, &args.request.absolute()?)?;
    if args.wait {
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
