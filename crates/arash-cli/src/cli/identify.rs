//! `arash identify LOG... --robot ROBOT.urdf`: preprocess, fit, print Tables I and II, write the
//! model file.

use std::path::PathBuf;

use anyhow::Context;
use arash_core::base_parameters::BaseParameterOptions;
use arash_core::identify::closed_loop::{ClosedLoop, IvOptions, LoggedController};
use arash_core::identify::drive_gains::{Calibration, GainEstimator, KnownLoad};
use arash_core::identify::{
    cross_validate, held_out_residual, identify, identify_in_closed_loop, identify_with_known_load, validation_table,
    Declared, IdentifyOptions, Log,
};
use arash_core::identify::{ConsistentOptions, PreprocessOptions};
use arash_core::model_file::IdentifyMethod;

use arash_core::BaseParameters;

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    runs: super::Runs,
    /// ols, wls, consistent, or for a log recorded in closed loop idim-iv, didim and their
    /// -consistent forms (the loop simulated with the estimate; docs/identification.md).
    #[arg(long, default_value_t)]
    method: IdentifyMethod,
    /// The controller a closed-loop log ran (JSON, docs/identification.md), for the idim-iv and
    /// didim methods; default: the one the flight log names.
    #[arg(long)]
    controller: Option<PathBuf>,
    /// Fit every exact base parameter, the weak ones too; by default those no trajectory within
    /// the limits separates (`arash model` lists them) are regrouped into the others.
    #[arg(long)]
    keep_weak: bool,
    /// Most iterations of idim-iv and didim (each one simulation of the loop).
    #[arg(long, default_value_t = IvOptions::default().max_iterations)]
    iv_iterations: usize,
    /// Whole excitation periods in the training data (averaged); default: found from the data;
    /// 1 says the data are not periodic.
    #[arg(long)]
    periods: Option<usize>,
    /// The excitation period (s), when known but not how many periods the log holds.
    #[arg(long)]
    period: Option<f64>,
    /// Low-pass cut-off (Hz); default: the best fit over cut-offs around 5 × the highest
    /// frequency of the motion (docs/identification.md, "Preprocessing").
    #[arg(long)]
    cutoff: Option<f64>,
    /// Butterworth order (applied forward and backward).
    #[arg(long, default_value_t = PreprocessOptions::default().order)]
    order: usize,
    /// Cut-off of the velocity that switches Coulomb friction (Hz); default: chosen by the fit
    /// (docs/identification.md), kept within [cut-off, a quarter of the sample rate].
    #[arg(long)]
    friction_cutoff: Option<f64>,
    /// Keep every k-th sample after filtering.
    #[arg(long, default_value_t = PreprocessOptions::default().decimate)]
    decimate: usize,
    /// Pull toward CAD in the consistent fit, relative to the data.
    #[arg(long, default_value_t = ConsistentOptions::default().pull)]
    pull: f64,
    /// Validation runs (MCAP or CSV), each cross-validated like the paper's Table II.
    #[arg(long, num_args = 1..)]
    validate: Vec<PathBuf>,
    /// Whole periods in each validation run (averaged); default: found from the data; 1 for none.
    #[arg(long)]
    validate_periods: Option<usize>,
    /// Model file to write.
    #[arg(short, long)]
    output: PathBuf,
    /// Runs carrying a known load (--load), to calibrate from motor currents: the training logs
    /// and these then hold currents (A) in their tau.<joint> columns, and each joint's drive gain
    /// is fitted with the parameters (docs/currents.md).
    #[arg(long, num_args = 1.., requires = "load")]
    loaded: Vec<PathBuf>,
    /// The known load, a TOML or JSON file: body = "<link>", mass = <kg>, and where known
    /// com = [x, y, z] (m, in the link's frame) and inertia = [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]
    /// (kg·m², about the centre of mass).
    #[arg(long, requires = "loaded")]
    load: Option<PathBuf>,
    /// Gains from a datasheet, K:SIGMA per joint (e.g. 0.8:0.08,1.2:0.12,...), checked against
    /// the load's and used where the load does not fix a gain.
    #[arg(long, value_delimiter = ',', requires = "load", value_parser = parse_gain)]
    datasheet_gains: Option<Vec<(f64, f64)>>,
    /// How the gains are fitted: `current` (least squares of the residual in amperes) or `tls`
    /// (total least squares of the stacked system, Gautier and Briot's).
    #[arg(long, requires = "load", default_value = "current")]
    gains_fit: GainEstimator,
}

fn parse_gain(text: &str) -> Result<(f64, f64), String> {
    let bad = || format!("`{text}`: expected K:SIGMA such as 0.8:0.08");
    let (k, s) = text.split_once(':').ok_or_else(bad)?;
    Ok((k.trim().parse().map_err(|_| bad())?, s.trim().parse().map_err(|_| bad())?))
}

/// The known load of `--load`, by its extension: `.json` is JSON, anything else TOML.
fn read_load(path: &std::path::Path) -> anyhow::Result<KnownLoad> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading the load {}", path.display()))?;
    let json = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let parsed = match json {
        true => serde_json::from_str(&text).map_err(anyhow::Error::from),
        false => toml::from_str(&text).map_err(anyhow::Error::from),
    };
    parsed.with_context(|| format!("the load {}", path.display()))
}

pub fn run(mut args: Args) -> anyhow::Result<()> {
    if args.load.is_some() {
        args.runs.effort = crate::runlog::Effort::Current;
    }
    let options = IdentifyOptions {
        preprocess: PreprocessOptions {
            periods: args.periods,
            period_s: args.period,
            cutoff_hz: args.cutoff,
            order: args.order,
            decimate: args.decimate,
            friction_cutoff_hz: args.friction_cutoff,
            ..Default::default()
        },
        consistent: ConsistentOptions { pull: args.pull, ..Default::default() },
        iv: IvOptions { max_iterations: args.iv_iterations, ..Default::default() },
    };
    // A bad setting is refused by name before any log is read.
    options.preprocess.validate()?;
    options.consistent.validate()?;
    let (model, urdf) = args.runs.robot()?;
    let log = args.runs.read_training(&model)?;
    eprintln!("identifying from {} samples ({} file(s)) with {:?} ...", log.t.len(), args.runs.logs.len(), args.method);
    let base = BaseParameters::compute(&model, &BaseParameterOptions::fitted(args.keep_weak))?;
    let declared = Declared { model: &model, base: &base, urdf: &urdf };
    let data = Log { t: &log.t, q: &log.q, tau: &log.tau };
    let mut identification = match (&args.load, args.method.closed_loop()) {
        (Some(path), _) => {
            let load = read_load(path)?;
            let carried = args.runs.read(&args.loaded, &model)?;
            let runs = [(data, false), (Log { t: &carried.t, q: &carried.q, tau: &carried.tau }, true)];
            eprintln!("fitting the drive gains with a {} kg load on {} ...", load.mass, load.body);
            let calibration =
                Calibration { load: &load, datasheet: args.datasheet_gains.as_deref(), estimator: args.gains_fit };
            identify_with_known_load(declared, &runs, calibration, args.method, &options).map(|(file, _)| file)
        }
        (None, true) => {
            let (reference, controller) = closed_loop_of(&args, &log)?;
            let closed_loop = ClosedLoop::new(reference, &controller);
            identify_in_closed_loop(declared, data, closed_loop, args.method, &options)
        }
        (None, false) => identify(declared, data, args.method, &options),
    }
    .context("identification failed")?;
    identification.data.sources = args.runs.logs.iter().map(|p| p.display().to_string()).collect();
    identification.settings.reasons.splice(0..0, log.repairs.iter().cloned());
    for warning in &identification.settings.warnings {
        eprintln!("warning: {warning}");
    }
    println!("{}", identification.table());
    if !args.validate.is_empty() {
        let joints = model.joint_names();
        let mut labels = Vec::new();
        let mut fp = Vec::new();
        let mut held_out = Vec::new();
        for path in &args.validate {
            let v = args.runs.read(std::slice::from_ref(path), &model)?;
            let pre = PreprocessOptions { periods: args.validate_periods, order: args.order, ..Default::default() };
            let validation = cross_validate(&model, &identification, &v.t, &v.q, &v.tau, &pre)
                .with_context(|| format!("validating on {}", path.display()))?;
            if validation.cutoff_hz != identification.settings.cutoff_hz {
                eprintln!(
                    "note: {}: {}",
                    path.display(),
                    validation.reasons.last().map_or(String::new(), ToString::to_string)
                );
            }
            labels.push(path.file_stem().map_or("run".into(), |s| s.to_string_lossy().into_owned()));
            fp.push(validation.metrics.fp_percent);
            held_out.push(v);
        }
        println!("Cross-validation (FP% per joint, one column per run):\n{}", validation_table(&joints, &labels, &fp));
        let runs: Vec<(&str, Log)> = labels
            .iter()
            .zip(&held_out)
            .map(|(label, v)| (label.as_str(), Log { t: &v.t, q: &v.q, tau: &v.tau }))
            .collect();
        let mut residual =
            held_out_residual(&model, &identification, &runs, args.order).context("the held-out residual")?;
        println!("Held-out residual RMS per joint: {}", rms_line(&joints, &residual.rms));
        let timing = held_out.first().map_or(arash_core::force::TorqueTiming::Sampled, |v| v.timing);
        let observer = arash_core::force_log::observer_held_out(&model, &identification, &runs, timing)
            .context("the force observer on the held-out runs")?;
        println!(
            "Force observer on the held-out runs: bandwidth {:?} Hz, σ (the force estimate's) {}",
            observer.bandwidth_hz,
            rms_line(&joints, &observer.sigma)
        );
        residual.observer = Some(observer);
        identification.held_out = Some(residual);
    }
    crate::report::write_atomically(&args.output, &identification.to_json())?;
    println!("wrote {}", args.output.display());
    Ok(())
}

/// The closed loop of the one log the idim-iv and didim methods take: its reference and the controller
/// (`--controller`, or the one the log names). Whatever is missing is named, with the methods
/// that still work.
fn closed_loop_of<'a>(
    args: &Args,
    log: &'a crate::runlog::Log,
) -> anyhow::Result<(&'a [Vec<f64>; 3], LoggedController)> {
    let method = args.method;
    let fallback = "ols, wls and consistent work on the log alone";
    if let [_, _, ..] = args.runs.logs.as_slice() {
        anyhow::bail!("--method {method} simulates one closed-loop run: give one log, not {}", args.runs.logs.len());
    }
    let path = args.runs.logs[0].display();
    let Some(channels) = &log.closed_loop else {
        anyhow::bail!(
            "--method {method} needs the reference the controller followed: {path} has no q_des, qd_des and qdd_des \
             (a CSV log needs q_des.<joint>, qd_des.<joint> and qdd_des.<joint> columns); {fallback}"
        );
    };
    let controller = match &args.controller {
        Some(file) => {
            let text = std::fs::read_to_string(file).with_context(|| format!("reading {}", file.display()))?;
            LoggedController::from_json(&text).with_context(|| format!("--controller {}", file.display()))?
        }
        None => channels.controller.clone().map_err(|why| {
            anyhow::anyhow!("--method {method} needs the controller that ran the log: {why}; {fallback}")
        })?,
    };
    Ok((&channels.reference, controller))
}

/// `name value, …`, each value in scientific notation.
fn rms_line(joints: &[String], rms: &[f64]) -> String {
    joints.iter().zip(rms).map(|(j, r)| format!("{j} {r:.4e}")).collect::<Vec<_>>().join(", ")
}
