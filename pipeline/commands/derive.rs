//! `unz derive RUN --out OUT`.

use std::process::ExitCode;

use crate::cli::StageArgs;
use crate::flow::{RunCtx, ensure_derive};
use crate::runs::load_run;

/// Runs the command.
pub fn run(args: &StageArgs) -> anyhow::Result<ExitCode> {
    let ctx = RunCtx::new(load_run(&args.run)?, args.out.clone(), true);
    let dir = ensure_derive(
        &ctx,
        &crate::config::for_run(&toml::Table::new(), &ctx.manifest)?,
    )?;
    println!("{}", dir.display());
    Ok(ExitCode::SUCCESS)
}
