//! `unz demo`: a small simulated campaign pushed through every stage.

use std::process::ExitCode;

use crate::cli::{DemoArgs, SimulateArgs};
use crate::ingest::{IngestOptions, ingest};
use crate::runs::{load_run, stage_dir};

/// Runs the command.
pub fn run(args: &DemoArgs) -> anyhow::Result<ExitCode> {
    let campaign = args.out.join("campaign");
    let results = args.out.join("results");
    let sim = SimulateArgs {
        out: campaign.clone(),
        seed: 1,
        runs: 2,
        duration_s: 600.0,
        static_s: 90.0,
        faults: false,
        azimuth_error_deg: None,
        no_noise: false,
        no_accel_bias: false,
        no_gyro_drift: false,
        no_odo_scale_error: false,
    };
    let mut runs = Vec::new();
    for c in super::simulate::configs(&sim)? {
        let run = unz_stages::simulate::simulate(&c);
        runs.push(crate::simulate_io::write_run(&run, &campaign)?);
        if c.seed == 2 {
            runs.push(crate::simulate_io::write_faulty_copy(&run, &campaign)?);
        }
    }
    println!(
        "{:<16} {:>8} {:>6} {:>9} {:>8} {:>6}",
        "run", "imu", "marks", "rejected", "skipped", "lost"
    );
    let mut failed = 0;
    for dir in &runs {
        let outcome = load_run(dir).and_then(|m| {
            let out = stage_dir(&results, &m.name, "ingest")?;
            Ok((m.name.clone(), ingest(&m, &out, IngestOptions::default())?))
        });
        match outcome {
            Ok((name, o)) => {
                let r = &o.report;
                println!(
                    "{name:<16} {:>8} {:>6} {:>9} {:>8} {:>6}",
                    r.imu_accepted,
                    r.marks_accepted,
                    r.rejected_total(),
                    r.bytes_skipped,
                    r.lost_samples
                );
            }
            Err(e) => {
                failed += 1;
                println!("{:<16} failed: {e:#}", dir.display());
            }
        }
    }
    println!(
        "campaign: {}\nresults:  {}",
        campaign.display(),
        results.display()
    );
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
