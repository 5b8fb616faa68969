//! `unz bench`: throughput measurements (kept out of the test run).

use std::process::ExitCode;
use std::time::Instant;

use unz_formats::manifest::RunManifest;
use unz_stages::simulate::{SimConfig, simulate};

use crate::cli::{BenchArgs, BenchTarget};
use crate::ingest::{IngestOptions, ingest};

/// Runs the command.
pub fn run(args: &BenchArgs) -> anyhow::Result<ExitCode> {
    match args.what {
        BenchTarget::Ingest => bench_ingest(args),
    }
}

fn bench_ingest(args: &BenchArgs) -> anyhow::Result<ExitCode> {
    let tmp = tempfile::tempdir()?;
    let mut config = SimConfig::new("bench", 1);
    config.duration_s = args.duration_s;
    let run = simulate(&config);
    let run_dir = crate::simulate_io::write_run(&run, tmp.path())?;
    let manifest = RunManifest::load(&run_dir.join("run.toml"))?;
    let raw_bytes = std::fs::metadata(&manifest.raw)?.len() as f64;
    // One core: the stage is single-threaded; nothing else runs meanwhile.
    for (label, options) in [
        ("raw → Parquet", IngestOptions { mcap: false }),
        ("full ingest (+ MCAP)", IngestOptions { mcap: true }),
    ] {
        let mut best = f64::INFINITY;
        for _ in 0..args.repeat.max(1) {
            let out = tmp.path().join("out");
            let t0 = Instant::now();
            ingest(&manifest, &out, options)?;
            best = best.min(t0.elapsed().as_secs_f64());
        }
        println!(
            "ingest {label}: {:.1} MB raw in {:.3} s = {:.0} MB/s ({:.2} M records/s)",
            raw_bytes / 1e6,
            best,
            raw_bytes / 1e6 / best,
            run.records.len() as f64 / best / 1e6
        );
    }
    Ok(ExitCode::SUCCESS)
}
