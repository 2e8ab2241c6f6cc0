//! `arash`: the command-line front of the ARASH:ASiST software. Each subcommand lives in
//! `cli/`, the reports and figures they write in `report/`; this file only parses arguments and
//! reports errors.

// The argument docs are clap's help text, written for a terminal: `tau.<joint>` and `<kg>` there
// are placeholders, not HTML.
#![allow(rustdoc::invalid_html_tags)]

mod cli;
#[cfg(test)]
mod docs_check;
mod report;
mod runlog;

// The BLAS and LAPACK that identification's SDP calls under their Fortran names: named here so
// that the crate is linked (arash-core leaves the choice of BLAS to the binary).
use arash_blas_lapack as _;
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
    /// Estimate the hand's force over logged runs from the model: the estimate with its σ, the
    /// contacts and collisions found, and a figure.
    Force(cli::force::Args),
    /// Run the simulated rig with a controller on a trajectory and write the flight log (MCAP).
    Simulate(cli::simulate::Args),
    /// Run the rig: the 1 kHz control loop over the motor link (starts with the motors disabled).
    Daemon(cli::daemon::Args),
    /// Command a running daemon: status, enable, disable, reset, hold, run, controller.
    Ctl(cli::ctl::Args),
    /// Serve the simulated rig behind the motor protocol on a pseudo-terminal.
    MockMotor(cli::mock_motor::Args),
}

fn main() -> std::process::ExitCode {
    // Model files are resolved by this binary in a helper process (daemon/model_helper.rs).
    arash_daemon::daemon::model_helper::serve_if_asked();
    arash_daemon::exit::report_panics_as_bugs();
    arash_daemon::exit::exit_code(run(Cli::parse().command))
}

fn run(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Demo(args) => cli::demo::run(args),
        Command::Model(args) => cli::model::run(args),
        Command::Excite(args) => cli::excite::run(args),
        Command::Identify(args) => cli::identify::run(args),
        Command::Diagnose(args) => cli::diagnose::run(args),
        Command::Force(args) => cli::force::run(args),
        Command::Simulate(args) => cli::simulate::run(args),
        Command::Daemon(args) => cli::daemon::run(args),
        Command::Ctl(args) => cli::ctl::run(args),
        Command::MockMotor(args) => cli::mock_motor::run(args),
    }
}
