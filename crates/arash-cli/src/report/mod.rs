//! What the commands write for people to read: the figures (plotters) and the demo's report.
//! Only the binary links this; the rig library does not.

pub mod demo;
pub mod figures;

use std::path::Path;

use anyhow::Context;

/// Write a file atomically (see [`arash_core::model_file::write_atomically`]), naming it on failure.
pub fn write_atomically(path: &Path, text: &str) -> anyhow::Result<()> {
    arash_core::model_file::write_atomically(path, text).with_context(|| format!("writing {}", path.display()))
}
