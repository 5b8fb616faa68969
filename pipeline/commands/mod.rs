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

/// Whether `command` is one stage's (ingest to review): it works on one run.
fn is_stage(command: &Command) -> bool {
    matches!(
        command,
        Command::Ingest(_)
            | Command::Derive(_)
            | Command::Navigate(_)
            | Command::Criteria(_)
            | Command::Disupt(_)
            | Command::Sweep(_)
            | Command::Export(_)
            | Command::Review(_)
    )
}

/// Whether `command` benchmarks one run's stages (every bench but the campaign's, which
/// runs many at once): it measures them with the allocator's settings their commands
/// take ([`crate::memory::one_run_at_a_time`]).
fn benches_one_run(command: &Command) -> bool {
    matches!(command, Command::Bench(a) if a.what != crate::cli::BenchTarget::Campaign)
}

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
    // A stage command works on one run: its threads share one malloc arena, which keeps
    // what is freed (`unz run` decides once it knows how many runs it has); a bench of
    // one run's stages measures them so.
    if is_stage(&cli.command) || benches_one_run(&cli.command) {
        crate::memory::one_run_at_a_time();
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

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    fn command(args: &[&str]) -> Command {
        Cli::try_parse_from(args).unwrap().command
    }

    /// A stage's command (and a sweep's) works on one run; `unz run` decides once it
    /// has found its runs; the other commands work on none.
    #[test]
    fn what_works_on_one_run() {
        for stage in [
            "ingest", "derive", "navigate", "criteria", "disupt", "export", "review",
        ] {
            assert!(
                is_stage(&command(&["unz", stage, "r", "--out", "o"])),
                "{stage}"
            );
        }
        let sweep = ["unz", "sweep", "r", "--out", "o", "--over", "azimuth"];
        assert!(is_stage(&command(&sweep)));
        assert!(!is_stage(&command(&["unz", "run", "r", "--out", "o"])));
        assert!(!is_stage(&command(&["unz", "simulate", "--out", "o"])));
        assert!(!is_stage(&command(&["unz", "bench", "disupt"])));
    }
}
