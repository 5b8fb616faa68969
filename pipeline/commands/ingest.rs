//! `unz ingest RUN --out OUT`.

use std::process::ExitCode;

use crate::cli::StageArgs;
use crate::ingest::{IngestOptions, ingest};
use crate::runs::{load_run, stage_dir};

/// Runs the command.
pub fn run(args: &StageArgs) -> anyhow::Result<ExitCode> {
    let manifest = load_run(&args.run)?;
    let dir = stage_dir(&args.out, &manifest.name, "ingest")?;
    let outcome = ingest(&manifest, &dir, IngestOptions::default())?;
    let r = &outcome.report;
    println!(
        "{}: {} IMU records, {} marks, {} odometer rows; {} rejected, {} bytes skipped, {} samples lost → {}",
        manifest.name,
        r.imu_accepted,
        r.marks_accepted,
        outcome.odometer_rows,
        r.rejected_total(),
        r.bytes_skipped,
        r.lost_samples,
        outcome.dir.display()
    );
    Ok(ExitCode::SUCCESS)
}
