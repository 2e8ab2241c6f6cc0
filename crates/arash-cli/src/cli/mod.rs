pub mod ctl;
pub mod daemon;
pub mod demo;
pub mod diagnose;
pub mod excite;
pub mod force;
pub mod identify;
pub mod mock_motor;
pub mod model;
pub mod simulate;

use anyhow::Context;
use arash_core::transmission::Transmission;

/// The logged runs a command reads and the robot they come from.
#[derive(clap::Args)]
pub struct Runs {
    /// Logged runs (MCAP flight logs, or CSV with columns t, q.<joint>, tau.<joint>), concatenated in order.
    #[arg(required = true)]
    pub logs: Vec<std::path::PathBuf>,
    /// The robot's URDF; default: the bundled ARASH:ASiST.
    #[arg(long)]
    pub robot: Option<std::path::PathBuf>,
    /// Declare every joint's Coulomb law as tanh(q̇/ε) with this ε (rad/s or m/s); the simulated
    /// rig's law is tanh with ε = 0.001. Without it (or --friction-velocity) each joint's law is
    /// chosen from the data. A model file records the laws it was fitted with, and `arash
    /// diagnose --model` uses the file's.
    #[arg(long, conflicts_with = "friction_velocity")]
    pub coulomb_epsilon: Option<f64>,
    /// Declare each joint's Coulomb law: its friction velocity v of tanh(q̇/v) (rad/s or m/s), or
    /// `sign`, one per joint (e.g. sign,0.01,0.002).
    #[arg(long, value_delimiter = ',')]
    pub friction_velocity: Option<Vec<String>>,
    /// The logs are motor-side: motor radians per joint radian, one per joint (the TX40's
    /// 32,32,45,-48,45,32). Angles map to q = R⁻¹θ + q₀, torques to τ = Rᵀτ_m (docs/real-data.md).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub gear_ratios: Option<Vec<f64>>,
    /// A motor that another joint turns too, as MOTOR,JOINT,RATIO (1-based; the TX40's wrist:
    /// 6,5,32). Repeat for more.
    #[arg(long, requires = "gear_ratios", value_parser = parse_coupling)]
    pub coupling: Vec<(usize, usize, f64)>,
    /// Joint angle offsets q₀ of a motor-side log (degrees), one per joint.
    #[arg(long, value_delimiter = ',', requires = "gear_ratios", allow_negative_numbers = true)]
    pub joint_offsets_deg: Option<Vec<f64>>,
    /// Repair each log before use: trim a block at either end that is not finite, steps back in
    /// time or follows a gap, and resample stamps that are not one uniform stream onto a uniform
    /// grid (docs/identification.md, "Logs as controllers write them"). What was done is printed
    /// and recorded among the model file's reasons. Off, such a log is refused.
    #[arg(long)]
    pub repair: bool,
    /// What the logs are read as: torques, or currents for a calibration from them (set by the
    /// command: `identify --load`, `diagnose --currents`).
    #[arg(skip = crate::runlog::Effort::Torque)]
    pub effort: crate::runlog::Effort,
}

impl Runs {
    /// The robot these runs come from (`--robot`), with its declared Coulomb law, and its URDF.
    pub fn robot(&self) -> anyhow::Result<(arash_core::Model, String)> {
        let (mut model, urdf) = load_robot(self.robot.as_deref())?;
        let dof = model.dof();
        if let Some(epsilon) = self.coulomb_epsilon {
            let shape = arash_core::model::CoulombShape::tanh(epsilon)
                .with_context(|| format!("--coulomb-epsilon must be positive, not {epsilon}"))?;
            model.coulomb_laws = arash_core::CoulombLaws::uniform(shape, dof);
        }
        if let Some(given) = &self.friction_velocity {
            anyhow::ensure!(
                given.len() == dof,
                "--friction-velocity needs {dof} values, one per joint; got {}",
                given.len()
            );
            let velocities = given
                .iter()
                .map(|v| match v.trim() {
                    "sign" => Ok(None),
                    v => v
                        .parse::<f64>()
                        .map(Some)
                        .with_context(|| format!("--friction-velocity: `{v}` is not a number or `sign`")),
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
            model.coulomb_laws = arash_core::CoulombLaws::of_velocities(&velocities).map_err(|(k, v)| {
                anyhow::anyhow!(
                    "--friction-velocity of joint {} must be positive and finite (or `sign`), not {v}",
                    k + 1
                )
            })?;
        }
        Ok((model, urdf))
    }

    /// The declared transmission of motor-side logs, if any.
    pub fn transmission(&self, dof: usize) -> anyhow::Result<Option<Transmission>> {
        let Some(ratios) = &self.gear_ratios else { return Ok(None) };
        let offsets = self.joint_offsets_deg.as_ref().map(|d| d.iter().map(|v| v.to_radians()).collect::<Vec<_>>());
        Transmission::new(dof, ratios, &self.coupling, offsets.as_deref()).context("--gear-ratios/--coupling").map(Some)
    }

    /// Read `paths` (the training logs or validation runs), mapped to joint space when the logs
    /// are motor-side, and concatenate them.
    pub fn read(&self, paths: &[std::path::PathBuf], model: &arash_core::Model) -> anyhow::Result<crate::runlog::Log> {
        let transmission = self.transmission(model.dof())?;
        let mut logs = Vec::with_capacity(paths.len());
        for path in paths {
            let mut log = crate::runlog::read(path, model, self.repair, self.effort)?;
            if self.repair {
                let (repaired, report) = log.repaired().with_context(|| format!("repairing {}", path.display()))?;
                for line in &report {
                    eprintln!("note: {}: {line}", path.display());
                }
                log = repaired;
                log.repairs = report.into_iter().map(|r| r.of_log(&path.display().to_string())).collect();
            }
            if let Some(t) = &transmission {
                (log.q, log.tau) = t.to_joints(&log.q, &log.tau).with_context(|| format!("{}", path.display()))?;
            }
            logs.push(log);
        }
        Ok(crate::runlog::concatenate(logs))
    }

    /// Read the training logs: as [`Self::read`], with a warning where the robot moved between
    /// two of them (a fit filters them as one series, and the filter rings across the jump).
    pub fn read_training(&self, model: &arash_core::Model) -> anyhow::Result<crate::runlog::Log> {
        let log = self.read(&self.logs, model)?;
        let names = model.joint_names();
        for (sample, joint, jump) in log.jumps() {
            eprintln!(
                "warning: the training logs are joined end to end and {} jumps by {jump:.3e} at sample {sample}, where \
                 a run starts: the filter rings across it and the samples around it fit badly. Fit one log (or \
                 logs that continue one another) and hold out the others with --validate, which filters each alone.",
                names[joint]
            );
        }
        Ok(log)
    }
}

fn parse_coupling(text: &str) -> Result<(usize, usize, f64), String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let bad = || format!("`{text}`: expected MOTOR,JOINT,RATIO such as 6,5,32");
    match parts.as_slice() {
        [m, j, r] => Ok((m.parse().map_err(|_| bad())?, j.parse().map_err(|_| bad())?, r.parse().map_err(|_| bad())?)),
        _ => Err(bad()),
    }
}

pub use arash_daemon::daemon::startup::load_robot;
