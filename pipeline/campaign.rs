//! Whole campaigns: every run under a folder, processed in parallel, each run's stages in
//! order; a failing run is recorded with its error and never stops the others; one
//! summary row per run in `OUT/campaign.parquet` and `OUT/campaign.md`, the report
//! `OUT/campaign.html` with its plots, and what the runs pool (`crate::campaign_pools`):
//! `campaign.md`'s sections below the runs and `OUT/campaign-settings.toml`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, bail};
use arrow::array::{BooleanArray, Float64Array, RecordBatch, StringArray, UInt64Array};
use rayon::prelude::*;
use unz_formats::atomic::{remove_stale_temps_of, write_atomic};
use unz_formats::manifest::RunManifest;
use unz_formats::parquet_io::write_batch;
use unz_formats::report::{IngestReport, OdometerFailures};
use unz_formats::schema;
use unz_viz::report::{JointEstimate, ReportRow};

use crate::artifacts::{RunLayout, StageName, files};
use crate::campaign_pools::{Pools, RunReports};
use crate::disupt_stage::{DisuptOut, Method, MethodOut, SettingsOut, SigmaOut, ensure_disupt};
use crate::flow::marks::RepeatedMark;
use crate::flow::moving_marks::MovingMark;
use crate::flow::site_apart::SiteApart;
use crate::flow::{
    Cores, NavigateSummary, Overrides, RunCtx, ensure_criteria, ensure_derive, ensure_ingest,
    ensure_ingest_before_derive, ensure_navigate,
};
use unz_stages::initial::{AzimuthApart, LevelApart, StandTravel, StaticCut, StaticUnused};

/// The stages of `unz run`, in order.
pub const STAGES: [&str; 7] = [
    "ingest", "derive", "navigate", "criteria", "disupt", "export", "review",
];
/// Deepest folder searched for run manifests.
const MAX_DEPTH: usize = 8;

/// What the search for runs found: their manifests, and what it passed over that a user
/// should hear of.
#[derive(Debug, Default)]
pub struct FoundRuns {
    /// Every `run.toml` found, sorted.
    pub manifests: Vec<PathBuf>,
    /// A `run.toml` that is not a regular file (a symbolic link, which is not followed, or
    /// a FIFO, a device, a folder), or a folder below `path` that could not be listed or
    /// is deeper than the search: each with why, in the order met.
    pub skipped: Vec<(PathBuf, String)>,
}

/// Every `run.toml` under `path` (or `path` itself), down to `MAX_DEPTH` folders below
/// it; `out` is never searched and symlinks are not followed. A folder below `path` that
/// cannot be listed, or is deeper than that, is skipped and said, as is a `run.toml` that
/// is not a regular file: the rest of the campaign goes on.
pub fn find_runs(path: &Path, out: &Path) -> anyhow::Result<FoundRuns> {
    if let Some(manifest) = crate::runs::one_run_manifest(path) {
        return Ok(FoundRuns {
            manifests: vec![manifest],
            skipped: Vec::new(),
        });
    }
    let out_real = out.canonicalize().ok();
    let mut found = FoundRuns::default();
    let mut stack = vec![(path.to_path_buf(), 0usize)];
    while let Some((dir, depth)) = stack.pop() {
        let entries = match std::fs::read_dir(&dir) {
            Ok(entries) => entries,
            Err(e) if depth > 0 => {
                found.skipped.push((dir, format!("cannot list it: {e}")));
                continue;
            }
            Err(e) => return Err(e).with_context(|| format!("cannot list {}", dir.display())),
        };
        for e in entries {
            let e = match e {
                Ok(e) => e,
                Err(err) => {
                    found
                        .skipped
                        .push((dir.clone(), format!("cannot list all of it: {err}")));
                    continue;
                }
            };
            let p = e.path();
            let meta = match std::fs::symlink_metadata(&p) {
                Ok(meta) => meta,
                Err(err) => {
                    found
                        .skipped
                        .push((p, format!("cannot read what it is: {err}")));
                    continue;
                }
            };
            let hidden = e.file_name().to_string_lossy().starts_with('.');
            let searched =
                meta.is_dir() && !hidden && out_real.as_deref() != p.canonicalize().ok().as_deref();
            if searched && depth < MAX_DEPTH {
                stack.push((p, depth + 1));
            } else if searched {
                let why = format!(
                    "a folder {} below the campaign's, deeper than the search for runs \
                     ({MAX_DEPTH}): not searched",
                    depth + 1
                );
                found.skipped.push((p, why));
            } else if e.file_name() == crate::runs::MANIFEST {
                if meta.is_file() {
                    found.manifests.push(p);
                } else {
                    let why = if meta.file_type().is_symlink() {
                        "a symbolic link, not followed (a run's manifest must be a file in its \
                         folder)"
                    } else {
                        "not a regular file"
                    };
                    found.skipped.push((p, why.to_owned()));
                }
            }
        }
    }
    found.manifests.sort();
    Ok(found)
}

/// Whether the run named `name` belongs to shard `i` of `n` (stable under adding runs).
pub fn in_shard(name: &str, i: u64, n: u64) -> bool {
    let h = blake3::hash(name.as_bytes());
    let v = u64::from_le_bytes(h.as_bytes()[..8].try_into().unwrap_or_default());
    v % n == i
}

/// What `unz run` asks for.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Output root.
    pub out: PathBuf,
    /// Force this stage and its descendants.
    pub from: Option<usize>,
    /// Last stage.
    pub until: usize,
    /// The config file's table (defaults for keys it lacks; runs' `[params]` override it).
    pub config: toml::Table,
    /// Shard `(i, n)`.
    pub shard: Option<(u64, u64)>,
    /// Say what each stage did (plain log lines).
    pub verbose: bool,
    /// Show progress bars (on a terminal).
    pub progress: bool,
}

impl Plan {
    /// Every stage into `out`, default parameters, quiet (the demo and the benchmark).
    pub fn every_stage(out: PathBuf) -> Self {
        Self {
            out,
            from: None,
            until: STAGES.len() - 1,
            config: toml::Table::new(),
            shard: None,
            verbose: false,
            progress: false,
        }
    }
}

/// One run's outcome.
#[derive(Debug, Clone)]
pub struct RunOutcome {
    /// Run name (the folder name when the manifest is unreadable).
    pub name: String,
    /// Manifest path.
    pub manifest: PathBuf,
    /// The error, if it failed.
    pub error: Option<String>,
    /// Stage log: (stage, computed, wall s).
    pub stages: Vec<(String, bool, f64)>,
    /// Wall time, s.
    pub wall_s: f64,
}

fn process(
    manifest: &RunManifest,
    plan: &Plan,
    bar: Option<indicatif::ProgressBar>,
    cores: Cores,
) -> (anyhow::Result<()>, Vec<(String, bool, f64)>) {
    let mut ctx = RunCtx::new(manifest.clone(), plan.out.clone(), plan.verbose);
    ctx.progress = bar;
    ctx.cores = cores;
    let result = (|| -> anyhow::Result<()> {
        if let Some(from) = plan.from {
            for stage in &STAGES[from..] {
                let record = plan
                    .out
                    .join(&manifest.name)
                    .join(stage)
                    .join(crate::stage::RECORD);
                match std::fs::remove_file(&record) {
                    Ok(()) => {}
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                    Err(e) => {
                        return Err(e)
                            .with_context(|| format!("cannot remove {}", record.display()));
                    }
                }
            }
        }
        let params = crate::config::for_run(&plan.config, manifest)?;
        let p = &params;
        let none = Overrides::default();
        for stage in &STAGES[..=plan.until] {
            match *stage {
                // The derive, when it follows, takes the series the ingest writes.
                "ingest" if plan.until > 0 => drop(ensure_ingest_before_derive(&ctx, p)?),
                "ingest" => drop(ensure_ingest(&ctx, p)?),
                "derive" => drop(ensure_derive(&ctx, p)?),
                "navigate" => drop(ensure_navigate(&ctx, p, &none)?),
                "criteria" => drop(ensure_criteria(&ctx, p, &none)?),
                "disupt" => drop(ensure_disupt(&ctx, p, Method::All)?),
                "export" => drop(crate::export::ensure_export(&ctx, p)?),
                _ => drop(crate::review::ensure_review(&ctx, p)?),
            }
        }
        Ok(())
    })();
    let log = ctx.log.lock().map(|l| l.clone()).unwrap_or_default();
    (result, log)
}

/// Runs a campaign; returns one outcome per run, in manifest order.
pub fn run_campaign(manifests: &[PathBuf], plan: &Plan) -> Vec<RunOutcome> {
    // Load every manifest first: names must be unique within the campaign.
    let loaded: Vec<(PathBuf, anyhow::Result<RunManifest>)> = manifests
        .iter()
        .map(|p| (p.clone(), RunManifest::load(p).map_err(anyhow::Error::from)))
        .collect();
    let mut seen = std::collections::HashMap::new();
    let checked: Vec<(PathBuf, String, anyhow::Result<RunManifest>)> = loaded
        .into_iter()
        .map(|(path, m)| {
            let fallback = path.parent().and_then(|d| d.file_name()).map_or_else(
                || path.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            );
            match m {
                Ok(m) => match seen.insert(m.name.clone(), path.clone()) {
                    Some(first) => {
                        let e = anyhow::anyhow!(
                            "run name {:?} is already used by {}",
                            m.name,
                            first.display()
                        );
                        (path, fallback, Err(e))
                    }
                    None => (path, m.name.clone(), Ok(m)),
                },
                Err(e) => (path, fallback, Err(e)),
            }
        })
        .filter(|(_, name, _)| plan.shard.is_none_or(|(i, n)| in_shard(name, i, n)))
        .collect();
    let bars = plan.progress.then(|| {
        let multi = indicatif::MultiProgress::new();
        let total = multi.add(indicatif::ProgressBar::new(checked.len() as u64));
        total.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:30} {pos}/{len} runs  {msg}  [{elapsed_precise}]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        (multi, total)
    });
    let counts = std::sync::Mutex::new((0usize, 0usize)); // failed, cached
    // Runs side by side share the cores (a campaign of one has them).
    let cores = if checked.len() > 1 {
        Cores::Shared
    } else {
        Cores::Own
    };
    let outcomes = checked
        .into_par_iter()
        .map(|(path, name, m)| {
            let t0 = Instant::now();
            let bar = bars.as_ref().map(|(multi, _)| {
                let b = multi.add(indicatif::ProgressBar::new_spinner());
                b.enable_steady_tick(std::time::Duration::from_millis(200));
                b.set_message(name.clone());
                b
            });
            let (result, stages) = match m {
                Ok(m) => guarded(|| process(&m, plan, bar.clone(), cores))
                    .unwrap_or_else(|e| (Err(e), Vec::new())),
                Err(e) => (Err(e), Vec::new()),
            };
            if let Some(b) = bar {
                b.finish_and_clear();
            }
            let error = result.err().map(|e| format!("{e:#}"));
            if let (Some((_, total)), Ok(mut c)) = (&bars, counts.lock()) {
                c.0 += usize::from(error.is_some());
                c.1 += usize::from(error.is_none() && stages.iter().all(|s| !s.1));
                total.inc(1);
                total.set_message(format!("{} failed, {} cached", c.0, c.1));
            }
            if plan.verbose {
                match &error {
                    None => eprintln!("{name}: done in {:.2} s", t0.elapsed().as_secs_f64()),
                    Some(e) => eprintln!("{name}: FAILED: {e}"),
                }
            }
            RunOutcome {
                name,
                manifest: path,
                error,
                stages,
                wall_s: t0.elapsed().as_secs_f64(),
            }
        })
        .collect();
    if let Some((_, total)) = bars {
        total.finish_and_clear();
    }
    outcomes
}

/// Runs `f`, a panic in it turned into an error that says it is unz's bug: a defect that
/// one run's data reaches fails that run alone, and the campaign's other runs and its
/// summary go on (the panic's message and place are on stderr too, from the panic hook).
/// A stage that panicked never recorded itself done, and its outputs are written whole or
/// not at all, so a re-run redoes it.
fn guarded<R>(f: impl FnOnce() -> R) -> anyhow::Result<R> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "no message".to_owned());
        anyhow::anyhow!("internal error, a bug in unz (please report it with this run): {what}")
    })
}

/// A run's report, read through its type; `None` when the run did not get that far.
pub(crate) fn read_report<T: serde::de::DeserializeOwned>(path: &Path) -> Option<T> {
    serde_json::from_slice(&std::fs::read(path).ok()?).ok()
}

/// What the summary says of a run whose odometer failed on some samples: flagged by the
/// log (status bit 1), or a count that stood while the vehicle moved (a run fails above a
/// tenth of both), from the ingest's account of its failures: bridged by the
/// inertial along-track speed, with how long and how far; not bridged, the dead reckoning
/// has no distance over them, so the route after them is short by what the vehicle drove
/// meanwhile, which the control points and the methods' fits then show.
fn odometer_failure_note(n: &NavigateSummary, failures: Option<&OdometerFailures>) -> String {
    let seconds = |samples: u64| samples as f64 * n.duration_s / n.samples.max(1) as f64;
    let flagged = (n.odometer_failure_samples > 0).then(|| {
        format!(
            "the odometer is flagged failed (status bit 1) on {} samples ({:.1} s)",
            n.odometer_failure_samples,
            seconds(n.odometer_failure_samples as u64)
        )
    });
    let stuck = failures.filter(|f| f.stuck > 0).map(|f| {
        format!(
            "the odometer's distance stood while the vehicle moved, unflagged: {} \
             time{} ({} samples, {:.1} s)",
            f.stuck,
            if f.stuck == 1 { "" } else { "s" },
            f.stuck_samples,
            seconds(f.stuck_samples)
        )
    });
    let gaps = failures.filter(|f| f.file_gaps > 0).map(|f| {
        format!(
            "the odometer file has no readings over {} gap{} longer than {:.0} s",
            f.file_gaps,
            if f.file_gaps == 1 { "" } else { "s" },
            crate::odometer_gaps::MIN_GAP_S
        )
    });
    let bridged = failures.filter(|f| f.bridged > 0).map(|f| {
        let one_ended = match f.one_ended {
            0 => String::new(),
            k => format!(
                ", {k} of them at the log's end from the readings before it alone (its \
                 distance drifts faster)"
            ),
        };
        let how_long = if f.bridged == 1 {
            format!("1 failure ({:.1} s", f.longest_bridged_s)
        } else {
            format!(
                "{} failures (the longest {:.1} s",
                f.bridged, f.longest_bridged_s
            )
        };
        format!(
            "bridged by the inertial along-track speed: {how_long}, {:.0} m driven over {}){one_ended}",
            f.bridged_distance_m,
            if f.bridged == 1 { "it" } else { "them" },
        )
    });
    let spikes = failures.filter(|f| f.spikes > 0).map(|f| {
        format!(
            "{} odometer speed{} left out as spikes (jumping from the speed faster than a \
             land vehicle brakes or accelerates, and back)",
            f.spikes,
            if f.spikes == 1 { "" } else { "s" },
        )
    });
    let jumps_kept = failures.filter(|f| f.jumps_kept > 0).map(|f| {
        format!(
            "the odometer's speed jumped faster than a land vehicle brakes or accelerates \
             {} time{} without coming back within {:.0} s: kept, unjudged (a fault the \
             speed alone cannot place, or junk)",
            f.jumps_kept,
            if f.jumps_kept == 1 { "" } else { "s" },
            unz_formats::speed_spikes::MAX_BURST_S
        )
    });
    let not_bridged = failures.map_or(0, |f| f.not_bridged);
    let file_gaps = failures.is_some_and(|f| f.file_gaps > 0);
    let trapezoid = (not_bridged > 0 && file_gaps).then(|| {
        format!(
            "{not_bridged} not bridged (longer than {:.0} s, or without readings around it): \
             the distance over {} is the trapezoid of the speeds at {} ends",
            crate::odometer_bridge::MAX_BRIDGED_S,
            if not_bridged == 1 { "it" } else { "them" },
            if not_bridged == 1 { "its" } else { "their" },
        )
    });
    let lost = (!file_gaps && (not_bridged > 0 || failures.is_none())).then(|| {
        let which = match failures {
            Some(f) => format!(
                "{not_bridged} failure{} ({} samples) not bridged (longer than {:.0} s, or \
                 without readings around it): ",
                if not_bridged == 1 { "" } else { "s" },
                f.not_bridged_samples,
                crate::odometer_bridge::MAX_BRIDGED_S
            ),
            None => String::new(),
        };
        format!(
            "{which}the dead reckoning has no distance over them, so the route after them is \
             short by what the vehicle drove meanwhile, and the control points' errors and \
             the methods' fits carry it"
        )
    });
    flagged
        .into_iter()
        .chain(spikes)
        .chain(jumps_kept)
        .chain(gaps)
        .chain(stuck)
        .chain(bridged)
        .chain(trapezoid)
        .chain(lost)
        .collect::<Vec<_>>()
        .join("; ")
}

/// What the summary's error column says of a run that did not fail: an odometer flagged
/// failed on some samples (bridged or not, and bridged again at the joint's lag); the
/// methods its disupt stage did not run
/// (those refused for one reason together) or ran but did not use for the corrected
/// navigation, with the reason; a coarse azimuth turn refused; an odometer yaw boresight
/// the joint fit's residuals show (and estimated); the control points the joint fit's
/// hold-out finds inconsistent with the rest of the run; and the control points marked
/// more than once, with the mark used.
fn run_note(
    d: Option<&DisuptOut>,
    nav: Option<&NavigateSummary>,
    ing: Option<&IngestReport>,
) -> String {
    let skipped = d.into_iter().flat_map(|d| &d.skipped);
    let repeated = nav.into_iter().flat_map(|n| &n.repeated_marks);
    let moving = nav.into_iter().flat_map(|n| &n.moving_marks);
    let inconsistent = d
        .and_then(|d| d.methods.get("joint")?.holdout.as_deref())
        .and_then(unz_stages::disupt::inconsistent_points_note);
    let coarse_refused = d
        .and_then(|d| d.coarse_azimuth_refused.as_ref())
        .map(crate::disupt_stage::coarse_refused_note);
    let odo_yaw = d
        .and_then(|d| d.joint_odo_yaw_check.as_ref())
        .and_then(crate::disupt_stage::odo_yaw_note);
    let mark_arm = d.and_then(crate::disupt_stage::joint_mark_arm_note);
    let heights = d
        .and_then(|d| d.odo_pitch.as_ref())
        .and_then(crate::campaign_pitch::heights_note);
    let lag_at_bound = d.and_then(|d| d.joint_odo_lag_at_bound_s).map(|lag| {
        format!(
            "the joint fit's odometer lag stopped at its search's bound ({lag:+.3} s beyond \
             the configured offset): it may lie beyond; widen `[disupt] odo_lag_bound_s` or \
             set `[derive] odo_time_offset_s`"
        )
    });
    let failures = ing.and_then(|i| i.odometer_failures.as_ref());
    let odo_failed = nav
        .filter(|n| {
            n.odometer_failure_samples > 0
                || failures.is_some_and(|f| f.stuck + f.file_gaps + f.spikes + f.jumps_kept > 0)
        })
        .map(|n| odometer_failure_note(n, failures));
    let rebridged = d
        .and_then(|d| d.methods.get("joint")?.rebridged.as_ref())
        .map(crate::disupt_stage::rebridged_note);
    // Methods refused for one reason (a run without motion refuses all three) share it.
    let mut by_reason: Vec<(Vec<&str>, &str)> = Vec::new();
    for (name, why) in skipped {
        match by_reason.iter_mut().find(|(_, w)| *w == why.as_str()) {
            Some((names, _)) => names.push(name),
            None => by_reason.push((vec![name], why)),
        }
    }
    let static_cut = nav.and_then(|n| n.initial.static_cut.as_ref());
    let static_unused = nav.and_then(|n| n.initial.static_unused.as_ref());
    let stand_travel = nav.and_then(|n| n.initial.stand_travel.as_ref());
    let level_apart = nav.and_then(|n| n.initial.level_apart.as_ref());
    let azimuth_apart = nav.and_then(|n| n.initial.azimuth_apart.as_ref());
    (static_cut.map(StaticCut::said))
        .into_iter()
        .chain(static_unused.map(StaticUnused::said))
        .chain(stand_travel.map(StandTravel::said))
        .chain(azimuth_apart.map(AzimuthApart::said))
        .chain(level_apart.map(LevelApart::said))
        .chain(ing.and_then(|i| i.speed_floor).map(|f| f.said()))
        .chain(ing.and_then(|i| i.speed_column_unread_said()))
        .chain(ing.into_iter().flat_map(|i| i.time_base_said()))
        .chain(odo_failed)
        .chain(rebridged)
        .chain(
            by_reason
                .into_iter()
                .map(|(names, why)| format!("{} not run: {why}", names.join(", "))),
        )
        .chain(coarse_refused)
        .chain(odo_yaw)
        .chain(mark_arm)
        .chain(heights)
        .chain(lag_at_bound)
        .chain(
            d.into_iter()
                .flat_map(|d| &d.not_used)
                .map(|(name, why)| format!("{name} not used: {why}")),
        )
        .chain(inconsistent)
        .chain(
            nav.and_then(|n| n.unknown_marks.as_ref())
                .map(|u| format!("marks of ids no control point has: {}", u.listed())),
        )
        .chain(repeated.map(RepeatedMark::said))
        .chain(moving.map(MovingMark::said))
        .chain(nav.and_then(|n| n.site_apart.as_ref()).map(SiteApart::said))
        .collect::<Vec<_>>()
        .join("; ")
}

/// Median and largest horizontal hold-out error of the joint fit, m.
fn holdout_stats(j: &MethodOut) -> Option<(f64, f64)> {
    unz_stages::disupt::holdout_median_max_m(j.holdout.as_ref()?)
}

/// The summary's numeric columns, in order.
/// One run's numbers in the campaign summary: one field per `campaign.parquet` column
/// after the per-stage times (`None` where the run has no such number).
#[derive(Debug, Clone, Copy, Default)]
struct SummaryValues {
    /// Odometer distance of the run, m.
    distance_m: Option<f64>,
    /// IMU records accepted.
    imu_accepted: Option<f64>,
    /// Records rejected, every reason, and the odometer file's lines rejected.
    rejected: Option<f64>,
    /// IMU samples lost in gaps.
    lost_samples: Option<f64>,
    /// North error at the last control point before DISUPT, m.
    before_dx_m: Option<f64>,
    /// East error there before DISUPT, m.
    before_dy_m: Option<f64>,
    /// North error there after OEPI, m.
    oepi_dx_m: Option<f64>,
    /// East error there after OEPI, m.
    oepi_dy_m: Option<f64>,
    /// North error there after OWPI, m.
    owpi_dx_m: Option<f64>,
    /// East error there after OWPI, m.
    owpi_dy_m: Option<f64>,
    /// North error there after the joint fit, m.
    joint_dx_m: Option<f64>,
    /// East error there after the joint fit, m.
    joint_dy_m: Option<f64>,
    /// Joint azimuth, deg.
    joint_azimuth_deg: Option<f64>,
    /// Its 1σ, deg.
    joint_azimuth_sigma_deg: Option<f64>,
    /// Joint z drift, rad/s.
    joint_drift_z_rad_s: Option<f64>,
    /// Its 1σ, rad/s.
    joint_drift_z_sigma_rad_s: Option<f64>,
    /// Joint odometer scale (multiplier).
    joint_odo_scale: Option<f64>,
    /// Its 1σ.
    joint_odo_scale_sigma: Option<f64>,
    /// Joint odometer boresight yaw, deg.
    joint_odo_yaw_deg: Option<f64>,
    /// Its 1σ, deg.
    joint_odo_yaw_sigma_deg: Option<f64>,
    /// Joint odometer lag, s.
    joint_odo_lag_s: Option<f64>,
    /// Its 1σ, s.
    joint_odo_lag_sigma_s: Option<f64>,
    /// Joint odometer speed bias, m/s.
    joint_odo_bias_mps: Option<f64>,
    /// Its 1σ, m/s.
    joint_odo_bias_sigma_mps: Option<f64>,
    /// Median hold-out error over the control points, m.
    joint_holdout_median_m: Option<f64>,
    /// Largest hold-out error, m.
    joint_holdout_max_m: Option<f64>,
    /// Samples whose odometer distance is not the odometer's reading (failed: bridged or
    /// held), flagged or found stuck.
    odometer_failed_samples: Option<f64>,
    /// The largest change of a failure's distance across it when the joint fit bridged
    /// the failures again at its lag, against the ingest's bridge, m (signed).
    joint_rebridge_change_m: Option<f64>,
    /// Control points the joint fit left out as inconsistent with the rest of the run
    /// (0 when it ran and kept them all).
    joint_excluded_points: Option<f64>,
    /// The vehicle's mark forward of the navigated point (IMU axes), m, when the joint
    /// fit estimated it.
    joint_mark_forward_m: Option<f64>,
    /// Its 1σ, m.
    joint_mark_forward_sigma_m: Option<f64>,
    /// The vehicle's mark right of the navigated point, m, when the joint fit estimated
    /// it.
    joint_mark_right_m: Option<f64>,
    /// Its 1σ, m.
    joint_mark_right_sigma_m: Option<f64>,
    /// The odometer pitch boresight the control points' heights showed, deg (whether the
    /// corrected navigation took it or not).
    odo_pitch_deg: Option<f64>,
    /// 1 when the corrected navigation took it, 0 when it was refused.
    odo_pitch_applied: Option<f64>,
    /// The corrected navigation's height error at the last control point the fit read, m.
    corrected_dh_m: Option<f64>,
    /// Wall time of the run, s.
    wall_s: Option<f64>,
}

impl SummaryValues {
    /// The numbers of a run from its reports.
    fn of(ing: Option<&IngestReport>, d: Option<&DisuptOut>, wall_s: f64) -> Self {
        let method = |name: &str| d.and_then(|d| d.methods.get(name));
        let err = |name: &str| method(name).map(|m| (m.outcome.dx_m, m.outcome.dy_m));
        let joint = method("joint");
        let x = |f: fn(&SettingsOut) -> f64| joint.map(|j| f(&j.outcome.x));
        let sd = |f: fn(&SigmaOut) -> f64| joint.and_then(|j| j.outcome.x.sigma.as_ref()).map(f);
        let holdout = joint.and_then(holdout_stats);
        let mark = d.and_then(crate::campaign_pools::mark_estimate);
        let pitch = d.and_then(|d| d.odo_pitch.as_ref());
        Self {
            distance_m: d.map(|d| d.distance_m),
            imu_accepted: ing.map(|i| i.imu_accepted as f64),
            rejected: ing.map(|i| i.rejected_all_files() as f64),
            lost_samples: ing.map(|i| i.lost_samples as f64),
            before_dx_m: d.map(|d| d.before.dx_m),
            before_dy_m: d.map(|d| d.before.dy_m),
            oepi_dx_m: err("oepi").map(|e| e.0),
            oepi_dy_m: err("oepi").map(|e| e.1),
            owpi_dx_m: err("owpi").map(|e| e.0),
            owpi_dy_m: err("owpi").map(|e| e.1),
            joint_dx_m: err("joint").map(|e| e.0),
            joint_dy_m: err("joint").map(|e| e.1),
            joint_azimuth_deg: x(|x| x.azimuth_deg),
            joint_azimuth_sigma_deg: sd(|s| s.azimuth_deg),
            joint_drift_z_rad_s: x(|x| x.drift_rad_s[2]),
            joint_drift_z_sigma_rad_s: sd(|s| s.drift_rad_s[2]),
            joint_odo_scale: x(|x| x.odo_scale),
            joint_odo_scale_sigma: sd(|s| s.odo_scale),
            joint_odo_yaw_deg: x(|x| x.odo_yaw_deg),
            joint_odo_yaw_sigma_deg: sd(|s| s.odo_yaw_deg),
            joint_odo_lag_s: x(|x| x.odo_lag_s),
            joint_odo_lag_sigma_s: sd(|s| s.odo_lag_s),
            joint_odo_bias_mps: x(|x| x.odo_bias_mps),
            joint_odo_bias_sigma_mps: sd(|s| s.odo_bias_mps),
            joint_holdout_median_m: holdout.map(|h| h.0),
            joint_holdout_max_m: holdout.map(|h| h.1),
            odometer_failed_samples: ing.map(|i| {
                i.odometer_failures
                    .as_ref()
                    .map_or(0.0, |f| (f.bridged_samples + f.not_bridged_samples) as f64)
            }),
            joint_rebridge_change_m: joint
                .and_then(|j| j.rebridged.as_ref())
                .map(|r| r.largest_change_m),
            joint_excluded_points: joint
                .map(|j| j.holdout.iter().flatten().filter(|h| h.excluded).count() as f64),
            joint_mark_forward_m: mark.map(|m| m.forward_m.0),
            joint_mark_forward_sigma_m: mark.map(|m| m.forward_m.1),
            joint_mark_right_m: mark.map(|m| m.right_m.0),
            joint_mark_right_sigma_m: mark.map(|m| m.right_m.1),
            odo_pitch_deg: pitch.map(|p| p.odo_pitch_deg),
            odo_pitch_applied: pitch.map(|p| f64::from(u8::from(p.applied))),
            corrected_dh_m: pitch.and_then(|p| p.points.last()).map(|p| p.dh_m),
            wall_s: Some(wall_s),
        }
    }

    /// (column name, value) in the file's order.
    fn columns(&self) -> [(&'static str, Option<f64>); 37] {
        [
            ("distance_m", self.distance_m),
            ("imu_accepted", self.imu_accepted),
            ("rejected", self.rejected),
            ("lost_samples", self.lost_samples),
            ("before_dx_m", self.before_dx_m),
            ("before_dy_m", self.before_dy_m),
            ("oepi_dx_m", self.oepi_dx_m),
            ("oepi_dy_m", self.oepi_dy_m),
            ("owpi_dx_m", self.owpi_dx_m),
            ("owpi_dy_m", self.owpi_dy_m),
            ("joint_dx_m", self.joint_dx_m),
            ("joint_dy_m", self.joint_dy_m),
            ("joint_azimuth_deg", self.joint_azimuth_deg),
            ("joint_azimuth_sigma_deg", self.joint_azimuth_sigma_deg),
            ("joint_drift_z_rad_s", self.joint_drift_z_rad_s),
            ("joint_drift_z_sigma_rad_s", self.joint_drift_z_sigma_rad_s),
            ("joint_odo_scale", self.joint_odo_scale),
            ("joint_odo_scale_sigma", self.joint_odo_scale_sigma),
            ("joint_odo_yaw_deg", self.joint_odo_yaw_deg),
            ("joint_odo_yaw_sigma_deg", self.joint_odo_yaw_sigma_deg),
            ("joint_odo_lag_s", self.joint_odo_lag_s),
            ("joint_odo_lag_sigma_s", self.joint_odo_lag_sigma_s),
            ("joint_odo_bias_mps", self.joint_odo_bias_mps),
            ("joint_odo_bias_sigma_mps", self.joint_odo_bias_sigma_mps),
            ("joint_holdout_median_m", self.joint_holdout_median_m),
            ("joint_holdout_max_m", self.joint_holdout_max_m),
            ("odometer_failed_samples", self.odometer_failed_samples),
            ("joint_rebridge_change_m", self.joint_rebridge_change_m),
            ("joint_excluded_points", self.joint_excluded_points),
            ("joint_mark_forward_m", self.joint_mark_forward_m),
            (
                "joint_mark_forward_sigma_m",
                self.joint_mark_forward_sigma_m,
            ),
            ("joint_mark_right_m", self.joint_mark_right_m),
            ("joint_mark_right_sigma_m", self.joint_mark_right_sigma_m),
            ("odo_pitch_deg", self.odo_pitch_deg),
            ("odo_pitch_applied", self.odo_pitch_applied),
            ("corrected_dh_m", self.corrected_dh_m),
            ("wall_s", self.wall_s),
        ]
    }
}

/// The summaries [`write_summary`] writes into the output folder.
const SUMMARY_FILES: [&str; 4] = [
    "campaign.parquet",
    "campaign.md",
    "campaign.html",
    crate::campaign_settings::FILE,
];

/// Removes the temporary files of the summaries (`.campaign.<ext>.<random>.tmp`, and
/// `.campaign-settings.toml.<random>.tmp`) that a run killed while writing them left in
/// `out` (the output folder is this process's alone: see [`crate::lock`]).
fn remove_stale_summary_temps(out: &Path) {
    for name in SUMMARY_FILES {
        remove_stale_temps_of(&out.join(name));
    }
}

/// Writes `campaign.parquet`, `campaign.md` and `campaign.html` into `out`, and
/// `campaign-settings.toml` (`config`, the campaign's, with the vehicle's settings the
/// runs pooled) when they pooled one.
pub fn write_summary(
    out: &Path,
    outcomes: &[RunOutcome],
    config: &toml::Table,
) -> anyhow::Result<()> {
    remove_stale_summary_temps(out);
    let mut cols: Vec<(&str, Vec<Option<f64>>)> = SummaryValues::default()
        .columns()
        .iter()
        .map(|(n, _)| (*n, Vec::new()))
        .collect();
    let mut md = String::from(
        "| run | status | distance [m] | rejected | before [m] | OEPI [m] | OWPI [m] | joint [m] | joint az σ [°] | hold-out median / max [m] | odometer lag [s] | wall [s] | computed | error |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut notes: Vec<Option<String>> = Vec::with_capacity(outcomes.len());
    let mut rows: Vec<ReportRow> = Vec::with_capacity(outcomes.len());
    let mut pools = Pools::default();
    for o in outcomes {
        let layout = RunLayout::new(out, &o.name);
        let ing: Option<IngestReport> =
            read_report(&layout.file(StageName::Ingest, files::INGEST_REPORT));
        let reports = RunReports::read(out, &o.name, &o.manifest);
        pools.add(&o.name, &reports);
        let RunReports {
            disupt: d,
            navigate: nav,
            ..
        } = reports;
        let v = SummaryValues::of(ing.as_ref(), d.as_ref(), o.wall_s);
        let note = Some(run_note(d.as_ref(), nav.as_ref(), ing.as_ref()))
            .filter(|n| o.error.is_none() && !n.is_empty());
        for (c, (_, x)) in cols.iter_mut().zip(v.columns()) {
            c.1.push(x);
        }
        let h = |a: Option<f64>, b: Option<f64>| {
            a.zip(b)
                .map_or("–".into(), |(x, y)| format!("{:.1}", x.hypot(y)))
        };
        let computed: Vec<&str> = o
            .stages
            .iter()
            .filter(|s| s.1)
            .map(|s| s.0.as_str())
            .collect();
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.2} | {} | {} |",
            o.name,
            if o.error.is_none() { "ok" } else { "failed" },
            v.distance_m.map_or("–".into(), |x| format!("{x:.0}")),
            v.rejected.map_or("–".into(), |x| format!("{x:.0}")),
            h(v.before_dx_m, v.before_dy_m),
            h(v.oepi_dx_m, v.oepi_dy_m),
            h(v.owpi_dx_m, v.owpi_dy_m),
            h(v.joint_dx_m, v.joint_dy_m),
            v.joint_azimuth_sigma_deg
                .map_or("–".into(), |x| format!("{x:.3}")),
            v.joint_holdout_median_m
                .zip(v.joint_holdout_max_m)
                .map_or("–".into(), |(a, b)| format!("{a:.1} / {b:.1}")),
            v.joint_odo_lag_s
                .zip(v.joint_odo_lag_sigma_s)
                .filter(|(_, s)| *s > 0.0)
                .map_or("–".into(), |(l, s)| format!("{l:.3} ± {s:.3}")),
            o.wall_s,
            match (computed.is_empty(), o.stages.is_empty()) {
                (_, true) => "–".to_owned(),
                (true, false) => "cached".to_owned(),
                (false, false) => computed.join(", "),
            },
            o.error
                .clone()
                .or_else(|| note.clone())
                .unwrap_or_default()
                .replace('|', "/")
                .replace('\n', " "),
        );
        rows.push(report_row(out, o, d.as_ref(), note.clone()));
        notes.push(note);
    }
    let mut arrays: Vec<Arc<dyn arrow::array::Array>> = vec![
        Arc::new(StringArray::from(
            outcomes.iter().map(|o| o.name.clone()).collect::<Vec<_>>(),
        )),
        Arc::new(StringArray::from(
            outcomes
                .iter()
                .map(|o| o.manifest.display().to_string())
                .collect::<Vec<_>>(),
        )),
        Arc::new(BooleanArray::from(
            outcomes
                .iter()
                .map(|o| o.error.is_none())
                .collect::<Vec<_>>(),
        )),
        Arc::new(StringArray::from(
            outcomes.iter().map(|o| o.error.clone()).collect::<Vec<_>>(),
        )),
        Arc::new(StringArray::from(notes)),
        Arc::new(UInt64Array::from(
            outcomes
                .iter()
                .map(|o| o.stages.iter().filter(|s| s.1).count() as u64)
                .collect::<Vec<_>>(),
        )),
    ];
    for stage in STAGES {
        arrays.push(Arc::new(Float64Array::from(
            outcomes
                .iter()
                .map(|o| o.stages.iter().find(|s| s.0 == stage).map(|s| s.2))
                .collect::<Vec<_>>(),
        )));
    }
    let stage_seconds: Vec<String> = STAGES.iter().map(|s| format!("{s}_s")).collect();
    let value_names: Vec<&str> = cols.iter().map(|(n, _)| *n).collect();
    let schema = schema::campaign(&stage_seconds, &value_names);
    for (_, v) in cols {
        arrays.push(Arc::new(Float64Array::from(v)));
    }
    write_batch(
        &out.join("campaign.parquet"),
        &RecordBatch::try_new(schema, arrays)?,
    )?;
    let pooled = pools.finish(config, crate::campaign_settings::FILE)?;
    md += &pooled.markdown;
    crate::campaign_settings::write(
        &out.join(crate::campaign_settings::FILE),
        pooled.settings.as_deref(),
    )?;
    write_atomic(&out.join("campaign.md"), md.as_bytes())?;
    let html = unz_viz::report::campaign_html(
        &format!("Campaign {}", out.display()),
        &rows,
        &pooled.markdown,
    );
    write_atomic(&out.join("campaign.html"), html.as_bytes())?;
    Ok(())
}

/// A run's row of `campaign.html`, from its `disupt.json` (`d`, as the summary read it)
/// and its note.
fn report_row(
    out: &Path,
    o: &RunOutcome,
    d: Option<&DisuptOut>,
    note: Option<String>,
) -> ReportRow {
    let mut last_cp_error_m = Vec::new();
    let mut cp_errors_m = Vec::new();
    let mut joint = None;
    let mut holdout_m = None;
    if let Some(d) = d {
        let settings = [(
            "initial",
            Some((d.before.dx_m, d.before.dy_m, &d.before.control_points)),
        )]
        .into_iter()
        .chain(["oepi", "owpi", "joint"].into_iter().map(|name| {
            (
                name,
                d.methods
                    .get(name)
                    .map(|m| (m.outcome.dx_m, m.outcome.dy_m, &m.outcome.control_points)),
            )
        }));
        for (label, v) in settings {
            let Some((dx, dy, cps)) = v else { continue };
            if dx.is_finite() && dy.is_finite() {
                last_cp_error_m.push((label.to_owned(), dx.hypot(dy)));
            }
            for cp in cps {
                cp_errors_m.push((cp.id, label.to_owned(), cp.kryt2_m));
            }
        }
        if let Some(j) = d.methods.get("joint") {
            let (b, x) = (&d.before.x, &j.outcome.x);
            joint = x.sigma.as_ref().map(|s| {
                let per_h = 1.0 / unz_stages::units::DEG_PER_H;
                JointEstimate {
                    azimuth_change_deg: (x.azimuth_deg - b.azimuth_deg + 180.0).rem_euclid(360.0)
                        - 180.0,
                    azimuth_sigma_deg: s.azimuth_deg,
                    drift_z_deg_h: x.drift_rad_s[2] * per_h,
                    drift_z_sigma_deg_h: s.drift_rad_s[2] * per_h,
                    odo_ppm: (x.odo_scale / b.odo_scale - 1.0) * 1e6,
                    odo_sigma_ppm: s.odo_scale / b.odo_scale * 1e6,
                }
            });
            holdout_m = holdout_stats(j);
        }
    }
    let rrd = format!("{0}/review/{0}.rrd", o.name);
    ReportRow {
        name: o.name.clone(),
        error: o.error.clone(),
        distance_m: d.map(|d| d.distance_m),
        last_cp_error_m,
        cp_errors_m,
        joint,
        holdout_m,
        note,
        recording: out.join(&rrd).is_file().then_some(rrd),
        wall_s: o.wall_s,
        computed: o
            .stages
            .iter()
            .filter(|s| s.1)
            .map(|s| s.0.clone())
            .collect(),
    }
}

/// Parses `I/N`.
pub fn parse_shard(s: &str) -> anyhow::Result<(u64, u64)> {
    let (i, n) = s.split_once('/').context("--shard takes I/N")?;
    let (i, n): (u64, u64) = (i.parse()?, n.parse()?);
    if n == 0 || i >= n {
        bail!("--shard {s}: need 0 <= I < N");
    }
    Ok((i, n))
}

/// Merges the `campaign.parquet` of several output folders (shards) into `dest`, refusing
/// a run that appears in two of them, and pools the runs of all of them as one campaign
/// would: their sections go to `dest`'s markdown beside it (`all.parquet` → `all.md`) and
/// the settings they agree on, with `config`, to `all-settings.toml` (removed when none).
/// Returns how many runs were merged.
pub fn merge_summaries(
    outs: &[PathBuf],
    dest: &Path,
    config: &toml::Table,
) -> anyhow::Result<usize> {
    let mut batches = Vec::new();
    let mut schema = None;
    let mut seen = std::collections::HashMap::new();
    // Each run's shard folder, name and manifest, in the shards' order.
    let mut runs: Vec<(&Path, String, String)> = Vec::new();
    for out in outs {
        let path = out.join("campaign.parquet");
        let (s, bs) = unz_formats::parquet_io::read_batches(&path)?;
        if schema
            .as_ref()
            .is_some_and(|first: &arrow::datatypes::SchemaRef| first.fields() != s.fields())
        {
            bail!(
                "{} has another summary schema than {}",
                path.display(),
                outs[0].display()
            );
        }
        for b in &bs {
            let column = |name: &str| {
                b.column_by_name(name)
                    .and_then(|c| c.as_any().downcast_ref::<StringArray>())
                    .with_context(|| format!("{}: no {name} column", path.display()))
            };
            let names = column(schema::CAMPAIGN_RUN)?;
            let manifests = column(schema::CAMPAIGN_MANIFEST)?;
            for (r, m) in names.iter().zip(manifests) {
                let Some(r) = r else { continue };
                if let Some(other) = seen.insert(r.to_owned(), path.clone()) {
                    bail!(
                        "run {r:?} is in both {} and {}",
                        other.display(),
                        path.display()
                    );
                }
                runs.push((out, r.to_owned(), m.unwrap_or_default().to_owned()));
            }
        }
        schema.get_or_insert(s);
        batches.extend(bs);
    }
    let schema = schema.context("nothing to merge")?;
    let merged = arrow::compute::concat_batches(&schema, &batches)?;
    write_batch(dest, &merged)?;
    // In a single campaign's order (its manifests sorted), so that the sections are the
    // ones it would write.
    runs.sort_by(|a, b| (&a.2, &a.1).cmp(&(&b.2, &b.1)));
    let mut pools = Pools::default();
    // A name that is not a plain run name names no folder of a shard's (a summary is
    // read, not trusted).
    for (out, name, manifest) in runs
        .iter()
        .filter(|r| unz_formats::manifest::is_plain_name(&r.1))
    {
        pools.add(name, &RunReports::read(out, name, Path::new(manifest)));
    }
    let (settings_path, md_path) = crate::campaign_pools::merged_names(dest);
    let settings_name = settings_path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let pooled = pools.finish(config, &settings_name)?;
    crate::campaign_settings::write(&settings_path, pooled.settings.as_deref())?;
    let md = format!(
        "# {} runs of {} shards\n\nThe runs' rows are in `{}`; pooled across all of them:\n{}",
        merged.num_rows(),
        outs.len(),
        dest.file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        if pooled.markdown.is_empty() {
            "\nnothing: no run's reports show a point, mark, angle, lag or yaw to pool.\n"
        } else {
            &pooled.markdown
        }
    );
    write_atomic(&md_path, md.as_bytes())?;
    Ok(merged.num_rows())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs are found down to the search's depth; a folder below it is said, not searched
    /// in silence; hidden folders and the output folder are not searched.
    #[test]
    fn runs_are_found_to_the_searchs_depth_and_deeper_folders_are_said() {
        let tmp = tempfile::tempdir().unwrap();
        let camp = tmp.path().join("c");
        let at = |depth: usize| (1..=depth).fold(camp.clone(), |p, d| p.join(d.to_string()));
        for (dir, name) in [
            (at(MAX_DEPTH), "run.toml"),
            (at(MAX_DEPTH + 2), "run.toml"),
            (camp.join(".hidden"), "run.toml"),
            (camp.join("out/r"), "run.toml"),
            (camp.join("r"), "notes.toml"),
        ] {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(dir.join(name), "").unwrap();
        }
        let found = find_runs(&camp, &camp.join("out")).unwrap();
        assert_eq!(found.manifests, [at(MAX_DEPTH).join("run.toml")]);
        let [(deeper, why)] = &found.skipped[..] else {
            panic!("{:?}", found.skipped)
        };
        assert_eq!(deeper, &at(MAX_DEPTH + 1));
        assert_eq!(
            why,
            "a folder 9 below the campaign's, deeper than the search for runs (8): not searched"
        );
    }

    /// A panic becomes the run's error with its message (a formatted one, a literal one);
    /// a result goes through untouched.
    #[test]
    fn a_panicking_run_becomes_its_error() {
        let index = 7;
        let e = guarded(|| -> u8 { panic!("index {index} out of range") }).unwrap_err();
        let said = format!("{e:#}");
        assert!(
            said.contains("a bug in unz") && said.contains("index 7 out of range"),
            "{said}"
        );
        let e = guarded(|| -> u8 { panic!("literal") }).unwrap_err();
        assert!(format!("{e}").ends_with(": literal"), "{e}");
        assert_eq!(guarded(|| 5).unwrap(), 5);
    }

    #[test]
    fn a_killed_summarys_temporary_files_are_removed_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let names = [
            ".campaign.md.5GrxMU.tmp",
            ".campaign.parquet.x1.tmp",
            ".campaign-settings.toml.x1.tmp",
            ".other.md.x1.tmp",
            "campaign.md",
            "unz.lock",
        ];
        for n in names {
            std::fs::write(dir.path().join(n), b"x").unwrap();
        }
        remove_stale_summary_temps(dir.path());
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, vec![".other.md.x1.tmp", "campaign.md", "unz.lock"]);
    }
}
