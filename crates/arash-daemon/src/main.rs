//! `arash-daemon`: the rig, as systemd runs it (deploy/arash.service). It runs the 1 kHz control
//! loop over the motor link and nothing else; the tools (identification, reports, figures) are
//! the `arash` binary's (crates/arash-cli), which can run this same daemon as `arash daemon`.

use arash_daemon::daemon::{self, DaemonArgs};
use clap::Parser;

#[derive(Parser)]
#[command(name = "arash-daemon", version, about = "Run the ARASH:ASiST rig (starts with the motors disabled)")]
struct Cli {
    #[command(flatten)]
    args: DaemonArgs,
}

fn main() -> std::process::ExitCode {
    // Model files are resolved by this binary in a helper process (daemon/model_helper.rs).
    arash_daemon::daemon::model_helper::serve_if_asked();
    arash_daemon::exit::report_panics_as_bugs();
    let args = Cli::parse().args;
    arash_daemon::exit::exit_code(daemon::startup::options(args).map_err(anyhow::Error::from).and_then(daemon::run))
}
