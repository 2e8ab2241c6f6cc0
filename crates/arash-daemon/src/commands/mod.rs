pub mod excite;
pub mod identify;
pub mod model;

use std::path::Path;

use anyhow::Context;

/// Load a robot model and keep its URDF text (model files embed it).
pub fn load_robot(path: &Path) -> anyhow::Result<(arash_core::Model, String)> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading URDF {}", path.display()))?;
    let model = arash_core::parse_urdf(&text).with_context(|| format!("loading {}", path.display()))?;
    Ok((model, text))
}

/// Write a file through a temporary name and a rename, so that a crash never leaves half a file.
pub fn write_atomically(path: &Path, text: &str) -> anyhow::Result<()> {
    let tmp = path.with_extension("partial");
    std::fs::write(&tmp, text).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("renaming {} to {}", tmp.display(), path.display()))
}
