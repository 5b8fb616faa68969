//! One run being processed: its manifest, where it writes, what each stage did, and what
//! the chain hands on in memory (the ingest's series to the derive, the derive to the
//! stages after it).

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use unz_formats::manifest::RunManifest;
use unz_stages::derive::Derived;

use crate::artifacts::RunLayout;
use crate::derive_io::{StoredDerive, load_derived_for_navigation};
use crate::stage::Stage;

use super::IngestedSeries;

/// One run being processed.
pub struct RunCtx {
    /// Its manifest.
    pub manifest: RunManifest,
    /// Output root.
    pub out: PathBuf,
    /// Say on stderr which stages ran and which were skipped.
    pub verbose: bool,
    /// What each stage did: (stage, computed (not cached), wall s), in order.
    pub log: std::sync::Mutex<Vec<(String, bool, f64)>>,
    /// A progress line showing the stage being worked on (campaigns on a terminal).
    pub progress: Option<indicatif::ProgressBar>,
    /// Whether the run has the machine's cores to itself or shares them with other runs
    /// (a campaign's): where a stage can order its work either for the shortest time or
    /// for the least CPU, the same files either way.
    pub cores: Cores,
    /// The derive stage's output in memory: the stages after it in the same process share
    /// it instead of each decoding `derived.parquet`. Set when the derive is computed or
    /// first loaded, as [`crate::derive_io::load_derived`] gives it back but without the
    /// velocity increments (only the alignment's static start reads them, from the file,
    /// and the review's sensor blocks, taken by the derive stage into `sensors.parquet`);
    /// cleared when it is recomputed.
    derived: std::sync::Mutex<Option<Arc<Derived>>>,
    /// The series the ingest wrote, when it ran in this process: the derive takes them
    /// instead of reading its files back.
    ingested: std::sync::Mutex<Option<IngestedSeries>>,
    /// The stages brought up to date in this context (ingest, derive), each with the hash
    /// of the parameters it was last brought up to date with ([`Self::ensured_with`]).
    ensured: std::sync::Mutex<Vec<(&'static str, String)>>,
}

/// Whom a run's process shares the cores with ([`RunCtx::cores`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cores {
    /// The run alone: a core idle while another works is time lost, so work may be
    /// ordered to keep both busy even where that costs some CPU.
    Own,
    /// Other runs side by side (a campaign of several): they keep every core busy, so the
    /// work is ordered for the least CPU.
    Shared,
}

impl RunCtx {
    /// A context for the run described by `manifest`, writing under `out`.
    pub fn new(manifest: RunManifest, out: PathBuf, verbose: bool) -> Self {
        Self {
            manifest,
            out,
            verbose,
            log: std::sync::Mutex::new(Vec::new()),
            progress: None,
            cores: Cores::Own,
            derived: std::sync::Mutex::new(None),
            ingested: std::sync::Mutex::new(None),
            ensured: std::sync::Mutex::new(Vec::new()),
        }
    }

    /// The run's derive (brought up to date by the caller): the one in memory, else
    /// loaded without its velocity increments and kept. Its `dvel_mps` is then empty:
    /// [`load_case`](super::load_case) reads the static start's apart.
    pub fn derived(&self) -> anyhow::Result<Arc<Derived>> {
        let mut memo = self.derived.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(d) = memo.as_ref() {
            return Ok(d.clone());
        }
        let d = Arc::new(load_derived_for_navigation(&StoredDerive::of(
            &self.layout(),
        ))?);
        *memo = Some(d.clone());
        Ok(d)
    }

    /// The derive in memory, when the chain holds it (nothing is loaded).
    pub fn kept_derived(&self) -> Option<Arc<Derived>> {
        self.derived
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Takes the derive out of memory, when the chain holds it: the last stage that reads
    /// it owns it then.
    pub fn take_kept_derived(&self) -> Option<Arc<Derived>> {
        self.derived
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
    }

    pub(super) fn set_derived(&self, d: Option<Arc<Derived>>) {
        *self.derived.lock().unwrap_or_else(|e| e.into_inner()) = d;
    }

    /// Keeps the series the ingest just wrote for the derive (none: forgets any kept).
    pub(super) fn set_ingested(&self, series: Option<IngestedSeries>) {
        *self.ingested.lock().unwrap_or_else(|e| e.into_inner()) = series;
    }

    /// Takes the series the ingest wrote in this process, if it did.
    pub(super) fn take_ingested(&self) -> Option<IngestedSeries> {
        self.ingested
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
    }

    /// Whether `stage` was brought up to date in this context with the parameters whose
    /// hash is `params_hash`. The stages of a chain each ask for the ones they read (a
    /// `unz run` of a cached run checked the derive's record 8 times, the ingest's 9):
    /// with this, once. Only this process writes the output folder (under its lock), and
    /// only its stage's own `ensure_` function writes a stage's files, so a stage up to
    /// date with the same parameters stays so for the context's life.
    pub(super) fn ensured_with(&self, stage: &str, params_hash: &str) -> bool {
        self.ensured
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .iter()
            .any(|(s, h)| *s == stage && h == params_hash)
    }

    /// Forgets that `stage` was brought up to date (a stage before it is asked for again:
    /// it may change what `stage` read).
    pub(super) fn forget_ensured(&self, stage: &str) {
        let mut ensured = self.ensured.lock().unwrap_or_else(|e| e.into_inner());
        ensured.retain(|(s, _)| *s != stage);
    }

    /// Notes that `stage` was brought up to date (computed, or found up to date) with the
    /// parameters whose hash is `params_hash`.
    pub(super) fn set_ensured(&self, stage: &'static str, params_hash: String) {
        let mut ensured = self.ensured.lock().unwrap_or_else(|e| e.into_inner());
        ensured.retain(|(s, _)| *s != stage);
        ensured.push((stage, params_hash));
    }

    fn record(&self, stage: &str, computed: bool, wall_s: f64) {
        if let Ok(mut log) = self.log.lock() {
            log.push((stage.to_owned(), computed, wall_s));
        }
    }
}

impl RunCtx {
    /// Where this run's artifacts live.
    pub fn layout(&self) -> RunLayout {
        RunLayout::new(&self.out, &self.manifest.name)
    }

    /// Says `what` of `stage` when verbose.
    pub fn say(&self, stage: &str, what: &str) {
        if self.verbose {
            eprintln!("{}: {stage}: {what}", self.manifest.name);
        }
    }

    /// Runs `body` unless `stage` is up to date; then records it.
    pub fn run_stage(
        &self,
        stage: &Stage<'_>,
        body: impl FnOnce() -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        let t0 = std::time::Instant::now();
        if let Some(p) = &self.progress {
            p.set_message(format!("{}: {}", self.manifest.name, stage.name));
        }
        if stage.is_up_to_date(self.manifest.dir())? {
            self.say(stage.name, "up to date, skipped");
            self.record(stage.name, false, t0.elapsed().as_secs_f64());
            return Ok(());
        }
        stage.invalidate()?;
        crate::read_ahead::read_ahead(&stage.inputs);
        // The inputs' hashes, which the record takes after the body, are taken beside it
        // when a core is free (a 12-hour ingest's raw log, 207 MB, was hashed alone after
        // its outputs); a file that cannot be read is left to the record, which says so.
        // Those the body hashes as it reads them are not read twice.
        let done = std::thread::scope(|s| {
            s.spawn(|| {
                for path in &stage.inputs {
                    if !stage.hashed_as_read.contains(path) {
                        let _ = crate::file_hashes::file_hash(path);
                    }
                }
            });
            body()
        });
        done.with_context(|| format!("{}: stage {} failed", self.manifest.name, stage.name))?;
        stage.commit(self.manifest.dir())?;
        let wall_s = t0.elapsed().as_secs_f64();
        self.say(stage.name, &format!("done in {wall_s:.2} s"));
        self.record(stage.name, true, wall_s);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::time::{Duration, Instant};

    use crate::stage::Stage;

    #[test]
    fn a_stages_inputs_are_hashed_beside_its_body() {
        let tmp = tempfile::tempdir().unwrap();
        let ctx = crate::simulate_io::simulated_ctx(tmp.path(), "beside", 3, 30.0).unwrap();
        let raw = ctx.manifest.raw.clone();
        let stage = Stage {
            dir: tmp.path().join("out").join("beside").join("probe"),
            name: "probe",
            version: 1,
            params_hash: "p".into(),
            inputs: vec![raw.clone()],
            outputs: &[],
            hashed_as_read: vec![],
        };
        std::fs::create_dir_all(&stage.dir).unwrap();
        ctx.run_stage(&stage, || {
            // The body waits (up to 20 s) for the raw log's hash to be taken beside it.
            let t0 = Instant::now();
            while crate::file_hashes::remembered(&raw).is_none() {
                anyhow::ensure!(
                    t0.elapsed() < Duration::from_secs(20),
                    "the input was not hashed while the stage's body ran"
                );
                std::thread::sleep(Duration::from_millis(1));
            }
            Ok(())
        })
        .unwrap();
    }

    #[test]
    fn an_input_the_body_hashes_as_it_reads_is_not_read_beside_it() {
        let tmp = tempfile::tempdir().unwrap();
        let ctx = crate::simulate_io::simulated_ctx(tmp.path(), "as-read", 4, 30.0).unwrap();
        let (raw, manifest) = (ctx.manifest.raw.clone(), ctx.manifest.path.clone());
        let stage = Stage {
            dir: tmp.path().join("out").join("as-read").join("probe"),
            name: "probe",
            version: 1,
            params_hash: "p".into(),
            // Hashed beside the body in this order: the manifest's hash says the raw log
            // was passed.
            inputs: vec![raw.clone(), manifest.clone()],
            outputs: &[],
            hashed_as_read: vec![raw.clone()],
        };
        std::fs::create_dir_all(&stage.dir).unwrap();
        ctx.run_stage(&stage, || {
            let t0 = Instant::now();
            while crate::file_hashes::remembered(&manifest).is_none() {
                anyhow::ensure!(t0.elapsed() < Duration::from_secs(20), "no hashes beside");
                std::thread::sleep(Duration::from_millis(1));
            }
            anyhow::ensure!(
                crate::file_hashes::remembered(&raw).is_none(),
                "the raw log was read beside the body"
            );
            let mut read = crate::file_hashes::HashingRead::new(std::fs::File::open(&raw)?, &raw);
            std::io::copy(&mut read, &mut std::io::sink())?;
            Ok(())
        })
        .unwrap();
        // The record takes the hash of the bytes the body read.
        let bytes = std::fs::read(stage.dir.join(crate::stage::RECORD)).unwrap();
        let record: crate::stage::StageRecord = serde_json::from_slice(&bytes).unwrap();
        let want = blake3::hash(&std::fs::read(&raw).unwrap())
            .to_hex()
            .to_string();
        let key = format!(
            "{}/{}",
            crate::stage::RUN_FOLDER_KEY,
            raw.file_name().unwrap().to_string_lossy()
        );
        assert_eq!(record.inputs.get(&key), Some(&want), "{:?}", record.inputs);
    }
}
