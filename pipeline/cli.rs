//! Command-line definitions (clap derive; doc comments are the help text).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// Post-process UNZ land-navigation logs and correct them with DISUPT.
#[derive(Debug, Parser)]
#[command(name = "unz", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simulate field runs (run.toml, raw .unz log and truth.parquet per run).
    Simulate(SimulateArgs),
    /// Ingest a run's raw log into Parquet and MCAP with an exact account of its records.
    Ingest(StageArgs),
    /// Simulate a small example and push it through every stage.
    Demo(DemoArgs),
    /// Measure throughput (not part of the tests).
    Bench(BenchArgs),
}

/// Arguments of `unz simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Output folder; one sub-folder per run.
    #[arg(long)]
    pub out: PathBuf,
    /// Random seed of the first run (run i uses seed + i).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Number of runs.
    #[arg(long, default_value_t = 1)]
    pub runs: u32,
    /// Length of each run, s.
    #[arg(long, default_value_t = 2400.0)]
    pub duration_s: f64,
    /// Static start, s (at least 60).
    #[arg(long, default_value_t = 90.0)]
    pub static_s: f64,
    /// Also write a damaged copy of each run (`<name>-faulty/`) with its expected accounting.
    #[arg(long)]
    pub faults: bool,
    /// Error of the manifest's azimuth, degrees (default: random, 4–8° either way).
    #[arg(long, allow_hyphen_values = true)]
    pub azimuth_error_deg: Option<f64>,
    /// No random sensor noise (angle and velocity random walk).
    #[arg(long)]
    pub no_noise: bool,
    /// No accelerometer biases.
    #[arg(long)]
    pub no_accel_bias: bool,
    /// No gyro drifts.
    #[arg(long)]
    pub no_gyro_drift: bool,
    /// No odometer scale error.
    #[arg(long)]
    pub no_odo_scale_error: bool,
}

/// Arguments shared by the stage commands.
#[derive(Debug, Args)]
pub struct StageArgs {
    /// Run folder, or its run.toml.
    pub run: PathBuf,
    /// Output folder: results go to OUT/<run name>/<stage>/.
    #[arg(long)]
    pub out: PathBuf,
}

/// Arguments of `unz demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder of the example campaign and its results.
    #[arg(long, default_value = "unz-demo")]
    pub out: PathBuf,
}

/// Arguments of `unz bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// What to measure.
    #[arg(value_enum)]
    pub what: BenchTarget,
    /// Simulated run length used as input, s.
    #[arg(long, default_value_t = 2400.0)]
    pub duration_s: f64,
    /// Repetitions (the best is reported).
    #[arg(long, default_value_t = 5)]
    pub repeat: u32,
}

/// Benchmarks.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum BenchTarget {
    /// Raw UNZ log → Parquet (and the full ingest with MCAP).
    Ingest,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_commands_parse() {
        let cli = Cli::try_parse_from(["unz", "ingest", "runs/r1", "--out", "out"]).unwrap();
        assert!(
            matches!(cli.command, Command::Ingest(a) if a.run == std::path::Path::new("runs/r1"))
        );
        let cli = Cli::try_parse_from([
            "unz",
            "simulate",
            "--out",
            "x",
            "--azimuth-error-deg",
            "-7",
            "--faults",
        ])
        .unwrap();
        assert!(
            matches!(cli.command, Command::Simulate(a) if a.azimuth_error_deg == Some(-7.0) && a.faults)
        );
        assert!(Cli::try_parse_from(["unz", "ingest", "runs/r1"]).is_err());
    }
}
