//! One file per subcommand, each with `run(args)`.

pub mod bench;
pub mod campaign;
pub mod config;
pub mod criteria;
pub mod demo;
pub mod derive;
pub mod disupt;
pub mod export;
pub mod ingest;
pub mod navigate;
pub mod review;
pub mod run;
pub mod simulate;
pub mod sweep;

use std::process::ExitCode;

use crate::cli::{Cli, Command};

/// Runs a parsed command line; the exit code says whether everything succeeded. A
/// command that writes into an output folder holds its lock while it runs.
pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    let out = match &cli.command {
        Command::Ingest(a) | Command::Derive(a) | Command::Export(a) | Command::Review(a) => {
            Some(a.out.clone())
        }
        Command::Navigate(a) | Command::Criteria(a) => Some(a.stage.out.clone()),
        Command::Disupt(a) => Some(a.stage.out.clone()),
        Command::Sweep(a) => Some(a.stage.out.clone()),
        Command::Run(a) => Some(a.out.clone()),
        Command::Demo(a) => Some(a.out.clone()),
        _ => None,
    };
    let _lock = out.as_deref().map(crate::lock::lock_output).transpose()?;
    // A stage command works on one run: its threads share one malloc arena (`unz run`
    // decides once it knows how many runs it has).
    if matches!(
        cli.command,
        Command::Ingest(_)
            | Command::Derive(_)
            | Command::Navigate(_)
            | Command::Criteria(_)
            | Command::Disupt(_)
            | Command::Sweep(_)
            | Command::Export(_)
            | Command::Review(_)
    ) {
        crate::memory::one_malloc_arena();
    }
    if let Some(out) = &out {
        crate::file_hashes::load(out);
    }
    let code = match cli.command {
        Command::Simulate(a) => simulate::run(&a),
        Command::Ingest(a) => ingest::run(&a),
        Command::Derive(a) => derive::run(&a),
        Command::Navigate(a) => navigate::run(&a),
        Command::Criteria(a) => criteria::run(&a),
        Command::Disupt(a) => disupt::run(&a),
        Command::Sweep(a) => sweep::run(&a),
        Command::Export(a) => export::run(&a),
        Command::Review(a) => review::run(&a),
        Command::Run(a) => run::run(&a),
        Command::Campaign(a) => campaign::run(&a),
        Command::Config(a) => config::run(&a),
        Command::Demo(a) => demo::run(&a),
        Command::Bench(a) => bench::run(&a),
    };
    // Saved whatever the outcome: what was hashed stays true (a failed save costs the
    // next process a read of the files, nothing else).
    if let Some(out) = &out
        && let Err(e) = crate::file_hashes::save(out)
    {
        eprintln!("warning: {e:#}");
    }
    code
}
