//! `arash excite`: design the excitation trajectory (paper eqs. 18–20) and write it as JSON.

use arash_core::identify::options::ExcitationOptions;
use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use arash_core::base_parameters::BaseParameterOptions;
use arash_core::control::fourier::{Excitation, DEFAULT_SAMPLE_RATE_HZ};
use arash_core::identify::excitation::{design_excitation, sigma_factors, Coverage};
use arash_core::BaseParameters;
use serde::Serialize;

#[derive(clap::Args)]
pub struct Args {
    /// The robot's URDF; default: the bundled ARASH:ASiST.
    #[arg(long)]
    robot: Option<PathBuf>,
    /// Harmonics L.
    #[arg(long, default_value_t = ExcitationOptions::default().harmonics)]
    harmonics: usize,
    /// Base period T (s).
    #[arg(long, default_value_t = ExcitationOptions::default().period_s)]
    period: f64,
    /// Seeded optimiser restarts.
    #[arg(long, default_value_t = ExcitationOptions::default().restarts)]
    restarts: usize,
    /// Nelder–Mead iterations per restart.
    #[arg(long, default_value_t = ExcitationOptions::default().iterations)]
    iterations: u64,
    /// Seed: the same seed gives the same trajectory.
    #[arg(long, default_value_t = ExcitationOptions::default().seed)]
    seed: u64,
    /// Acceleration limit per joint, comma-separated (rad/s² or m/s²); default 5 × speed limit/s.
    #[arg(long, value_delimiter = ',')]
    acceleration_limits: Option<Vec<f64>>,
    /// Design for every base parameter, the weak ones too (those no trajectory within the limits
    /// separates; `arash model` lists them).
    #[arg(long)]
    keep_weak: bool,
    /// Sample rate of the written trajectory (Hz).
    #[arg(long, default_value_t = DEFAULT_SAMPLE_RATE_HZ)]
    rate: f64,
    /// Output file.
    #[arg(short, long)]
    output: PathBuf,
}

/// The trajectory file: coefficients, and one period sampled at `sample_rate_hz`.
#[derive(Serialize)]
struct TrajectoryFile<'a> {
    format: &'static str,
    robot: &'a str,
    joint_names: Vec<String>,
    #[serde(flatten)]
    excitation: &'a Excitation,
    sample_rate_hz: f64,
    t: Vec<f64>,
    /// One row per sample, one entry per joint (SI).
    q: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    qdd: Vec<Vec<f64>>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (model, _) = super::load_robot(args.robot.as_deref())?;
    let base = BaseParameters::compute(&model, &BaseParameterOptions::fitted(args.keep_weak))?;
    let options = ExcitationOptions {
        harmonics: args.harmonics,
        period_s: args.period,
        restarts: args.restarts,
        seed: args.seed,
        iterations: args.iterations,
        acceleration_limits: args.acceleration_limits,
        ..Default::default()
    };
    let started = std::time::Instant::now();
    let excitation = design_excitation(&model, &base, &options, &mut |p| {
        eprint!(
            "\rdesigning excitation: restart {}/{}, best normalised κ = {:.3}, {:.1} s   ",
            p.restart,
            p.restarts,
            p.best_condition_number,
            started.elapsed().as_secs_f64()
        );
        let _ = std::io::stderr().flush();
    })
    .context("designing the excitation")?;
    eprintln!();
    let samples = write(&args.output, &model, &excitation, args.rate)?;
    let limits = arash_core::identify::excitation::limits(&model, &options)?;
    let seconds = started.elapsed().as_secs_f64();
    print!("{}", summary(&model, &base, &excitation, &Coverage::of(&excitation, &limits), seconds));
    println!("wrote {} ({samples} samples at {} Hz)", args.output.display(), args.rate);
    Ok(())
}

/// The design's figures: κ both ways, what it means against the paper's, and each joint's motion.
fn summary(
    model: &arash_core::Model,
    base: &BaseParameters,
    excitation: &Excitation,
    coverage: &Coverage,
    seconds: f64,
) -> String {
    let mut s = format!(
        "excitation: L = {}, T = {} s, designed in {:.1} s\n",
        excitation.harmonics, excitation.period_s, seconds
    );
    s += &format!(
        "normalised condition number κ (σmax/σmin of the reduced regressor over one period, each column scaled to unit \
         norm):\n  over the {} base parameters designed for: {:.3}\n",
        base.rank, excitation.condition_number
    );
    if base.weak.is_empty() {
        s += &format!("  (no weak base parameter: {})\n", base.weak_report().trim_end());
    } else {
        s += &format!(
            "  with the weak ones kept ({}): {:.4e}\n",
            base.weak.iter().map(|w| w.name.as_str()).collect::<Vec<_>>().join(", "),
            excitation.condition_number_with_weak
        );
    }
    s +=
        "  the paper quotes 2.132 for its excitation without defining the normalisation or the parameter set; compare \
          with care (docs/identification.md)\n";
    s += &sigma_report(model, base, excitation);
    s += "joint motion over one period (range: share of the usable range; peak speed: share of the fastest the series can \
          reach over that range; moving: share of the period above a tenth of the peak speed):\n";
    for (j, joint) in model.joints.iter().enumerate() {
        s += &format!(
            "  {:<12} range {:>5.1} %   peak speed {:>5.1} %   moving {:>5.1} %\n",
            joint.name,
            100.0 * coverage.range_fraction[j],
            100.0 * coverage.speed_fraction[j],
            100.0 * coverage.moving_fraction[j]
        );
    }
    s
}

/// Each base parameter's σ factor (1 when its column is orthogonal to the others): the friction
/// and stiffness terms, which a joint that barely moves leaves in the noise, and the worst three.
fn sigma_report(model: &arash_core::Model, base: &BaseParameters, excitation: &Excitation) -> String {
    let Some(factors) = sigma_factors(model, base, excitation, ExcitationOptions::default().samples) else {
        return "σ factors: the regressor over one period has no full column rank\n".into();
    };
    let first_joint_term = model.layout().friction().start;
    let named = |i: usize| format!("{} {:.1}", base.names[i], factors[i]);
    let joint_terms: Vec<String> =
        (0..base.rank).filter(|&i| base.independent[i] >= first_joint_term).map(named).collect();
    let mut order: Vec<usize> = (0..base.rank).collect();
    order.sort_by(|a, b| factors[*b].total_cmp(&factors[*a]));
    format!(
        "σ factor per base parameter (√[(WₙᵀWₙ)⁻¹]ᵢᵢ: 1 when its column is orthogonal to the others):\n  friction and \
         stiffness: {}\n  largest: {}\n",
        joint_terms.join(", "),
        order.iter().take(3).map(|&i| named(i)).collect::<Vec<_>>().join(", ")
    )
}

/// Write the trajectory file: the coefficients, and one period sampled at `rate` Hz. Returns
/// the number of samples.
pub fn write(
    path: &std::path::Path,
    model: &arash_core::Model,
    excitation: &Excitation,
    rate: f64,
) -> anyhow::Result<usize> {
    let (t, q, qd, qdd) = excitation.sample(rate, 1);
    let file = TrajectoryFile {
        format: "arash-trajectory/1",
        robot: &model.name,
        joint_names: model.joint_names(),
        excitation,
        sample_rate_hz: rate,
        t,
        q: rows(&q, model.dof()),
        qd: rows(&qd, model.dof()),
        qdd: rows(&qdd, model.dof()),
    };
    crate::report::write_atomically(path, &serde_json::to_string(&file)?)?;
    Ok(file.t.len())
}

fn rows(x: &[f64], dof: usize) -> Vec<Vec<f64>> {
    x.chunks(dof).map(<[f64]>::to_vec).collect()
}
