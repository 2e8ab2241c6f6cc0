//! `arash model ROBOT.urdf`

use std::path::PathBuf;

use anyhow::Context;
use arash_core::base_parameters::BaseParameterOptions;
use arash_core::{BaseParameters, JointKind, Model};

#[derive(clap::Args)]
pub struct Args {
    /// The robot's URDF (mimic joints describe closed chains).
    urdf: PathBuf,
    /// Random states stacked to find the base parameters.
    #[arg(long, default_value_t = BaseParameterOptions::default().samples)]
    samples: usize,
    /// Seed of the state sampler.
    #[arg(long, default_value_t = BaseParameterOptions::default().seed)]
    seed: u64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (model, _) = super::load_robot(Some(&args.urdf))?;
    let options = BaseParameterOptions { samples: args.samples, seed: args.seed, ..Default::default() };
    let base = BaseParameters::compute(&model, &options).context("computing base parameters")?;
    print!("{}{}", describe(&model, &base), base.identifiable(&model, &options).weak_report());
    Ok(())
}

fn describe(model: &Model, base: &BaseParameters) -> String {
    let mut s = format!(
        "robot `{}`: {} dof, {} moving bodies\n\njoints (SI: rad, m; limits shown in degrees and mm):\n",
        model.name,
        model.dof(),
        model.bodies.len()
    );
    for j in &model.joints {
        let (scale, unit) =
            if j.kind == JointKind::Prismatic { (1e3, "mm") } else { (180.0 / std::f64::consts::PI, "°") };
        s += &format!(
            "  {:<12} {:<9} [{:>7.2}, {:>7.2}] {unit}  |q̇| ≤ {:.1} {unit}/s\n",
            j.name,
            format!("{:?}", j.kind).to_lowercase(),
            j.lower * scale,
            j.upper * scale,
            j.velocity * scale
        );
    }
    s += "\nbodies (mass, driven by):\n";
    for (b, body) in model.bodies.iter().enumerate() {
        let driver = match body.coupling {
            Some(c) if model.joints[c.index].body == b => "actuated".to_string(),
            Some(c) => format!("mimic {} × {} + {}", model.joints[c.index].name, c.multiplier, c.offset),
            None => "fixed".into(),
        };
        s += &format!("  {:<22} {:>7.4} kg  joint `{}` ({driver})\n", body.name, body.inertial[0], body.joint);
    }
    s += &format!(
        "\nstandard parameters: {} (10 × {} bodies + 3 × {} joints)\nbase parameters: p = {} (rank gap: kept ≥ {:.2e}, dropped ≤ {:.2e})\n",
        model.num_params(),
        model.bodies.len(),
        model.dof(),
        base.rank,
        base.rank_gap.0,
        base.rank_gap.1
    );
    for e in &base.expressions {
        s += &format!("  {e}\n");
    }
    s
}
