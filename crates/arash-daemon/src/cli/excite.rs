//! `arash excite`: design the excitation trajectory (paper eqs. 18–20) and write it as JSON.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use arash_core::base_parameters::BaseParameterOptions;
use arash_core::control::fourier::{Excitation, DEFAULT_SAMPLE_RATE_HZ};
use arash_core::identify::excitation::{design_excitation, ExcitationOptions};
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
    /// Seed: the same seed gives the same trajectory.
    #[arg(long, default_value_t = ExcitationOptions::default().seed)]
    seed: u64,
    /// Acceleration limit per joint, comma-separated (rad/s² or m/s²); default 5 × speed limit/s.
    #[arg(long, value_delimiter = ',')]
    acceleration_limits: Option<Vec<f64>>,
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
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default())?;
    let options = ExcitationOptions {
        harmonics: args.harmonics,
        period_s: args.period,
        restarts: args.restarts,
        seed: args.seed,
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
    println!(
        "excitation: L = {}, T = {} s, normalised condition number κ = {:.3}; wrote {} ({samples} samples at {} Hz)",
        excitation.harmonics,
        excitation.period_s,
        excitation.condition_number,
        args.output.display(),
        args.rate
    );
    Ok(())
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
