//! `unz demo`: a small simulated campaign (three runs, one of them damaged) pushed through
//! every stage, with a summary table.

use std::path::PathBuf;
use std::process::ExitCode;

use rayon::prelude::*;
use unz_formats::IngestReport;

use crate::artifacts::{RunLayout, StageName, files};
use crate::campaign::{Plan, run_campaign, write_summary};
use crate::cli::{DemoArgs, SimulateArgs};
use crate::disupt_stage::{DisuptOut, MethodOut};

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
        odo_boresight_deg: 0.0,
        odo_pitch_deg: 0.0,
        // An odometer that reports 0.2 s late, and every stop on a control point: the
        // joint fit estimates the lag, and each point's hold-out error is reported.
        odo_lag_s: 0.2,
        cp_at_every_stop: true,
        log_start_s: None,
        mark_lever_arm_m: None,
        out_and_back: false,
        imu_axes: unz_stages::imu_axes::ImuAxes::FRD,
    };
    let dirs: Vec<PathBuf> = super::simulate::configs(&sim)?
        .par_iter()
        .map(|c| {
            // The second run is archived damaged: bad CRCs, garbage, lost records…
            let faulty = c.seed == 2;
            if let Some(dir) = crate::simulate_io::simulated_before(c, faulty, &campaign) {
                return Ok(dir);
            }
            let run = unz_stages::simulate::simulate(c);
            if faulty {
                crate::simulate_io::write_faulty_copy(&run, &campaign)
            } else {
                crate::simulate_io::write_run(&run, &campaign)
            }
        })
        .collect::<anyhow::Result<_>>()?;
    // Every stage, through the same campaign runner as `unz run`.
    let manifests: Vec<PathBuf> = dirs.iter().map(|d| d.join("run.toml")).collect();
    let plan = Plan::every_stage(results.clone());
    let outcomes = run_campaign(&manifests, &plan);
    write_summary(&results, &outcomes, &plan.config)?;

    println!(
        "{:<16} {:>7} {:>8} {:>9} {:>10} {:>10} {:>10} {:>10} {:>12} {:>13} {:>12}",
        "run",
        "imu",
        "rejected",
        "dist [m]",
        "before [m]",
        "OEPI [m]",
        "OWPI [m]",
        "joint [m]",
        "joint az σ°",
        "odo lag [s]",
        "hold-out [m]"
    );
    let mut failed = 0;
    for o in &outcomes {
        if let Some(e) = &o.error {
            failed += 1;
            println!("{:<16} failed: {e}", o.name);
            continue;
        }
        let layout = RunLayout::new(&results, &o.name);
        fn read<T: serde::de::DeserializeOwned>(p: std::path::PathBuf) -> Option<T> {
            serde_json::from_slice(&std::fs::read(p).ok()?).ok()
        }
        let report: IngestReport =
            read(layout.file(StageName::Ingest, files::INGEST_REPORT)).unwrap_or_default();
        let Some(d) = read::<DisuptOut>(layout.file(StageName::Disupt, files::DISUPT_REPORT))
        else {
            println!("{:<16} no DISUPT report", o.name);
            continue;
        };
        let method = |name: &str| d.methods.get(name);
        let err =
            |m: Option<&MethodOut>| m.map_or(f64::NAN, |m| m.outcome.dx_m.hypot(m.outcome.dy_m));
        let joint = method("joint");
        let sigma = joint.and_then(|j| j.outcome.x.sigma.as_ref());
        let holdout_max = joint
            .and_then(|j| j.holdout.as_deref())
            .and_then(unz_stages::disupt::holdout_median_max_m)
            .map_or(f64::NAN, |h| h.1);
        println!(
            "{:<16} {:>7} {:>8} {:>9.0} {:>10.1} {:>10.1} {:>10.1} {:>10.1} {:>12.3} {:>13} {:>12.1}",
            o.name,
            report.imu_accepted,
            report.rejected_all_files(),
            d.distance_m,
            d.before.dx_m.hypot(d.before.dy_m),
            err(method("oepi")),
            err(method("owpi")),
            err(joint),
            sigma.map_or(f64::NAN, |s| s.azimuth_deg),
            joint.zip(sigma).map_or("–".into(), |(j, s)| format!(
                "{:.2}±{:.2}",
                j.outcome.x.odo_lag_s, s.odo_lag_s
            )),
            holdout_max,
        );
    }
    println!(
        "errors are horizontal distances at the last control point; the odometer lag is the joint \
         fit's (the runs' odometers report 0.2 s late), hold-out the largest error at a control \
         point left out of the joint fit"
    );
    println!(
        "campaign: {}\nresults:  {} (per run: ingest/ derive/ navigate/ criteria/ disupt/ export/ review/)\nreport:   {}\nrecordings (open with `rerun FILE`):",
        campaign.display(),
        results.display(),
        results.join("campaign.html").display()
    );
    for o in outcomes.iter().filter(|o| o.error.is_none()) {
        println!(
            "  {}",
            results
                .join(&o.name)
                .join("review")
                .join(crate::review::rrd_name(&o.name))
                .display()
        );
    }
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
