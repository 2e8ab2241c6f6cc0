//! `arash simulate`: run the simulated rig with a controller on a trajectory and write the
//! flight log.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use arash_core::control::gains::PaperUnits;
use arash_core::control::{RobustGains, Trajectory};
use arash_core::diagnose::EffectTerm;
use arash_core::flightlog::LogWriter;
use arash_core::model_file::ModelFile;
use arash_core::sim::{named_parameters, ControllerChoice, RunSpec, Scenario};
use arash_core::Model;
use indicatif::{ProgressBar, ProgressStyle};

#[derive(clap::Args)]
pub struct Args {
    /// Scenario file (TOML); see scenarios/ and docs/simulator.md.
    #[arg(long)]
    scenario: PathBuf,
    /// Trajectory file (arash-trajectory/1 JSON): `arash excite` output or trajectories/*.json.
    #[arg(long)]
    trajectory: PathBuf,
    /// pd (PD plus gravity; CAD unless --params), idc-cad (inverse dynamics with CAD: the
    /// paper's baseline), idc (inverse dynamics with --params) or robust (eq. 22; default
    /// parameters: truth).
    #[arg(long)]
    controller: ControllerChoice,
    /// The controller's parameters: `cad`, `truth` (the simulated robot's own) or a model file
    /// written by `arash identify`.
    #[arg(long)]
    params: Option<String>,
    /// Reading of the paper's K_d: si, deg-mm or deg-cm (see docs/simulator.md).
    #[arg(long, default_value = "si")]
    gain_units: PaperUnits,
    /// Seconds of rig time; default: 20 periods of an excitation, one of a validation trajectory.
    #[arg(long)]
    duration: Option<f64>,
    /// Also log the simulator's ground truth (true q, q̇, q̈, applied torque) on /arash/truth.
    #[arg(long)]
    truth: bool,
    /// Override the scenario's seed.
    #[arg(long)]
    seed: Option<u64>,
    /// The robot's URDF (the CAD model; the truth derives from it); default: the bundled ARASH:ASiST.
    #[arg(long)]
    robot: Option<PathBuf>,
    /// Flight log to write (MCAP).
    #[arg(short, long)]
    output: PathBuf,
}

/// The controller's parameter source, its parameters, and the effects a diagnosis added to them.
type ControllerParameters = (String, Vec<f64>, Vec<EffectTerm>);

fn controller_parameters(args: &Args, model: &Model, scenario: &Scenario) -> anyhow::Result<ControllerParameters> {
    let Some(source) = args.params.as_deref().or(args.controller.default_params()) else {
        bail!("--controller idc needs --params cad|truth|MODEL.json");
    };
    args.controller.check_params(source).map_err(anyhow::Error::msg)?;
    let (params, effects) = match named_parameters(model, scenario, source) {
        Some(params) => (params, vec![]),
        None => {
            let text = std::fs::read_to_string(source).with_context(|| format!("reading model file {source}"))?;
            let identification = ModelFile::from_json(&text).with_context(|| format!("loading {source}"))?;
            let params = identification.controller_parameters(model).with_context(|| format!("using {source}"))?;
            (params, identification.effects)
        }
    };
    Ok((source.to_string(), params, effects))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (model, urdf) = super::load_robot(args.robot.as_deref())?;
    let mut scenario =
        Scenario::load(&args.scenario).with_context(|| format!("scenario {}", args.scenario.display()))?;
    if let Some(seed) = args.seed {
        scenario.seed = seed;
    }
    scenario.validate(model.dof()).with_context(|| format!("scenario {}", args.scenario.display()))?;
    let text = std::fs::read_to_string(&args.trajectory)
        .with_context(|| format!("reading trajectory {}", args.trajectory.display()))?;
    let trajectory = Trajectory::from_json(&text, model.dof())
        .with_context(|| format!("trajectory {}", args.trajectory.display()))?;
    let (params_source, params, effects) = controller_parameters(&args, &model, &scenario)?;
    let spec = RunSpec {
        duration_s: args.duration.unwrap_or_else(|| trajectory.default_duration()),
        scenario,
        trajectory,
        controller: args.controller.kind(),
        params_source,
        params,
        effects,
        gains: RobustGains::from_paper(&model, args.gain_units).ok(),
    };
    simulate(&model, &urdf, &spec, &args.output, args.truth)
}

/// Simulate into `output.part` and rename it when the run is complete, so that a failed or
/// interrupted run never leaves a file that looks finished.
fn simulate(model: &Model, urdf: &str, spec: &RunSpec, output: &Path, with_truth: bool) -> anyhow::Result<()> {
    let mut part = output.as_os_str().to_owned();
    part.push(".part");
    let part = PathBuf::from(part);
    let result = simulate_into(model, urdf, spec, &part, with_truth);
    match result {
        Ok(()) => std::fs::rename(&part, output).with_context(|| format!("renaming {}", part.display()))?,
        Err(e) => {
            let _ = std::fs::remove_file(&part);
            return Err(e);
        }
    }
    eprintln!(
        "wrote {} ({:.1} MB)",
        output.display(),
        std::fs::metadata(output).map(|m| m.len() as f64 / 1e6).unwrap_or(0.0)
    );
    Ok(())
}

fn simulate_into(model: &Model, urdf: &str, spec: &RunSpec, output: &Path, with_truth: bool) -> anyhow::Result<()> {
    let mut rig = spec.rig(model)?;
    let mut log = LogWriter::create(output, &spec.log_header(model, urdf, with_truth), spec.scenario.physics.rate_hz)?;
    let cycles = spec.cycles();
    let bar = ProgressBar::new(cycles as u64).with_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {percent:>3}% rig time {pos}/{len} ms, eta {eta}")
            .expect("a valid template")
            .progress_chars("=> "),
    );
    bar.set_message(format!("simulating {}", spec.scenario.name));
    let started = std::time::Instant::now();
    let mut worst_faults = arash_core::control::Faults::NONE;
    for i in 0..cycles {
        rig.step().with_context(|| format!("cycle {i}"))?;
        log.write_cycle(rig.record())?;
        if with_truth {
            log.write_truth(rig.truth())?;
        }
        worst_faults |= rig.record().faults;
        if i % 1000 == 999 {
            bar.set_position(i as u64 + 1);
        }
    }
    bar.finish_and_clear();
    log.finish()?;
    let elapsed = started.elapsed().as_secs_f64();
    eprintln!(
        "simulated {:.1} s of rig time in {:.2} s ({:.0}× real time)",
        spec.duration_s,
        elapsed,
        spec.duration_s / elapsed
    );
    if !worst_faults.is_empty() {
        eprintln!("warning: the safety gate latched a fault: {}", worst_faults.names().join(", "));
    }
    Ok(())
}
