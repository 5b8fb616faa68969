//! Stage records: each stage folder holds `stage.json` — stage name and version, a hash
//! of its parameters, and the content hashes of its inputs and outputs. It is written
//! last, after every output was renamed into place, so a stage killed at any moment is
//! never taken as done. A stage whose record matches is skipped.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
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
    /// Input files (as given) and their blake3.
    pub inputs: BTreeMap<String, String>,
    /// Output files (names in the stage folder) and their blake3.
    pub outputs: BTreeMap<String, String>,
}

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
}

impl Stage<'_> {
    /// Inputs by name — relative to the output root (`OUT`, two levels above the stage
    /// folder) when they lie under it, so a moved output tree stays valid — and hash.
    fn input_hashes(&self) -> anyhow::Result<BTreeMap<String, String>> {
        let root = self.dir.parent().and_then(Path::parent);
        self.inputs
            .iter()
            .map(|p| {
                let key = root.and_then(|r| p.strip_prefix(r).ok()).unwrap_or(p);
                Ok((key.display().to_string(), file_hash(p)?))
            })
            .collect()
    }

    /// Whether the folder holds this stage's outputs for these parameters and inputs.
    pub fn is_up_to_date(&self) -> anyhow::Result<bool> {
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
        if rec.inputs != self.input_hashes()? {
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
    pub fn commit(&self) -> anyhow::Result<()> {
        let outputs = self
            .outputs
            .iter()
            .map(|n| Ok(((*n).to_owned(), file_hash(&self.dir.join(n))?)))
            .collect::<anyhow::Result<_>>()?;
        let rec = StageRecord {
            stage: self.name.to_owned(),
            version: self.version,
            params_hash: self.params_hash.clone(),
            inputs: self.input_hashes()?,
            outputs,
        };
        write_json_atomic(&self.dir.join(RECORD), &rec)?;
        Ok(())
    }

    /// Removes the record, so a stage that starts over is never taken as done, and the
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
        match std::fs::remove_file(self.dir.join(RECORD)) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            Err(e) => {
                Err(e).with_context(|| format!("cannot remove {}", self.dir.join(RECORD).display()))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalidate_clears_what_a_killed_stage_left() {
        let dir = tempfile::tempdir().unwrap();
        for leftover in [".nav.parquet.123.tmp", ".run.rrd.77.tmp", RECORD] {
            std::fs::write(dir.path().join(leftover), b"x").unwrap();
        }
        std::fs::write(dir.path().join("nav.parquet"), b"kept").unwrap();
        let stage = Stage {
            dir: dir.path().to_path_buf(),
            name: "t",
            version: 1,
            params_hash: String::new(),
            inputs: vec![],
            outputs: &[],
        };
        stage.invalidate().unwrap();
        let left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(left, vec!["nav.parquet".to_owned()]);
    }
}
