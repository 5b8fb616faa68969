//! Stage records: each stage folder holds `stage.json` — stage name and version, a hash
//! of its parameters, and the content hashes of its inputs and outputs. It is written
//! last, after every output was renamed into place, so a stage killed at any moment is
//! never taken as done. A stage whose record matches is skipped.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::{Deserialize, Serialize};
use unz_formats::atomic::write_json_atomic;

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

/// What identifies a file's content without reading it again within one process: every
/// output is written to a new file and renamed into place, so a changed file has a new
/// inode (and usually a new size and modification time).
type FileKey = (PathBuf, u64, u64, u64, i64, i64);

fn file_key(path: &Path) -> Option<FileKey> {
    use std::os::unix::fs::MetadataExt;
    let m = std::fs::metadata(path).ok()?;
    Some((
        path.to_path_buf(),
        m.dev(),
        m.ino(),
        m.len(),
        m.mtime(),
        m.mtime_nsec(),
    ))
}

/// Hashes already computed in this process (a campaign checks the same inputs in several
/// stages).
static HASHES: std::sync::LazyLock<std::sync::Mutex<std::collections::HashMap<FileKey, String>>> =
    std::sync::LazyLock::new(Default::default);

/// Forgets the remembered hashes (a benchmark's "cached" pass measures what a new
/// process would do).
pub fn forget_hashes() {
    if let Ok(mut m) = HASHES.lock() {
        m.clear();
    }
}

/// blake3 of a file's content, streamed; remembered for the process while the file keeps
/// its inode, size and modification time.
pub fn file_hash(path: &Path) -> anyhow::Result<String> {
    let key = file_key(path);
    if let Some(k) = &key
        && let Some(h) = HASHES.lock().ok().and_then(|m| m.get(k).cloned())
    {
        return Ok(h);
    }
    let h = hash_content(path)?;
    if let (Some(k), Ok(mut m)) = (key, HASHES.lock()) {
        m.insert(k, h.clone());
    }
    Ok(h)
}

fn hash_content(path: &Path) -> anyhow::Result<String> {
    thread_local! {
        /// One read buffer per thread, not one zeroed per file.
        static BUF: std::cell::RefCell<Vec<u8>> = std::cell::RefCell::new(vec![0; 1 << 20]);
    }
    let mut f =
        std::fs::File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut h = blake3::Hasher::new();
    BUF.with(|buf| -> anyhow::Result<()> {
        let buf = &mut *buf.borrow_mut();
        loop {
            let n = f
                .read(buf)
                .with_context(|| format!("cannot read {}", path.display()))?;
            if n == 0 {
                return Ok(());
            }
            h.update(&buf[..n]);
        }
    })?;
    Ok(h.finalize().to_hex().to_string())
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
    fn a_file_replaced_by_rename_is_hashed_again() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        std::fs::write(&p, b"first").unwrap();
        let h1 = file_hash(&p).unwrap();
        assert_eq!(file_hash(&p).unwrap(), h1, "remembered");
        // Same size, written the way every output is: a new file renamed into place.
        let tmp = dir.path().join(".a.bin.tmp");
        std::fs::write(&tmp, b"other").unwrap();
        std::fs::rename(&tmp, &p).unwrap();
        let h2 = file_hash(&p).unwrap();
        assert_ne!(h1, h2);
        assert_eq!(h2, blake3::hash(b"other").to_hex().to_string());
    }

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
