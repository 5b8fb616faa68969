//! `unz export RUN --out OUT`: corrected navigation as Parquet and MCAP (brings every
//! stage before it up to date first).

use std::process::ExitCode;

use crate::cli::StageArgs;
use crate::export::ensure_export;
use crate::flow::RunCtx;
use crate::runs::load_run;

/// Runs the command.
pub fn run(args: &StageArgs) -> anyhow::Result<ExitCode> {
    let ctx = RunCtx::new(load_run(&args.run)?, args.out.clone(), true);
    let dir = ensure_export(
        &ctx,
        &crate::config::for_run(&toml::Table::new(), &ctx.manifest)?,
    )?;
    println!("{}", dir.display());
    Ok(ExitCode::SUCCESS)
}
