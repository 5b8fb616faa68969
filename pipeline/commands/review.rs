//! `unz review RUN --out OUT`: the run's Rerun recording (brings every stage before it up
//! to date first).

use std::process::ExitCode;

use crate::cli::StageArgs;
use crate::flow::RunCtx;
use crate::review::ensure_review;
use crate::runs::load_run;

/// Runs the command.
pub fn run(args: &StageArgs) -> anyhow::Result<ExitCode> {
    let ctx = RunCtx::new(load_run(&args.run)?, args.out.clone(), true);
    let out = ensure_review(
        &ctx,
        &crate::config::for_run(&toml::Table::new(), &ctx.manifest)?,
    )?;
    println!(
        "{} ({:.1} MB; open with `rerun {}`)",
        out.rrd.display(),
        out.bytes as f64 / 1e6,
        out.rrd.display()
    );
    Ok(ExitCode::SUCCESS)
}
