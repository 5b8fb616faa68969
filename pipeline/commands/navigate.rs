//! `unz navigate RUN --out OUT [overrides]`.

use std::process::ExitCode;

use crate::artifacts::files;
use crate::cli::NavArgs;
use crate::flow::{NavigateSummary, RunCtx, ensure_navigate};
use crate::runs::load_run;

/// Runs the command.
pub fn run(args: &NavArgs) -> anyhow::Result<ExitCode> {
    let ctx = RunCtx::new(load_run(&args.stage.run)?, args.stage.out.clone(), true);
    let dir = ensure_navigate(
        &ctx,
        &crate::config::for_run(&toml::Table::new(), &ctx.manifest)?,
        &args.overrides()?,
    )?;
    let summary: NavigateSummary =
        serde_json::from_slice(&std::fs::read(dir.join(files::NAVIGATE_REPORT))?)?;
    let i = &summary.initial;
    println!(
        "{}: {:.0} m in {:.0} s; initial heading {:.3}° ({:?}), roll {:.3}°, pitch {:.3}°",
        ctx.manifest.name,
        summary.distance_m,
        summary.duration_s,
        i.azimuth_deg,
        i.azimuth_source,
        i.roll_deg,
        i.pitch_deg,
    );
    match (
        i.gyrocompass_deg,
        i.gyrocompass_sigma_deg,
        i.gyrocompass_skipped,
    ) {
        (Some(gc), Some(sigma), _) => println!("gyrocompass heading {gc:.3}° ± {sigma:.2}° (1σ)"),
        (_, _, Some(why)) => println!("gyrocompassing skipped: {why:?}"),
        _ => {}
    }
    for cp in &summary.control_points {
        println!(
            "control point {}: ΔX {:.1} m, ΔY {:.1} m",
            cp.id, cp.dx_m, cp.dy_m
        );
    }
    println!("{}", dir.display());
    Ok(ExitCode::SUCCESS)
}
