//! Command-line definitions (clap derive; doc comments are the help text).
// The doc comments are written for the terminal (`OUT/<name>`, `[params]`), not as
// Markdown.
#![allow(rustdoc::invalid_html_tags, rustdoc::broken_intra_doc_links)]

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
    /// Derive odometer terms and accelerometer pitch/roll (runs ingest first if needed).
    Derive(StageArgs),
    /// Navigate the run (odometer-aided strapdown dead reckoning).
    Navigate(NavArgs),
    /// Compute the criteria Kryt1 and Kryt2 of a navigation.
    Criteria(NavArgs),
    /// Correct the initial settings with DISUPT (OEPI, OWPI, joint).
    Disupt(DisuptArgs),
    /// Sensitivity map: Kryt1 and Kryt2 over a grid of one or two settings.
    Sweep(SweepArgs),
    /// Export the corrected navigation: corrected.mcap (ROS 2 messages, for Foxglove and Rerun).
    Export(StageArgs),
    /// Write the run's Rerun recording for review (OUT/<name>/review/<name>.rrd).
    Review(StageArgs),
    /// Run the stages over a run or a whole campaign folder, in parallel, with a summary.
    Run(RunArgs),
    /// Show the effective parameters (defaults, --config file, a run's [params]).
    Config(ConfigArgs),
    /// Work on campaign summaries.
    Campaign(CampaignArgs),
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
    /// Yaw of the IMU on the vehicle, degrees: the odometer's direction of travel is the
    /// IMU's x axis turned by it (what `[disupt] joint_odo_yaw` estimates).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub odo_boresight_deg: f64,
    /// Pitch of the vehicle's path above the IMU's x axis, degrees (an IMU pitched nose
    /// down on its mount by it): what the disupt stage fits to the control points' heights.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub odo_pitch_deg: f64,
    /// Odometer lag, s: the count logged with IMU time t is the distance at t − lag
    /// (derive's `odo_time_offset_s` = −lag undoes it).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub odo_lag_s: f64,
    /// Put a control point at every intermediate stop (default: mid-route and final only).
    #[arg(long)]
    pub cp_at_every_stop: bool,
    /// Begin the log this far into the run, s, while driving: no static start
    /// (`static_s = 0` in the manifest), the site and truth taken at that moment.
    #[arg(long)]
    pub log_start_s: Option<f64>,
    /// Survey each control point under the vehicle's mark, this far from the navigated
    /// (odometer's) point in the IMU's axes: x forward, y right, z down, m (as
    /// `x,y,z`). The manifest then gives it in `[params.vehicle] mark_lever_arm_m`.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub mark_lever_arm_m: Option<Vec<f64>>,
    /// Drive each route out and back: every control point but the far one is visited and
    /// marked twice, at the same place, and the run ends at its start, on a point of its
    /// own. Not with a mark lever arm.
    #[arg(long)]
    pub out_and_back: bool,
    /// Write the IMU's increments in these axes (where the log's x, y, z point on the
    /// vehicle: F/B, R/L, D/U; "FLU" for ROS's x forward, y left, z up), as an IMU
    /// mounted so would log them; the manifest names them in `[params.vehicle] imu_axes`.
    #[arg(long, default_value = "FRD")]
    pub imu_axes: unz_stages::imu_axes::ImuAxes,
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

/// Arguments of the navigation stages: every initial setting can be overridden.
#[derive(Debug, Args)]
pub struct NavArgs {
    /// Run folder and output folder.
    #[command(flatten)]
    pub stage: StageArgs,
    /// Initial azimuth (azpocz), degrees clockwise from true north.
    #[arg(long, allow_hyphen_values = true)]
    pub azimuth_deg: Option<f64>,
    /// Gyro drifts x,y,z in rad/s (subtracted from the measured rates).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub drift_rad_s: Option<Vec<f64>>,
    /// Metres per odometer pulse (text logs: a multiplier on the odometer distance).
    #[arg(long)]
    pub odo_scale_m_per_pulse: Option<f64>,
}

impl NavArgs {
    /// The overrides these flags ask for.
    pub fn overrides(&self) -> anyhow::Result<crate::flow::Overrides> {
        let drift_rad_s = match self.drift_rad_s.as_deref() {
            None => None,
            Some([x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => Some([*x, *y, *z]),
            Some(other) => {
                anyhow::bail!("--drift-rad-s needs three finite numbers x,y,z, got {other:?}")
            }
        };
        if let Some(s) = self.odo_scale_m_per_pulse
            && !(s.is_finite() && s > 0.0)
        {
            anyhow::bail!("--odo-scale-m-per-pulse must be positive, got {s}");
        }
        if let Some(a) = self.azimuth_deg
            && !a.is_finite()
        {
            anyhow::bail!("--azimuth-deg must be finite");
        }
        Ok(crate::flow::Overrides {
            azimuth_deg: self.azimuth_deg,
            drift_rad_s,
            odo_scale_m_per_pulse: self.odo_scale_m_per_pulse,
        })
    }
}

/// Arguments of `unz disupt`.
#[derive(Debug, Args)]
pub struct DisuptArgs {
    /// Run folder and output folder.
    #[command(flatten)]
    pub stage: StageArgs,
    /// Which method(s).
    #[arg(long, value_enum, default_value = "all")]
    pub method: crate::disupt_stage::Method,
}

/// Arguments of `unz sweep`.
#[derive(Debug, Args)]
pub struct SweepArgs {
    /// Run folder and output folder.
    #[command(flatten)]
    pub stage: StageArgs,
    /// Grid: `name=from:to:count[,name=from:to:count]`, names among azimuth_deg,
    /// drift_x_rad_s, drift_y_rad_s, drift_z_rad_s, odo_scale, odo_yaw_deg (absolute
    /// values).
    #[arg(long, allow_hyphen_values = true)]
    pub over: String,
}

/// Arguments of `unz run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// A run folder, a run.toml, or a campaign folder (every run.toml below it).
    pub path: PathBuf,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Force this stage and every later one (ingest, derive, navigate, criteria, disupt,
    /// export, review).
    #[arg(long)]
    pub from: Option<String>,
    /// Last stage to run (default: review, the last).
    #[arg(long)]
    pub until: Option<String>,
    /// Runs processed at once (default: all cores).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Process a deterministic 1/N of the runs: I/N with 0 <= I < N.
    #[arg(long)]
    pub shard: Option<String>,
    /// Parameter file (TOML); a run's `[params]` in run.toml overrides it.
    #[arg(long)]
    pub config: Option<PathBuf>,
}

/// Arguments of `unz config`.
#[derive(Debug, Args)]
pub struct ConfigArgs {
    /// Print the effective parameters as TOML.
    #[arg(long)]
    pub show: bool,
    /// Parameter file (TOML) over the built-in defaults.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A run (folder or run.toml) whose `[params]` apply on top.
    pub run: Option<PathBuf>,
}

/// Arguments of `unz campaign`.
#[derive(Debug, Args)]
pub struct CampaignArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: CampaignCommand,
}

/// `unz campaign` subcommands.
#[derive(Debug, Subcommand)]
pub enum CampaignCommand {
    /// Merge the campaign.parquet of shard output folders into one file, and pool their
    /// runs as one campaign: the sections beside it (`all.parquet` → `all.md`) and the
    /// vehicle's settings they agree on (`all-settings.toml`).
    Merge {
        /// Output folders of the shards.
        #[arg(required = true)]
        outs: Vec<PathBuf>,
        /// Merged summary to write.
        #[arg(long)]
        into: PathBuf,
        /// The config the shards ran with: the settings file is it with the pooled
        /// settings.
        #[arg(long)]
        config: Option<PathBuf>,
    },
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
    /// Runs of the campaign benchmark.
    #[arg(long, default_value_t = 20)]
    pub runs: u32,
}

/// Benchmarks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchTarget {
    /// Raw UNZ log → Parquet (and the full ingest with MCAP).
    Ingest,
    /// Navigation kernel and criteria evaluation (derive done once).
    Navigate,
    /// A campaign of simulated runs end to end, cold then cached (--runs, --duration-s).
    Campaign,
    /// Writing one run's Rerun recording from its cached tables, and its size.
    Review,
    /// OEPI, OWPI and joint on one run (derive done once), with passes per method; then one
    /// round of the joint fit's odometer lag search (three trials in one walk).
    Disupt,
    /// A 41 × 41 sweep (azimuth × driftz) on one run (derive done once).
    Sweep,
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
        let cli = Cli::try_parse_from([
            "unz",
            "navigate",
            "r",
            "--out",
            "o",
            "--drift-rad-s",
            "-1e-6,2e-6,0",
            "--azimuth-deg",
            "-3",
        ])
        .unwrap();
        let Command::Navigate(a) = cli.command else {
            panic!()
        };
        let o = a.overrides().unwrap();
        assert_eq!(o.drift_rad_s, Some([-1e-6, 2e-6, 0.0]));
        assert_eq!(o.azimuth_deg, Some(-3.0));
        let cli = Cli::try_parse_from(["unz", "navigate", "r", "--out", "o", "--drift-rad-s=1,2"])
            .unwrap();
        let Command::Navigate(a) = cli.command else {
            panic!()
        };
        assert!(a.overrides().is_err());
    }
}
