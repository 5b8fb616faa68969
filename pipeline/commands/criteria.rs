//! `unz criteria RUN --out OUT [overrides]`.

use std::process::ExitCode;

use crate::cli::NavArgs;
use crate::flow::{RunCtx, ensure_criteria};
use crate::runs::load_run;

/// Runs the command.
pub fn run(args: &NavArgs) -> anyhow::Result<ExitCode> {
    let ctx = RunCtx::new(load_run(&args.stage.run)?, args.stage.out.clone(), true);
    let (dir, s) = ensure_criteria(
        &ctx,
        &crate::config::for_run(&toml::Table::new(), &ctx.manifest)?,
        &args.overrides()?,
    )?;
    println!(
        "{}: Kryt1 {:.4} rad over {} of {} epochs",
        ctx.manifest.name, s.kryt1_rad, s.valid_epochs, s.epochs
    );
    for cp in &s.control_points {
        println!(
            "control point {}: ΔX {:.1} m, ΔY {:.1} m, Kryt2 {:.1} m",
            cp.id, cp.dx_m, cp.dy_m, cp.kryt2_m
        );
    }
    println!("{}", dir.display());
    Ok(ExitCode::SUCCESS)
}
