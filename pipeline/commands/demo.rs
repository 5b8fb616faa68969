//! `unz demo`: a small simulated campaign (three runs, one of them damaged) pushed through
//! every stage, with a summary table.

use std::path::PathBuf;
use std::process::ExitCode;

use rayon::prelude::*;
use unz_formats::IngestReport;

use crate::cli::{DemoArgs, SimulateArgs};
use crate::disupt_stage::{Method, ensure_disupt};
use crate::flow::{Overrides, Params, RunCtx, ensure_criteria};
use crate::runs::load_run;

/// One run's line of the summary.
struct Line {
    name: String,
    report: IngestReport,
    disupt: serde_json::Value,
}

fn process(dir: &std::path::Path, results: &std::path::Path) -> anyhow::Result<Line> {
    let ctx = RunCtx::new(load_run(dir)?, results.to_path_buf(), false);
    let params = Params::default();
    ensure_criteria(&ctx, &params, &Overrides::default())?;
    let disupt_dir = ensure_disupt(&ctx, &params, Method::All)?;
    let name = ctx.manifest.name.clone();
    let report = serde_json::from_slice(&std::fs::read(
        results.join(&name).join("ingest/ingest.json"),
    )?)?;
    let disupt = serde_json::from_slice(&std::fs::read(disupt_dir.join("disupt.json"))?)?;
    Ok(Line {
        name,
        report,
        disupt,
    })
}

/// Runs the command.
pub fn run(args: &DemoArgs) -> anyhow::Result<ExitCode> {
    let campaign = args.out.join("campaign");
    let results = args.out.join("results");
    let sim = SimulateArgs {
        out: campaign.clone(),
        seed: 1,
        runs: 3,
        duration_s: 600.0,
        static_s: 90.0,
        faults: false,
        azimuth_error_deg: None,
        no_noise: false,
        no_accel_bias: false,
        no_gyro_drift: false,
        no_odo_scale_error: false,
    };
    let dirs: Vec<PathBuf> = super::simulate::configs(&sim)?
        .par_iter()
        .map(|c| {
            let run = unz_stages::simulate::simulate(c);
            // The second run is archived damaged: bad CRCs, garbage, lost records…
            if c.seed == 2 {
                crate::simulate_io::write_faulty_copy(&run, &campaign)
            } else {
                crate::simulate_io::write_run(&run, &campaign)
            }
        })
        .collect::<anyhow::Result<_>>()?;
    let lines: Vec<(PathBuf, anyhow::Result<Line>)> = dirs
        .par_iter()
        .map(|d| (d.clone(), process(d, &results)))
        .collect();

    println!(
        "{:<16} {:>7} {:>8} {:>9} {:>10} {:>10} {:>10} {:>10} {:>12}",
        "run",
        "imu",
        "rejected",
        "dist [m]",
        "before [m]",
        "OEPI [m]",
        "OWPI [m]",
        "joint [m]",
        "joint az σ°"
    );
    let mut failed = 0;
    for (dir, line) in lines {
        match line {
            Ok(l) => {
                let err = |v: &serde_json::Value| {
                    v["dx_m"]
                        .as_f64()
                        .unwrap_or(f64::NAN)
                        .hypot(v["dy_m"].as_f64().unwrap_or(f64::NAN))
                };
                let m = &l.disupt["methods"];
                println!(
                    "{:<16} {:>7} {:>8} {:>9.0} {:>10.1} {:>10.1} {:>10.1} {:>10.1} {:>12.3}",
                    l.name,
                    l.report.imu_accepted,
                    l.report.rejected_total(),
                    l.disupt["distance_m"].as_f64().unwrap_or(f64::NAN),
                    err(&l.disupt["before"]),
                    err(&m["oepi"]),
                    err(&m["owpi"]),
                    err(&m["joint"]),
                    m["joint"]["x"]["sigma"]["azimuth_deg"]
                        .as_f64()
                        .unwrap_or(f64::NAN),
                );
            }
            Err(e) => {
                failed += 1;
                println!("{:<16} failed: {e:#}", dir.display());
            }
        }
    }
    println!("errors are horizontal distances at the last control point");
    println!(
        "campaign: {}\nresults:  {} (per run: ingest/ derive/ navigate/ criteria/ disupt/)",
        campaign.display(),
        results.display()
    );
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
