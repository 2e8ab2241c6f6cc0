//! `arash force LOG... --model M [--frame F]`: the hand's force over logged runs, estimated from
//! the calibrated model (`arash_core::force_log`, docs/force.md). Writes the estimate with its σ
//! band and each sample's level (force.csv), the contacts and collisions found with what chose
//! each setting (report.txt), and a figure (force.png).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use arash_core::force::{Level, TorqueTiming, COLLISION_SIGMAS, CONTACT_SIGMAS};
use arash_core::force_log::{
    default_frame, estimate_force, Effort, ForceInput, ForceLog, ForceLogOptions, FrameChoice, Source, ThresholdChoice,
};
use arash_core::{Model, ModelFile};

use crate::report::figures::{panels, Panel};

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    runs: super::Runs,
    /// The model file (from `arash identify` or `arash diagnose`): its parameters, effects, band
    /// and held-out σ.
    #[arg(long)]
    model: PathBuf,
    /// The frame the force is wanted at (a link or a fixed frame of the URDF); default: the
    /// instrument tip where the robot has one (ARASH:ASiST), else none (joint torques only).
    #[arg(long)]
    frame: Option<String>,
    /// The frame the force's moment is taken about; default: the remote centre with the
    /// instrument tip, else the base.
    #[arg(long)]
    about: Option<String>,
    /// The observer's bandwidth (Hz), one or one per joint; default: the band the model's σ was
    /// measured in.
    #[arg(long, value_delimiter = ',')]
    bandwidth: Option<Vec<f64>>,
    /// Contact thresholds by hand, per joint (N·m, N); with --collision.
    #[arg(long, value_delimiter = ',', requires = "collision")]
    contact: Option<Vec<f64>>,
    /// Collision thresholds by hand, per joint (N·m, N); with --contact.
    #[arg(long, value_delimiter = ',', requires = "contact")]
    collision: Option<Vec<f64>>,
    /// Without --contact: contact at this many σ of the model's held-out residual.
    #[arg(long, default_value_t = CONTACT_SIGMAS)]
    contact_sigmas: f64,
    /// Without --collision: collision at this many σ.
    #[arg(long, default_value_t = COLLISION_SIGMAS)]
    collision_sigmas: f64,
    /// How the logged effort acted between samples: `held` (a command held until the next
    /// sample: `arash simulate`'s logs), `preceding` (a drive's report of the cycle that ended
    /// at its sample: the daemon's logs) or `sampled` (a sensor at its instant: CSV). Default:
    /// from the log.
    #[arg(long, value_parser = parse_timing)]
    timing: Option<TorqueTiming>,
    /// The logs hold motor currents (A), turned into torques by the model's drive gains.
    #[arg(long)]
    currents: bool,
    /// The estimate without the observer's lag, in the hand's band (5 Hz): for measuring a
    /// hand's force after the fact (docs/force.md). Contacts and collisions stay those the
    /// causal observer, the rig's, finds.
    #[arg(long)]
    zero_phase: bool,
    /// Directory for force.csv, report.txt and force.png.
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(mut args: Args) -> anyhow::Result<()> {
    if args.currents {
        args.runs.effort = crate::runlog::Effort::Current;
    }
    let (model, _) = args.runs.robot()?;
    let text = std::fs::read_to_string(&args.model).with_context(|| format!("reading {}", args.model.display()))?;
    let file = ModelFile::from_json(&text).with_context(|| format!("model {}", args.model.display()))?;
    anyhow::ensure!(
        file.parameter_names == model.parameter_names(),
        "{} is a model of `{}`, whose parameters are not those of the robot `{}` (--robot)",
        args.model.display(),
        file.robot_name,
        model.name
    );
    let log = args.runs.read(&args.runs.logs, &model)?;
    let options = options(&args, &model, &file, log.timing)?;
    let input = ForceInput { t: &log.t, q: &log.q, qd: None, effort: &log.tau };
    eprintln!("estimating the hand's force over {} samples ...", log.t.len());
    let result = estimate_force(&model, Source::File(&file), input, &options).context("estimating the force")?;
    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    let frame = result.frame.as_ref().map(|(f, _)| f.as_str());
    crate::report::write_atomically(&args.output.join("force.csv"), &csv(&model, &log.t, &result, frame))?;
    let report = report(&model, &log.t, &result);
    crate::report::write_atomically(&args.output.join("report.txt"), &report)?;
    figure(&args.output.join("force.png"), &model, &log.t, &result, frame)?;
    print!("{report}");
    println!("wrote force.csv, report.txt and force.png in {}", args.output.display());
    Ok(())
}

fn options(args: &Args, model: &Model, file: &ModelFile, logged: TorqueTiming) -> anyhow::Result<ForceLogOptions> {
    let n = model.dof();
    let per_joint = |name: &str, v: &[f64]| -> anyhow::Result<Vec<f64>> {
        match v.len() {
            1 => Ok(vec![v[0]; n]),
            m if m == n => Ok(v.to_vec()),
            m => anyhow::bail!("--{name} has {m} values; give one, or one per joint ({n})"),
        }
    };
    let frame = match (&args.frame, &args.about) {
        // The instrument tip's moment is wanted about the remote centre even when named alone.
        (Some(f), about) => Some(FrameChoice {
            frame: f.clone(),
            about: about.clone().or_else(|| default_frame(model).filter(|d| &d.frame == f).and_then(|d| d.about)),
        }),
        (None, Some(_)) => anyhow::bail!("--about needs --frame"),
        (None, None) => default_frame(model),
    };
    let thresholds = match (&args.contact, &args.collision) {
        (Some(c), Some(k)) => {
            ThresholdChoice::ByHand { contact: per_joint("contact", c)?, collision: per_joint("collision", k)? }
        }
        _ if file.held_out.is_some() => {
            ThresholdChoice::Sigma { contact: args.contact_sigmas, collision: args.collision_sigmas }
        }
        _ => {
            eprintln!(
                "note: {} records no held-out σ (identify with --validate, or diagnose), so no contact is told: give \
                 --contact and --collision in N·m and N",
                args.model.display()
            );
            ThresholdChoice::None
        }
    };
    Ok(ForceLogOptions {
        bandwidth_hz: args.bandwidth.as_deref().map(|b| per_joint("bandwidth", b)).transpose()?,
        frame,
        timing: args.timing.unwrap_or(logged),
        effort: if args.currents { Effort::Current } else { Effort::Torque },
        thresholds,
        zero_phase: args.zero_phase,
        ..Default::default()
    })
}

/// One row per sample: t, the joint estimate, the level, and at the frame the force, its σ, its
/// components in the frame's axes, its moment and whether it is singular.
fn csv(model: &Model, t: &[f64], result: &ForceLog, frame: Option<&str>) -> String {
    let (n, names) = (model.dof(), model.joint_names());
    let mut header: Vec<String> = vec!["t".into()];
    header.extend(names.iter().map(|j| format!("tau_ext.{j}")));
    header.extend(names.iter().map(|j| format!("sigma.{j}")));
    header.push("level".into());
    if frame.is_some() {
        for what in ["force", "sigma", "local", "moment"] {
            header.extend(["x", "y", "z"].iter().map(|a| format!("{what}.{a}")));
        }
        header.push("singular".into());
    }
    let mut out = header.join(",") + "\n";
    for (i, ti) in t.iter().enumerate() {
        let mut row = vec![format!("{ti}")];
        row.extend(result.tau_ext[i * n..(i + 1) * n].iter().map(|v| format!("{v:e}")));
        row.extend(result.sigma_joint.iter().map(|v| format!("{v:e}")));
        row.push(result.levels.get(i).map_or(String::new(), |l| level_name(*l).into()));
        if frame.is_some() {
            for series in [&result.force, &result.sigma, &result.local, &result.moment] {
                row.extend(series[i * 3..i * 3 + 3].iter().map(|v| format!("{v:e}")));
            }
            row.push(result.singular[i].to_string());
        }
        out += &(row.join(",") + "\n");
    }
    out
}

fn level_name(level: Level) -> &'static str {
    match level {
        Level::Free => "free",
        Level::Contact => "contact",
        Level::Collision => "collision",
    }
}

/// What chose each setting, the thresholds, and the contacts and collisions found.
fn report(model: &Model, t: &[f64], result: &ForceLog) -> String {
    let mut s = String::from("The hand's force, estimated from the model\n\n");
    for reason in &result.reasons {
        let _ = writeln!(s, "  {reason}");
    }
    if let Some((frame, about)) = &result.frame {
        let _ = writeln!(s, "  the force at `{frame}`, its moment about `{about}` (base frame)");
    }
    let names = model.joint_names();
    let Some(thresholds) = &result.thresholds else {
        s += "\nNo thresholds: no contact told.\n";
        return s;
    };
    s += "\nThresholds per joint (N·m or N): σ, contact, collision\n";
    for (k, name) in names.iter().enumerate() {
        let _ = writeln!(
            s,
            "  {name:<16} {:>10.3e} {:>10.3e} {:>10.3e}",
            result.sigma_joint[k],
            thresholds.contact()[k],
            thresholds.collision()[k]
        );
    }
    let collisions = result.episodes.iter().filter(|e| e.level == Level::Collision).count();
    let _ = writeln!(s, "\n{} episode(s) at contact or above, {collisions} reaching collision:", result.episodes.len());
    for e in &result.episodes {
        let _ = writeln!(s, "  {:>9.3} s – {:>9.3} s  {}", t[e.start], t[e.end.min(t.len()) - 1], level_name(e.level));
    }
    s
}

/// The force at the frame per axis with its ±σ band, or the joint estimate with its thresholds.
fn figure(path: &Path, model: &Model, t: &[f64], result: &ForceLog, frame: Option<&str>) -> anyhow::Result<()> {
    let n = model.dof();
    let column = |x: &[f64], width: usize, k: usize| x.iter().skip(k).step_by(width).copied().collect::<Vec<_>>();
    let band = |x: &[f64], s: &[f64], sign: f64| x.iter().zip(s).map(|(x, s)| x + sign * s).collect::<Vec<_>>();
    let mut all = Vec::new();
    match frame {
        Some(name) => {
            for (k, axis) in ["x", "y", "z"].iter().enumerate() {
                let (f, s) = (column(&result.force, 3, k), column(&result.sigma, 3, k));
                let series = vec![("+σ", t, band(&f, &s, 1.0)), ("−σ", t, band(&f, &s, -1.0)), ("force", t, f)];
                all.push(Panel { y_label: format!("{name} {axis} (N)"), series });
            }
        }
        None => {
            for (k, joint) in model.joint_names().iter().enumerate() {
                let estimate = column(&result.tau_ext, n, k);
                let mut series = vec![("estimate", t, estimate)];
                if let Some(th) = &result.thresholds {
                    series.push(("contact", t, vec![th.contact()[k]; t.len()]));
                    series.push(("collision", t, vec![th.collision()[k]; t.len()]));
                }
                all.push(Panel { y_label: format!("{joint} (N·m or N)"), series });
            }
        }
    }
    panels(path, "The hand's force, estimated from the model", "t (s)", &all)
}

fn parse_timing(text: &str) -> Result<TorqueTiming, String> {
    match text {
        "held" => Ok(TorqueTiming::Held),
        "preceding" => Ok(TorqueTiming::Preceding),
        "sampled" => Ok(TorqueTiming::Sampled),
        other => Err(format!("`{other}`: give held, preceding or sampled")),
    }
}
