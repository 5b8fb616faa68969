//! `unz config --show [--config FILE] [RUN]`: the effective parameters as TOML.

use std::process::ExitCode;

use crate::cli::ConfigArgs;
use crate::runs::load_run;

/// Runs the command (showing is its only action; `--show` says so on the command line).
pub fn run(args: &ConfigArgs) -> anyhow::Result<ExitCode> {
    let table = crate::config::load(args.config.as_deref())?;
    let params = match &args.run {
        Some(run) => crate::config::for_run(&table, &load_run(run)?)?,
        None => crate::config::effective(&table, None)?,
    };
    print!("{}", crate::config::to_toml(&params)?);
    Ok(ExitCode::SUCCESS)
}
