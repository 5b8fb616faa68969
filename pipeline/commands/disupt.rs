//! `unz disupt RUN --out OUT [--method oepi|owpi|joint|all]`.

use std::process::ExitCode;

use crate::artifacts::files;
use crate::cli::DisuptArgs;
use crate::disupt_stage::ensure_disupt;
use crate::flow::RunCtx;
use crate::runs::load_run;

/// Runs the command.
pub fn run(args: &DisuptArgs) -> anyhow::Result<ExitCode> {
    let ctx = RunCtx::new(load_run(&args.stage.run)?, args.stage.out.clone(), true);
    let dir = ensure_disupt(
        &ctx,
        &crate::config::for_run(&toml::Table::new(), &ctx.manifest)?,
        args.method,
    )?;
    print!(
        "{}",
        std::fs::read_to_string(dir.join(files::DISUPT_TABLES))?
    );
    println!("{}", dir.display());
    Ok(ExitCode::SUCCESS)
}
