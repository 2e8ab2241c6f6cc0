//! `arash mock-motor`: the simulated rig behind the motor protocol, on a pseudo-terminal.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use anyhow::Context;
use arash_core::sim::Scenario;
use arash_daemon::config::RtConfig;
use arash_daemon::drive_config::DriveConfig;
use arash_daemon::rt::clock::{setup_realtime, RtPolicy};
use arash_mock::{pseudo_terminal, FaultPlan, MockMotor};

#[derive(clap::Args)]
pub struct Args {
    /// Scenario of the simulated rig (TOML); default: the nominal rig.
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Fault plan (TOML, the fields of `FaultPlan`; see docs/daemon.md).
    #[arg(long)]
    faults: Option<PathBuf>,
    /// Override the scenario's seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Also make this path a symbolic link to the pseudo-terminal.
    #[arg(long)]
    link: Option<PathBuf>,
    /// The robot's URDF; default: the bundled ARASH:ASiST.
    #[arg(long)]
    robot: Option<PathBuf>,
    /// The drive's own watchdog (ms): while powered, it switches off and latches HOST_TIMEOUT
    /// after this long without a host frame.
    #[arg(long, default_value_t = 100)]
    watchdog_ms: u64,
    /// Start with the power stage on, holding these motor currents (A, one per joint, comma
    /// separated), as a drive left powered by a crashed host would.
    #[arg(long, value_delimiter = ',', num_args = 1..)]
    powered: Option<Vec<f64>>,
    /// Real-time set-up of the serving thread (SCHED_FIFO at the daemon's default priority, and
    /// mlockall): `ignore` tries it and serves without if refused; `require` refuses to start.
    #[arg(long, value_parser = <RtPolicy as std::str::FromStr>::from_str, default_value = "ignore")]
    rt: RtPolicy,
    /// Write the simulated rig's truth to this CSV file, a row per powered cycle: t, q, q̇, the
    /// motors' and the hand's joint torques, and the hand's force (SI, base frame).
    #[arg(long)]
    truth: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (model, _) = super::load_robot(args.robot.as_deref())?;
    let mut scenario = match &args.scenario {
        Some(p) => Scenario::load(p).with_context(|| format!("scenario {}", p.display()))?,
        None => Scenario::default(),
    };
    if let Some(seed) = args.seed {
        scenario.seed = seed;
    }
    let faults: FaultPlan = match &args.faults {
        Some(p) => toml::from_str(&std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?)
            .with_context(|| format!("fault plan {}", p.display()))?,
        None => FaultPlan::default(),
    };
    let mut motor = MockMotor::new(&model, &scenario, DriveConfig::default(), faults)?;
    motor.watchdog = std::time::Duration::from_millis(args.watchdog_ms);
    if let Some(path) = &args.truth {
        motor.record_truth(path)?;
    }
    if let Some(amps) = &args.powered {
        anyhow::ensure!(
            amps.len() == model.dof() && amps.iter().all(|a| a.is_finite()),
            "--powered takes {} finite currents (A), one per joint; got {amps:?}",
            model.dof()
        );
        motor.power_on(amps);
    }
    let (master, slave, path) = pseudo_terminal()?;
    if let Some(link) = &args.link {
        let _ = std::fs::remove_file(link);
        std::os::unix::fs::symlink(&path, link).with_context(|| format!("linking {}", link.display()))?;
    }
    // A drive does not stall. Served at ordinary priority on a loaded host, the mock can answer
    // several frames late, and the plant then runs open-loop on held commands: a rig fault the
    // real drive would not have (docs/daemon.md, "The mock motor").
    let priority = RtConfig::default().priority;
    let rt = setup_realtime(priority, args.rt).map_err(anyhow::Error::msg)?;
    // The slave stays open here so the master never sees a hang-up between daemon runs.
    println!("{path}");
    let scheduling = if rt.problems.is_empty() {
        format!("SCHED_FIFO priority {priority}, memory locked")
    } else {
        format!("without full real-time set-up: {}", rt.problems.join("; "))
    };
    eprintln!("arash mock-motor: serving {path} (scenario seed {}, {scheduling}); Ctrl-C to stop", scenario.seed);
    let stop = AtomicBool::new(false);
    let served = motor.serve(master, &stop);
    drop(slave);
    served
}
