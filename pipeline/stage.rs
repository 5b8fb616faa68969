//! Stage records: each stage folder holds `stage.json` — stage name and version, a hash
//! of its parameters, and the content hashes of its inputs and outputs. It is written
//! last, after every output was renamed into place, so a stage killed at any moment is
//! never taken as done. A stage whose record matches is skipped.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use unz_formats::atomic::write_json_atomic;

use crate::file_hashes::file_hash;

/// Name of the record in every stage folder.
pub const RECORD: &str = "stage.json";

/// The record of one stage run.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct StageRecord {
    /// Stage name.
    pub stage: String,
    /// Version of the stage's code: a change of meaning bumps it.
    pub version: u32,
    /// blake3 of the canonical JSON of the parameters.
    pub params_hash: String,
    /// Input files and their blake3, each named where it lies: relative to the output
    /// root (`<run>/<stage>/<file>`) for an earlier stage's output, relative to the run
    /// folder behind [`RUN_FOLDER_KEY`] for a file of the run (its manifest, raw log,
    /// odometer file). The record so does not depend on the working directory, nor on
    /// where the campaign and output folders lie.
    pub inputs: BTreeMap<String, String>,
    /// Output files (names in the stage folder) and their blake3.
    pub outputs: BTreeMap<String, String>,
}

/// The prefix naming a file of the run folder in [`StageRecord::inputs`]: `@` is in no run
/// name, so the key never reads as an output's.
pub const RUN_FOLDER_KEY: &str = "@run";

/// blake3 of the JSON of `params`.
pub fn params_hash(params: &impl Serialize) -> anyhow::Result<String> {
    Ok(blake3::hash(&serde_json::to_vec(params)?)
        .to_hex()
        .to_string())
}

/// A stage about to run or be skipped.
pub struct Stage<'a> {
    /// Stage folder.
    pub dir: PathBuf,
    /// Name.
    pub name: &'a str,
    /// Version.
    pub version: u32,
    /// Parameter hash.
    pub params_hash: String,
    /// Input files.
    pub inputs: Vec<PathBuf>,
    /// Output file names.
    pub outputs: &'a [&'a str],
    /// Inputs the body reads front to back through [`crate::file_hashes::HashingRead`],
    /// which hashes their bytes as it reads them: they are not read again to be hashed
    /// beside the body ([`crate::flow::RunCtx::run_stage`]).
    pub hashed_as_read: Vec<PathBuf>,
}

impl Stage<'_> {
    /// Inputs by name and hash: see [`StageRecord::inputs`]. The output root is `OUT`,
    /// two levels above the stage folder; `run_dir` is the run's folder.
    fn input_hashes(&self, run_dir: &Path) -> anyhow::Result<BTreeMap<String, String>> {
        let root = self.dir.parent().and_then(Path::parent);
        self.inputs
            .iter()
            .map(|p| Ok((input_key(p, root, run_dir), file_hash(p)?)))
            .collect()
    }

    /// Whether the folder holds this stage's outputs for these parameters and inputs, the
    /// run's own files being in `run_dir`.
    pub fn is_up_to_date(&self, run_dir: &Path) -> anyhow::Result<bool> {
        let Ok(bytes) = std::fs::read(self.dir.join(RECORD)) else {
            return Ok(false);
        };
        let Ok(rec) = serde_json::from_slice::<StageRecord>(&bytes) else {
            return Ok(false);
        };
        if rec.stage != self.name
            || rec.version != self.version
            || rec.params_hash != self.params_hash
        {
            return Ok(false);
        }
        if rec.inputs != self.input_hashes(run_dir)? {
            return Ok(false);
        }
        for name in self.outputs {
            match rec.outputs.get(*name) {
                Some(h)
                    if self.dir.join(name).is_file() && file_hash(&self.dir.join(name))? == *h => {}
                _ => return Ok(false),
            }
        }
        Ok(true)
    }

    /// Writes the record (after the outputs are in place).
    pub fn commit(&self, run_dir: &Path) -> anyhow::Result<()> {
        // Side by side: a stage's last outputs are written just before (the disupt
        // stage's 4.8-MB corrected navigation beside its tables).
        let outputs = self
            .outputs
            .par_iter()
            .map(|n| Ok(((*n).to_owned(), file_hash(&self.dir.join(n))?)))
            .collect::<anyhow::Result<Vec<_>>>()?
            .into_iter()
            .collect();
        let rec = StageRecord {
            stage: self.name.to_owned(),
            version: self.version,
            params_hash: self.params_hash.clone(),
            inputs: self.input_hashes(run_dir)?,
            outputs,
        };
        write_json_atomic(&self.dir.join(RECORD), &rec)?;
        Ok(())
    }

    /// Removes the record, so a stage that starts over is never taken as done, then its
    /// outputs (stale without it; a file renamed over an old one has its pages written
    /// out in the rename, 15 ms for `raw.mcap` on ext4, where a removed one's are
    /// dropped; their hashes are forgotten, as their inodes may be reused) and the
    /// temporary files (`.<name>.<random>.tmp`) a killed run may have left.
    pub fn invalidate(&self) -> anyhow::Result<()> {
        if let Ok(entries) = std::fs::read_dir(&self.dir) {
            for e in entries.flatten() {
                let name = e.file_name().to_string_lossy().into_owned();
                if name.starts_with('.') && name.ends_with(".tmp") {
                    let _ = std::fs::remove_file(e.path());
                }
            }
        }
        let remove = |path: &Path| {
            crate::file_hashes::remove_file(path)
                .with_context(|| format!("cannot remove {}", path.display()))
        };
        remove(&self.dir.join(RECORD))?;
        for name in self.outputs {
            remove(&self.dir.join(name))?;
        }
        Ok(())
    }
}

/// An input's name in a record: relative to the output root `root` when under it, else
/// `@run/<path>` relative to the run folder `run_dir` when under it (a run folder given as
/// `.` holds every relative path that does not leave it), else the path as given.
fn input_key(path: &Path, root: Option<&Path>, run_dir: &Path) -> String {
    if let Some(rel) = root.and_then(|r| path.strip_prefix(r).ok()) {
        return rel.display().to_string();
    }
    let in_cwd = run_dir == Path::new(".")
        && path.is_relative()
        && !path
            .components()
            .any(|c| matches!(c, std::path::Component::ParentDir));
    match path.strip_prefix(run_dir) {
        Ok(rel) => Path::new(RUN_FOLDER_KEY).join(rel).display().to_string(),
        Err(_) if in_cwd => Path::new(RUN_FOLDER_KEY).join(path).display().to_string(),
        Err(_) => path.display().to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_are_named_where_they_lie_not_as_given() {
        let root = Some(Path::new("../out"));
        let key = |p: &str, run: &str| input_key(Path::new(p), root, Path::new(run));
        assert_eq!(
            key("../out/r1/derive/epochs.parquet", "../c/r1"),
            "r1/derive/epochs.parquet"
        );
        assert_eq!(key("../c/r1/run.toml", "../c/r1"), "@run/run.toml");
        assert_eq!(
            key("/a/b/c/r1/logs/r1.unz", "/a/b/c/r1"),
            "@run/logs/r1.unz"
        );
        // The same files named from the run folder itself.
        assert_eq!(key("run.toml", "."), "@run/run.toml");
        assert_eq!(key("./logs/r1.unz", "."), "@run/logs/r1.unz");
        // Anything else as given.
        assert_eq!(key("/etc/x.toml", "../c/r1"), "/etc/x.toml");
        assert_eq!(key("../y.toml", "."), "../y.toml");
    }

    #[test]
    fn invalidate_clears_what_a_killed_stage_left() {
        let dir = tempfile::tempdir().unwrap();
        for leftover in [
            ".nav.parquet.123.tmp",
            ".run.rrd.77.tmp",
            RECORD,
            "old.parquet",
        ] {
            std::fs::write(dir.path().join(leftover), b"x").unwrap();
        }
        // Another stage's output in the same folder stays.
        std::fs::write(dir.path().join("nav.parquet"), b"kept").unwrap();
        let stage = Stage {
            dir: dir.path().to_path_buf(),
            name: "t",
            version: 1,
            params_hash: String::new(),
            inputs: vec![],
            // An output not written yet is no error.
            outputs: &["old.parquet", "never.json"],
            hashed_as_read: vec![],
        };
        // The removed output's hash is forgotten: a file written next may take its inode.
        let old = dir.path().join("old.parquet");
        crate::file_hashes::file_hash(&old).unwrap();
        let old_id = crate::file_hashes::identity(&old).unwrap();
        assert!(crate::file_hashes::knows(&old_id));
        stage.invalidate().unwrap();
        assert!(!crate::file_hashes::knows(&old_id));
        let left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(left, vec!["nav.parquet".to_owned()]);
    }
}
