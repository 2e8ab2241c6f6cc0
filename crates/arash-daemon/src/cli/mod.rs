pub mod ctl;
pub mod daemon;
pub mod demo;
pub mod diagnose;
pub mod excite;
pub mod identify;
pub mod mock_motor;
pub mod model;
pub mod simulate;

use std::path::Path;

use anyhow::Context;

/// The logged runs a command reads and the robot they come from.
#[derive(clap::Args)]
pub struct Runs {
    /// Logged runs (MCAP flight logs, or CSV with columns t, q.<joint>, tau.<joint>), concatenated in order.
    #[arg(required = true)]
    pub logs: Vec<std::path::PathBuf>,
    /// The robot's URDF; default: the bundled ARASH:ASiST.
    #[arg(long)]
    pub robot: Option<std::path::PathBuf>,
}

/// Load a robot model and keep its URDF text (model files and logs embed it). `None` is the
/// ARASH:ASiST description built into the binary.
pub fn load_robot(path: Option<&Path>) -> anyhow::Result<(arash_core::Model, String)> {
    let Some(path) = path else {
        return Ok((arash_core::arash_asist(), arash_core::ARASH_ASIST_URDF.to_string()));
    };
    let text = std::fs::read_to_string(path).with_context(|| format!("reading URDF {}", path.display()))?;
    let model = arash_core::parse_urdf(&text).with_context(|| format!("loading {}", path.display()))?;
    for warning in &model.warnings {
        eprintln!("warning: {}: {warning}", path.display());
    }
    Ok((model, text))
}
