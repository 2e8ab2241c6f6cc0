//! `arash diagnose LOG... --robot ROBOT.urdf [--model model.json] [--validate LOG...]`: find what
//! the declared model lacks, and write the report, the JSON, the figures and the updated model.

use std::path::{Path, PathBuf};

use anyhow::Context;
use arash_core::base_parameters::BaseParameterOptions;
use arash_core::diagnose::{consistent_with_effects, diagnose, DiagnoseOptions, Diagnosis, EffectKind, Start};
use arash_core::identify::{ConsistentOptions, PreprocessOptions};
use arash_core::identify::{Declared, Log};
use arash_core::model_file::ModelFile;
use arash_core::BaseParameters;

use crate::report::figures;
use arash_daemon::drive_config::DriveConfig;

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    runs: super::Runs,
    /// A model file (from `arash identify` or an earlier diagnosis) to diagnose against; its
    /// inertial parameters are held, friction is refitted and kept where it predicts the held-out
    /// data better. No joint ends worse than this model on held-out data. Default: the model
    /// `arash identify` makes of the training log (see --from-identified).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Without --model (the default): start from the model `arash identify` makes of the
    /// training log, its parameters refitted with the effects, or held where that predicts a
    /// joint of a held-out run worse (docs/diagnosis.md, "Where it starts").
    #[arg(long, conflicts_with_all = ["model", "from_declared"])]
    from_identified: bool,
    /// Without --model: start from the declared model refitted on the log at the diagnosis's
    /// band instead.
    #[arg(long, conflicts_with = "model")]
    from_declared: bool,
    /// With --model: refit all its base parameters too.
    #[arg(long, conflicts_with = "hold_friction")]
    refit: bool,
    /// With --model: hold its friction too (trust the whole model file).
    #[arg(long)]
    hold_friction: bool,
    /// Held-out runs for ranking and the held-out errors (joined, each filtered on its own);
    /// default: the odd blocks of the training data.
    #[arg(long, num_args = 1..)]
    validate: Vec<PathBuf>,
    /// Joint motion per motor radian, comma-separated, for the cogging search; default: from
    /// `--gear-ratios` (1/|ratio|), else the bundled ARASH:ASiST drive's, or no cogging search
    /// for another robot.
    #[arg(long, value_delimiter = ',')]
    transmission: Option<Vec<f64>>,
    /// Low-pass cut-off, the diagnosis's band (Hz), in (0, fs/2); default: chosen from the data,
    /// the widest in which the declared model predicts held-out torque as well as in the best
    /// (docs/diagnosis.md, "The band"). Set, the report says when it predicts worse than that.
    #[arg(long)]
    cutoff: Option<f64>,
    /// Cut-off of the velocity that switches Coulomb friction (Hz); default: the band, slower
    /// where the encoder's steps would make up more than 0.25 % of a joint's RMS speed
    /// (docs/diagnosis.md, "The friction velocity").
    #[arg(long)]
    friction_cutoff: Option<f64>,
    /// Butterworth order (applied forward and backward).
    #[arg(long, default_value_t = PreprocessOptions::default().order)]
    order: usize,
    /// Length of the blocks of time of the held-out split without --validate (s).
    #[arg(long, default_value_t = DiagnoseOptions::default().block_s)]
    block: f64,
    /// Length of the Wald test's batches (s); default: each test chooses from its own scores,
    /// by blocking (docs/diagnosis.md).
    #[arg(long)]
    batch: Option<f64>,
    /// Family-wise error rate per search round (Holm).
    #[arg(long, default_value_t = DiagnoseOptions::default().alpha)]
    alpha: f64,
    /// Smallest cut of a joint's held-out squared error worth a term (fraction).
    #[arg(long, default_value_t = DiagnoseOptions::default().min_gain)]
    min_gain: f64,
    /// Search only these effects (comma-separated identifiers; see docs/diagnosis.md).
    #[arg(long, value_delimiter = ',')]
    effects: Option<Vec<String>>,
    /// The logged torque was computed from motor currents: also search a drive gain error per
    /// joint (drive_gain; a torque constant or current scale that is off).
    #[arg(long)]
    torque_from_currents: bool,
    /// The logs hold motor currents (A) in their tau.<joint> columns, and the --model was
    /// calibrated from currents with a known load: each joint's torque is its calibrated drive
    /// gain times its current, and a gain that changed since (a new motor, a sensor) is searched
    /// as drive_gain (docs/currents.md).
    #[arg(long, requires = "model")]
    currents: bool,
    /// Also fit the physically consistent model together with the effects found and write it
    /// as model_consistent.json: the model the model-based controllers accept.
    #[arg(long)]
    consistent: bool,
    /// Low-pass cut-off (Hz) of that fit; default: --cutoff. The calibration's own cut-off (in
    /// its model file as settings.cutoff_hz) gives the controller a model that sees the data as
    /// the calibrated one did. Its friction columns switch with the diagnosis's friction
    /// velocity, on which the effects were found (or --friction-cutoff).
    #[arg(long, requires = "consistent")]
    consistent_cutoff: Option<f64>,
    /// Directory for report.txt, diagnosis.json, model.json and the figures.
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(mut args: Args) -> anyhow::Result<()> {
    if args.currents {
        args.runs.effort = crate::runlog::Effort::Current;
    }
    let (model, urdf) = args.runs.robot()?;
    anyhow::ensure!(
        args.model.is_some() || !(args.refit || args.hold_friction),
        "--refit and --hold-friction apply to a model given with --model"
    );
    let options = options(&args, &model)?;
    let read = |paths: &[PathBuf]| args.runs.read(paths, &model);
    let train = args.runs.read_training(&model)?;
    let mut validation = if args.validate.is_empty() { None } else { Some(read(&args.validate)?) };
    let given = args
        .model
        .as_ref()
        .map(|p| -> anyhow::Result<ModelFile> {
            let text = std::fs::read_to_string(p).with_context(|| format!("reading model {}", p.display()))?;
            ModelFile::from_json(&text).with_context(|| format!("model {}", p.display()))
        })
        .transpose()?;
    let mut train = train;
    if args.currents {
        let gains = given.as_ref().and_then(|g| g.drive_gains.as_ref()).with_context(|| {
            "--currents needs a --model calibrated from currents with a known load (arash identify --loaded --load)"
        })?;
        for log in std::iter::once(&mut train).chain(validation.as_mut()) {
            log.tau.iter_mut().enumerate().for_each(|(i, c)| *c *= gains.gains[i % gains.gains.len()]);
        }
    }
    eprintln!(
        "diagnosing {} samples ({} file(s)){} ...",
        train.t.len(),
        args.runs.logs.len(),
        validation.as_ref().map_or(String::new(), |v| format!(", holding out {} samples", v.t.len()))
    );
    let started = std::time::Instant::now();
    // A given model names its base parameters (the default ones, or the exact ones it kept).
    let base = match &given {
        Some(g) => BaseParameters::with_independent(&model, &g.base_independent)?,
        None => None,
    };
    let base = base.map_or_else(|| BaseParameters::compute(&model, &BaseParameterOptions::diagnosed()), Ok)?;
    let diagnosis = diagnose(
        Declared { model: &model, base: &base, urdf: &urdf },
        Log { t: &train.t, q: &train.q, tau: &train.tau },
        validation.as_ref().map(crate::runlog::Log::runs),
        given.as_ref(),
        &options,
    )
    .context("diagnosis failed")?;
    let mut diagnosis = diagnosis;
    // The consistent refit works in the diagnosed model's base parameters (a given model's).
    let base = match diagnosis.model.base_independent == base.independent {
        true => base,
        false => BaseParameters::with_independent(&model, &diagnosis.model.base_independent)?
            .context("the diagnosed model's base parameters are neither the exact nor the regrouped ones")?,
    };
    let repairs = train.repairs.iter().chain(validation.iter().flat_map(|v| &v.repairs));
    diagnosis.settings.reasons.splice(0..0, repairs.cloned());
    eprintln!("diagnosed in {:.1} s", started.elapsed().as_secs_f64());
    let report = diagnosis.report();
    println!("{report}");
    write_outputs(&args.output, &diagnosis, &report)?;
    if args.consistent {
        let train = Log { t: &train.t, q: &train.q, tau: &train.tau };
        let main_hz = args.consistent_cutoff.unwrap_or(diagnosis.settings.cutoff_hz);
        let (refit, _) = write_consistent(&args.output, &model, &base, train, &diagnosis, &options, main_hz)?;
        println!("{}", consistent_summary(&refit, &model.joint_names()));
    }
    println!("wrote {}/ (report.txt, diagnosis.json, model.json, figures)", args.output.display());
    Ok(())
}

/// The diagnosis's settings from the command line, whose defaults are `DiagnoseOptions::default`.
fn options(args: &Args, model: &arash_core::Model) -> anyhow::Result<DiagnoseOptions> {
    let mut options = DiagnoseOptions {
        preprocess: PreprocessOptions {
            cutoff_hz: args.cutoff,
            friction_cutoff_hz: args.friction_cutoff,
            order: args.order,
            ..PreprocessOptions::default()
        },
        block_s: args.block,
        batch_s: args.batch,
        alpha: args.alpha,
        min_gain: args.min_gain,
        torque_from_currents: args.torque_from_currents || args.currents,
        ..DiagnoseOptions::default()
    };
    if let Some(ids) = &args.effects {
        options.effects = EffectKind::parse_list(ids).context("--effects")?;
    }
    options.transmission = match &args.transmission {
        Some(t) => Some(t.clone()),
        None if model.name == arash_core::arash_asist().name => Some(DriveConfig::default().transmission),
        None => None,
    };
    options.motors = args.runs.transmission(model.dof())?;
    options.refit = args.refit;
    options.hold_friction = args.hold_friction;
    if args.from_identified {
        options.start = Start::Identified;
    }
    if args.from_declared {
        options.start = Start::Declared;
    }
    options.validate(model.dof())?;
    if let Some(v) = args.consistent_cutoff {
        anyhow::ensure!(v.is_finite() && v > 0.0, "--consistent-cutoff must be positive, not {v}");
    }
    Ok(options)
}

/// Fit the physically consistent model together with the effects `diagnosis` found, on `train`
/// filtered at `main_hz` (the friction velocity the diagnosis's, unless the options set one),
/// and write it to `dir/model_consistent.json`; returns it and the path.
pub fn write_consistent(
    dir: &Path,
    model: &arash_core::Model,
    base: &BaseParameters,
    train: Log,
    diagnosis: &Diagnosis,
    options: &DiagnoseOptions,
    main_hz: f64,
) -> anyhow::Result<(ModelFile, PathBuf)> {
    let preprocess = PreprocessOptions { cutoff_hz: Some(main_hz), ..options.preprocess.clone() };
    let options = DiagnoseOptions { preprocess, ..options.clone() };
    let refit = consistent_with_effects(model, base, train, &diagnosis.model, &options, &ConsistentOptions::default())
        .context("the consistent fit with the effects found failed")?;
    let path = dir.join("model_consistent.json");
    crate::report::write_atomically(&path, &refit.to_json())?;
    Ok((refit, path))
}

/// One paragraph on the consistent refit: its fit and its effects' coefficients.
pub fn consistent_summary(refit: &ModelFile, joint_names: &[String]) -> String {
    let fp: Vec<String> = refit.fitted.training.fp_percent.iter().map(|f| format!("{f:.2}")).collect();
    let worst = refit.fitted.min_pseudo_inertia_eigenvalue.iter().copied().fold(f64::INFINITY, f64::min);
    let mut s = format!(
        "The physically consistent model fitted with the effects found: training FP% {}, smallest pseudo-inertia eigenvalue {worst:.3e}",
        fp.join(" / ")
    );
    for term in &refit.effects {
        let coefficients: Vec<String> = term.coefficients.iter().map(|c| format!("{c:.4e}")).collect();
        s += &format!("\n  {}: {}", term.describe(joint_names), coefficients.join(", "));
    }
    s
}

/// Write report.txt, diagnosis.json, model.json and the figures into `dir`.
pub fn write_outputs(dir: &Path, diagnosis: &Diagnosis, report: &str) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    crate::report::write_atomically(&dir.join("report.txt"), report)?;
    crate::report::write_atomically(&dir.join("diagnosis.json"), &diagnosis.to_json())?;
    crate::report::write_atomically(&dir.join("model.json"), &diagnosis.model.to_json())?;
    for path in write_figures(dir, diagnosis)? {
        eprintln!("figure {}", path.display());
    }
    Ok(())
}

/// The figures: per accepted effect and joint, the residual against the variable the effect
/// depends on, with the effect (before) and without it (after); and the held-out FP% per joint
/// before and after.
pub fn write_figures(dir: &Path, d: &Diagnosis) -> anyhow::Result<Vec<PathBuf>> {
    let s = &d.series;
    let dof = d.joint_names.len();
    let mut written = Vec::new();
    let errors = dir.join("errors.png");
    figures::bars_before_after(
        &errors,
        "Held-out FP% per joint, before and after the effects found",
        "FP% (held-out)",
        &d.joint_names,
        &d.before.heldout.fp_percent,
        &d.after.heldout.fp_percent,
    )?;
    written.push(errors);
    for (i, finding) in d.accepted.iter().enumerate().filter(|(_, f)| f.term.kind != EffectKind::Delay) {
        let Some(contribution) = s.contributions.get(effect_index(d, i)) else { continue };
        for &k in &finding.joints {
            let column = |x: &[f64]| x.iter().skip(k).step_by(dof).copied().collect::<Vec<f64>>();
            let (position, torque) = if d.prismatic[k] { ("m", "N") } else { ("rad", "N·m") };
            let name = &d.joint_names[k];
            let (label, x) = match finding.term.kind.plotted_against() {
                "t" => ("t (s)".to_string(), s.t.clone()),
                "qd" => (format!("q̇ of {name} ({position}/s)"), column(&s.qd)),
                "qdd" => (format!("q̈ of {name} ({position}/s²)"), column(&s.qdd)),
                "tau" => (format!("measured torque of {name} ({torque})"), column(&s.tau)),
                _ => (format!("q of {name} ({position})"), column(&s.q)),
            };
            let after = column(&s.residual_after);
            let before: Vec<f64> = after.iter().zip(column(contribution)).map(|(a, c)| a + c).collect();
            let path = dir.join(format!("effect-{}-{}-{}.png", i + 1, finding.name, name));
            let title = format!("{}: {name}'s residual with it (before) and without", finding.label);
            let y_label = format!("residual ({torque})");
            figures::scatter_before_after(&path, &title, &label, &y_label, &x, &before, &after)?;
            written.push(path);
        }
    }
    Ok(written)
}

/// Index of accepted effect `i` among those with a contribution series (the delay has none).
fn effect_index(d: &Diagnosis, i: usize) -> usize {
    d.accepted[..i].iter().filter(|f| f.term.kind != EffectKind::Delay).count()
}
