//! `unz sweep RUN --out OUT --over name=A:B:N[,name=C:D:M]`.

use std::process::ExitCode;

use crate::cli::SweepArgs;
use crate::flow::RunCtx;
use crate::runs::load_run;
use crate::sweep::{ensure_sweep, parse_over};

/// Runs the command.
pub fn run(args: &SweepArgs) -> anyhow::Result<ExitCode> {
    let axes = parse_over(&args.over)?;
    let ctx = RunCtx::new(load_run(&args.stage.run)?, args.stage.out.clone(), true);
    let dir = ensure_sweep(
        &ctx,
        &crate::config::for_run(&toml::Table::new(), &ctx.manifest)?,
        &axes,
    )?;
    print!("{}", std::fs::read_to_string(dir.join("sweep.json"))?);
    println!("{}", dir.join("sweep.parquet").display());
    Ok(ExitCode::SUCCESS)
}
