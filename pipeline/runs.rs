//! Finding runs and their output folders.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use unz_formats::manifest::{RunManifest, is_plain_name};

/// A run's manifest, in its folder.
pub const MANIFEST: &str = "run.toml";

/// The manifest of the one run `path` names (a run.toml file, or a folder holding one);
/// `None` for anything else (a campaign's folder, whose runs lie below it).
pub fn one_run_manifest(path: &Path) -> Option<PathBuf> {
    if path.is_file() {
        Some(path.to_path_buf())
    } else {
        Some(path.join(MANIFEST)).filter(|m| m.is_file())
    }
}

/// Resolves a run argument (a run folder or its `run.toml`) and loads the manifest.
pub fn load_run(path: &Path) -> anyhow::Result<RunManifest> {
    let manifest = if path.is_dir() {
        path.join(MANIFEST)
    } else {
        path.to_path_buf()
    };
    if !manifest.is_file() {
        bail!("no run manifest at {}", manifest.display());
    }
    Ok(RunManifest::load(&manifest)?)
}

/// `OUT/<name>/<stage>/`, created. The name is a validated plain name, and neither
/// folder may be a symbolic link (one planted there would send outputs outside `out`).
pub fn stage_dir(out: &Path, run_name: &str, stage: &str) -> anyhow::Result<PathBuf> {
    if !is_plain_name(run_name) {
        bail!("run name {run_name:?} is not a plain name");
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let run_dir = out.join(run_name);
    let dir = run_dir.join(stage);
    for d in [&run_dir, &dir] {
        match std::fs::symlink_metadata(d) {
            Ok(m) if m.file_type().is_symlink() => bail!(
                "{} is a symbolic link: outputs are written only inside the output folder",
                d.display()
            ),
            Ok(m) if !m.is_dir() => bail!("{} exists and is not a folder", d.display()),
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                std::fs::create_dir(d).with_context(|| format!("cannot create {}", d.display()))?;
            }
            Err(e) => return Err(e).with_context(|| format!("cannot read {}", d.display())),
        }
    }
    Ok(dir)
}
