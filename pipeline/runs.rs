//! Finding runs and their output folders.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use unz_formats::manifest::{RunManifest, is_plain_name};

/// Resolves a run argument (a run folder or its `run.toml`) and loads the manifest.
pub fn load_run(path: &Path) -> anyhow::Result<RunManifest> {
    let manifest = if path.is_dir() {
        path.join("run.toml")
    } else {
        path.to_path_buf()
    };
    if !manifest.is_file() {
        bail!("no run manifest at {}", manifest.display());
    }
    Ok(RunManifest::load(&manifest)?)
}

/// `OUT/<name>/<stage>/`, created. The name is a validated plain name, so the folder
/// stays inside `out`.
pub fn stage_dir(out: &Path, run_name: &str, stage: &str) -> anyhow::Result<PathBuf> {
    if !is_plain_name(run_name) {
        bail!("run name {run_name:?} is not a plain name");
    }
    let dir = out.join(run_name).join(stage);
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    Ok(dir)
}
