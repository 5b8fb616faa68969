//! `unz navigate RUN --out OUT [overrides]`.

use std::process::ExitCode;

use crate::cli::NavArgs;
use crate::flow::{RunCtx, ensure_navigate};
use crate::runs::load_run;

/// Runs the command.
pub fn run(args: &NavArgs) -> anyhow::Result<ExitCode> {
    let ctx = RunCtx::new(load_run(&args.stage.run)?, args.stage.out.clone(), true);
    let dir = ensure_navigate(
        &ctx,
        &crate::config::for_run(&toml::Table::new(), &ctx.manifest)?,
        &args.overrides()?,
    )?;
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("navigate.json"))?)?;
    let i = &summary["initial"];
    println!(
        "{}: {:.0} m in {:.0} s; initial heading {:.3}° ({}), roll {:.3}°, pitch {:.3}°",
        ctx.manifest.name,
        summary["distance_m"].as_f64().unwrap_or(0.0),
        summary["duration_s"].as_f64().unwrap_or(0.0),
        i["azimuth_deg"].as_f64().unwrap_or(0.0),
        i["azimuth_source"].as_str().unwrap_or(""),
        i["roll_deg"].as_f64().unwrap_or(0.0),
        i["pitch_deg"].as_f64().unwrap_or(0.0),
    );
    if let (Some(gc), Some(sigma)) = (
        i["gyrocompass_deg"].as_f64(),
        i["gyrocompass_sigma_deg"].as_f64(),
    ) {
        println!("gyrocompass heading {gc:.3}° ± {sigma:.2}° (1σ)");
    }
    for cp in summary["control_points"].as_array().into_iter().flatten() {
        println!(
            "control point {}: ΔX {:.1} m, ΔY {:.1} m",
            cp["id"],
            cp["dx_m"].as_f64().unwrap_or(0.0),
            cp["dy_m"].as_f64().unwrap_or(0.0)
        );
    }
    println!("{}", dir.display());
    Ok(ExitCode::SUCCESS)
}
