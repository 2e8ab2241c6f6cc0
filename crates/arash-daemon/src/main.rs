//! `arash`: the command-line front of the ARASH:ASiST software. Each subcommand lives in
//! `cli/`, the reports and figures they write in `report/`; this file only parses arguments and
//! reports errors.

// The argument docs are clap's help text, written for a terminal: `tau.<joint>` and `<kg>` there
// are placeholders, not HTML.
#![allow(rustdoc::invalid_html_tags)]

mod cli;
mod report;
mod runlog;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "arash", version, about = "Calibrate and control the ARASH:ASiST haptic robot")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The paper end to end on the simulated rig, through the daemon: excitation, calibration,
    /// diagnosis, tracking three or four ways, and a report under logs/<run>/report/.
    Demo(cli::demo::Args),
    /// Describe a robot: bodies, joints, parameter count and base parameters.
    Model(cli::model::Args),
    /// Design a persistently exciting Fourier trajectory and write it as JSON.
    Excite(cli::excite::Args),
    /// Identify the dynamic parameters from logged runs and write a model file.
    Identify(cli::identify::Args),
    /// Find what the declared model lacks in logged runs: report, figures and an updated model.
    Diagnose(cli::diagnose::Args),
    /// Run the simulated rig with a controller on a trajectory and write the flight log (MCAP).
    Simulate(cli::simulate::Args),
    /// Run the rig: the 1 kHz control loop over the motor link (starts with the motors disabled).
    Daemon(cli::daemon::Args),
    /// Command a running daemon: status, enable, disable, reset, hold, run, controller.
    Ctl(cli::ctl::Args),
    /// Serve the simulated rig behind the motor protocol on a pseudo-terminal.
    MockMotor(cli::mock_motor::Args),
}

/// Errors are for the person at the rig: the message and its causes on one line, without the
/// backtrace anyhow would add under `RUST_BACKTRACE`.
fn main() -> std::process::ExitCode {
    std::panic::set_hook(Box::new(report_bug));
    match run(Cli::parse().command) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // Causes whose text the message already quotes are not repeated.
            let mut message = e.to_string();
            for cause in e.chain().skip(1).map(|c| c.to_string()) {
                if !message.contains(&cause) {
                    message = format!("{message}: {cause}");
                }
            }
            eprintln!("error: {message}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// A panic is a bug in arash, not the user's mistake: say so in one line with where it happened,
/// without a backtrace (set `ARASH_BACKTRACE=1` to get one for a bug report).
fn report_bug(info: &std::panic::PanicHookInfo) {
    let message = info
        .payload()
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| info.payload().downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown cause".into());
    let place = info.location().map(|l| format!(" at {}:{}", l.file(), l.line())).unwrap_or_default();
    let thread = std::thread::current().name().unwrap_or("main").to_string();
    eprintln!("error: internal error in arash (thread `{thread}`{place}): {message}. This is a bug; please report it with the command line.");
    if std::env::var_os("ARASH_BACKTRACE").is_some() {
        eprintln!("{}", std::backtrace::Backtrace::force_capture());
    }
}

fn run(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Demo(args) => cli::demo::run(args),
        Command::Model(args) => cli::model::run(args),
        Command::Excite(args) => cli::excite::run(args),
        Command::Identify(args) => cli::identify::run(args),
        Command::Diagnose(args) => cli::diagnose::run(args),
        Command::Simulate(args) => cli::simulate::run(args),
        Command::Daemon(args) => cli::daemon::run(args),
        Command::Ctl(args) => cli::ctl::run(args),
        Command::MockMotor(args) => cli::mock_motor::run(args),
    }
}
