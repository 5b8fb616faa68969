//! A run's artifacts: where every stage's files live under `OUT/<run name>/`, by name, in
//! one place. Writers and readers both take paths from here; the report types
//! (`IngestReport`, `NavigateSummary`, `CriteriaSummary`, `DisuptOut`) are the one
//! definition each file is written and read with.

use std::path::{Path, PathBuf};

use crate::runs::stage_dir;

/// The stages, by their folder names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StageName {
    /// `ingest/`.
    Ingest,
    /// `derive/`.
    Derive,
    /// `navigate/`.
    Navigate,
    /// `criteria/`.
    Criteria,
    /// `disupt/`.
    Disupt,
    /// `export/`.
    Export,
    /// `review/`.
    Review,
    /// `sweep/`.
    Sweep,
}

impl StageName {
    /// The folder name.
    pub const fn as_str(self) -> &'static str {
        match self {
            StageName::Ingest => "ingest",
            StageName::Derive => "derive",
            StageName::Navigate => "navigate",
            StageName::Criteria => "criteria",
            StageName::Disupt => "disupt",
            StageName::Export => "export",
            StageName::Review => "review",
            StageName::Sweep => "sweep",
        }
    }
}

/// File names of the artifacts, per stage.
pub mod files {
    /// ingest: the IMU table.
    pub const IMU: &str = "imu.parquet";
    /// ingest: the odometer table.
    pub const ODOMETER: &str = "odometer.parquet";
    /// ingest: control-point marks.
    pub const MARKS: &str = "marks.parquet";
    /// ingest: the raw log's records as ROS 2 messages, for Foxglove and Rerun.
    pub const RAW_MCAP: &str = "raw.mcap";
    /// ingest: the accounting report.
    pub const INGEST_REPORT: &str = "ingest.json";
    /// ingest: the first faults, located ([`unz_formats::IngestEvents`]).
    pub const INGEST_EVENTS: &str = "ingest_events.json";
    /// derive: per-sample series (the time base and the odometer's terms).
    pub const DERIVED: &str = "derived.parquet";
    /// derive: the IMU samples whose increments it replaced, with their replacements.
    pub const IMU_REPAIRS: &str = "imu_repairs.parquet";
    /// derive: per-epoch series.
    pub const EPOCHS: &str = "epochs.parquet";
    /// derive: the filtered series per block of F.
    pub const BLOCKS: &str = "blocks.parquet";
    /// derive: the per-sample sensor series in the review recording's blocks.
    pub const SENSORS: &str = "sensors.parquet";
    /// navigate: the track.
    pub const NAV: &str = "nav.parquet";
    /// navigate: its summary.
    pub const NAVIGATE_REPORT: &str = "navigate.json";
    /// criteria: per-epoch residuals.
    pub const CRITERIA: &str = "criteria.parquet";
    /// criteria: the summary.
    pub const CRITERIA_REPORT: &str = "criteria.json";
    /// disupt: the report.
    pub const DISUPT_REPORT: &str = "disupt.json";
    /// disupt: the paper's tables.
    pub const DISUPT_TABLES: &str = "disupt.md";
    /// disupt: the corrected navigation with its σ.
    pub const CORRECTED_NAV: &str = "corrected_nav.parquet";
}

/// The folders and files of one run under an output folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunLayout {
    run_dir: PathBuf,
}

impl RunLayout {
    /// The layout of run `name` under `out` (the name is a manifest's plain name).
    pub fn new(out: &Path, name: &str) -> Self {
        Self {
            run_dir: out.join(name),
        }
    }

    /// `OUT/<run>/`.
    pub fn run_dir(&self) -> &Path {
        &self.run_dir
    }

    /// A stage's folder (not created).
    pub fn dir(&self, stage: StageName) -> PathBuf {
        self.run_dir.join(stage.as_str())
    }

    /// A stage's file.
    pub fn file(&self, stage: StageName, name: &str) -> PathBuf {
        self.dir(stage).join(name)
    }

    /// A stage's folder, created, refusing symbolic links (see [`stage_dir`]).
    pub fn create(&self, stage: StageName) -> anyhow::Result<PathBuf> {
        let out = self.run_dir.parent().unwrap_or(Path::new("."));
        let name = self
            .run_dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        stage_dir(out, &name, stage.as_str())
    }

    /// The review recording, `review/<run>.rrd`.
    pub fn recording(&self) -> PathBuf {
        let name = self
            .run_dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        self.file(StageName::Review, &format!("{name}.rrd"))
    }
}
