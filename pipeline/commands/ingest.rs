//! `unz ingest RUN --out OUT`.

use std::process::ExitCode;

use unz_formats::IngestReport;

use crate::artifacts::files;
use crate::cli::StageArgs;
use crate::flow::{RunCtx, ensure_ingest};
use crate::runs::load_run;

/// Runs the command.
pub fn run(args: &StageArgs) -> anyhow::Result<ExitCode> {
    let ctx = RunCtx::new(load_run(&args.run)?, args.out.clone(), true);
    let dir = ensure_ingest(
        &ctx,
        &crate::config::for_run(&toml::Table::new(), &ctx.manifest)?,
    )?;
    let r: IngestReport = serde_json::from_slice(&std::fs::read(dir.join(files::INGEST_REPORT))?)?;
    let odometer_file = r.odometer_file.as_ref().map_or(String::new(), |o| {
        format!(
            "; odometer file: {} lines kept, {} rejected",
            o.lines_accepted, o.lines_rejected
        )
    });
    println!(
        "{}: {} IMU records, {} marks; {} rejected, {} bytes skipped, {} samples lost{} → {}",
        ctx.manifest.name,
        r.imu_accepted,
        r.marks_accepted,
        r.rejected_total(),
        r.bytes_skipped,
        r.lost_samples,
        odometer_file,
        dir.display()
    );
    Ok(ExitCode::SUCCESS)
}
