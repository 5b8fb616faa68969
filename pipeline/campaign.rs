//! Whole campaigns: every run under a folder, processed in parallel, each run's stages in
//! order; a failing run is recorded with its error and never stops the others; one
//! summary row per run in `OUT/campaign.parquet` and `OUT/campaign.md`, and the report
//! `OUT/campaign.html` with its plots.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, bail};
use arrow::array::{BooleanArray, Float64Array, RecordBatch, StringArray, UInt64Array};
use arrow::datatypes::{DataType, Field, Schema};
use rayon::prelude::*;
use serde_json::Value;
use unz_formats::atomic::write_atomic;
use unz_formats::manifest::RunManifest;
use unz_formats::parquet_io::write_batch;
use unz_viz::report::{JointEstimate, ReportRow};

use crate::disupt_stage::{Method, ensure_disupt};
use crate::flow::{
    Overrides, RunCtx, ensure_criteria, ensure_derive, ensure_ingest, ensure_navigate,
};

/// The stages of `unz run`, in order.
pub const STAGES: [&str; 7] = [
    "ingest", "derive", "navigate", "criteria", "disupt", "export", "review",
];
/// Deepest folder searched for run manifests.
const MAX_DEPTH: usize = 8;

/// Every `run.toml` under `path` (or `path` itself), sorted; `out` is never searched and
/// symlinks are not followed.
pub fn find_runs(path: &Path, out: &Path) -> anyhow::Result<Vec<PathBuf>> {
    if path.is_file() {
        return Ok(vec![path.to_path_buf()]);
    }
    if path.join("run.toml").is_file() {
        return Ok(vec![path.join("run.toml")]);
    }
    let out_real = out.canonicalize().ok();
    let mut found = Vec::new();
    let mut stack = vec![(path.to_path_buf(), 0usize)];
    while let Some((dir, depth)) = stack.pop() {
        let entries =
            std::fs::read_dir(&dir).with_context(|| format!("cannot list {}", dir.display()))?;
        for e in entries {
            let e = e?;
            let p = e.path();
            let meta = std::fs::symlink_metadata(&p)?;
            let hidden = e.file_name().to_string_lossy().starts_with('.');
            if meta.is_dir()
                && !hidden
                && depth < MAX_DEPTH
                && out_real.as_deref() != p.canonicalize().ok().as_deref()
            {
                stack.push((p, depth + 1));
            } else if meta.is_file() && e.file_name() == "run.toml" {
                found.push(p);
            }
        }
    }
    found.sort();
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
) -> (anyhow::Result<()>, Vec<(String, bool, f64)>) {
    let mut ctx = RunCtx::new(manifest.clone(), plan.out.clone(), plan.verbose);
    ctx.progress = bar;
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
                "ingest" => drop(ensure_ingest(&ctx)?),
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
                Ok(m) => process(&m, plan, bar.clone()),
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

fn read_json(path: &Path) -> Value {
    std::fs::read(path)
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok())
        .unwrap_or(Value::Null)
}

/// Writes `campaign.parquet` and `campaign.md` into `out`.
pub fn write_summary(out: &Path, outcomes: &[RunOutcome]) -> anyhow::Result<()> {
    let f = |v: &Value| v.as_f64();
    let mut cols: Vec<(&str, Vec<Option<f64>>)> = [
        "distance_m",
        "imu_accepted",
        "rejected",
        "lost_samples",
        "before_dx_m",
        "before_dy_m",
        "oepi_dx_m",
        "oepi_dy_m",
        "owpi_dx_m",
        "owpi_dy_m",
        "joint_dx_m",
        "joint_dy_m",
        "joint_azimuth_deg",
        "joint_azimuth_sigma_deg",
        "joint_drift_z_rad_s",
        "joint_drift_z_sigma_rad_s",
        "joint_odo_scale",
        "joint_odo_scale_sigma",
        "joint_odo_yaw_deg",
        "joint_odo_yaw_sigma_deg",
        "wall_s",
    ]
    .into_iter()
    .map(|n| (n, Vec::new()))
    .collect();
    let mut md = String::from(
        "| run | status | distance [m] | rejected | before [m] | OEPI [m] | OWPI [m] | joint [m] | joint az σ [°] | wall [s] | computed | error |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for o in outcomes {
        let dir = out.join(&o.name);
        let ing = read_json(&dir.join("ingest/ingest.json"));
        let d = read_json(&dir.join("disupt/disupt.json"));
        let m = &d["methods"];
        let rejected = ing["records_read"]
            .as_f64()
            .zip(ing["records_accepted"].as_f64())
            .map(|(a, b)| a - b);
        let values = [
            f(&d["distance_m"]),
            f(&ing["imu_accepted"]),
            rejected,
            f(&ing["lost_samples"]),
            f(&d["before"]["dx_m"]),
            f(&d["before"]["dy_m"]),
            f(&m["oepi"]["dx_m"]),
            f(&m["oepi"]["dy_m"]),
            f(&m["owpi"]["dx_m"]),
            f(&m["owpi"]["dy_m"]),
            f(&m["joint"]["dx_m"]),
            f(&m["joint"]["dy_m"]),
            f(&m["joint"]["x"]["azimuth_deg"]),
            f(&m["joint"]["x"]["sigma"]["azimuth_deg"]),
            f(&m["joint"]["x"]["drift_rad_s"][2]),
            f(&m["joint"]["x"]["sigma"]["drift_rad_s"][2]),
            f(&m["joint"]["x"]["odo_scale"]),
            f(&m["joint"]["x"]["sigma"]["odo_scale"]),
            f(&m["joint"]["x"]["odo_yaw_deg"]),
            f(&m["joint"]["x"]["sigma"]["odo_yaw_deg"]),
            Some(o.wall_s),
        ];
        for (c, v) in cols.iter_mut().zip(values) {
            c.1.push(v);
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
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.2} | {} | {} |",
            o.name,
            if o.error.is_none() { "ok" } else { "failed" },
            values[0].map_or("–".into(), |v| format!("{v:.0}")),
            values[2].map_or("–".into(), |v| format!("{v:.0}")),
            h(values[4], values[5]),
            h(values[6], values[7]),
            h(values[8], values[9]),
            h(values[10], values[11]),
            values[13].map_or("–".into(), |v| format!("{v:.3}")),
            o.wall_s,
            match (computed.is_empty(), o.stages.is_empty()) {
                (_, true) => "–".to_owned(),
                (true, false) => "cached".to_owned(),
                (false, false) => computed.join(", "),
            },
            o.error
                .as_deref()
                .unwrap_or("")
                .replace('|', "/")
                .replace('\n', " "),
        );
    }
    let mut fields = vec![
        Field::new("run", DataType::Utf8, false),
        Field::new("manifest", DataType::Utf8, false),
        Field::new("ok", DataType::Boolean, false),
        Field::new("error", DataType::Utf8, true),
        Field::new("stages_computed", DataType::UInt64, false),
    ];
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
        Arc::new(UInt64Array::from(
            outcomes
                .iter()
                .map(|o| o.stages.iter().filter(|s| s.1).count() as u64)
                .collect::<Vec<_>>(),
        )),
    ];
    for stage in STAGES {
        fields.push(Field::new(format!("{stage}_s"), DataType::Float64, true));
        arrays.push(Arc::new(Float64Array::from(
            outcomes
                .iter()
                .map(|o| o.stages.iter().find(|s| s.0 == stage).map(|s| s.2))
                .collect::<Vec<_>>(),
        )));
    }
    for (name, v) in cols {
        fields.push(Field::new(name, DataType::Float64, true));
        arrays.push(Arc::new(Float64Array::from(v)));
    }
    write_batch(
        &out.join("campaign.parquet"),
        &RecordBatch::try_new(Arc::new(Schema::new(fields)), arrays)?,
    )?;
    write_atomic(&out.join("campaign.md"), md.as_bytes())?;
    let rows: Vec<ReportRow> = outcomes.iter().map(|o| report_row(out, o)).collect();
    let html = unz_viz::report::campaign_html(&format!("Campaign {}", out.display()), &rows);
    write_atomic(&out.join("campaign.html"), html.as_bytes())?;
    Ok(())
}

/// A run's row of `campaign.html`, from its `disupt.json`.
fn report_row(out: &Path, o: &RunOutcome) -> ReportRow {
    let d = read_json(&out.join(&o.name).join("disupt/disupt.json"));
    let settings = [
        ("initial", &d["before"]),
        ("oepi", &d["methods"]["oepi"]),
        ("owpi", &d["methods"]["owpi"]),
        ("joint", &d["methods"]["joint"]),
    ];
    let mut last_cp_error_m = Vec::new();
    let mut cp_errors_m = Vec::new();
    for (label, v) in settings {
        if let (Some(dx), Some(dy)) = (v["dx_m"].as_f64(), v["dy_m"].as_f64()) {
            last_cp_error_m.push((label.to_owned(), dx.hypot(dy)));
        }
        for cp in v["control_points"].as_array().into_iter().flatten() {
            if let (Some(id), Some(k)) = (cp["id"].as_u64(), cp["kryt2_m"].as_f64()) {
                cp_errors_m.push((u32::try_from(id).unwrap_or(u32::MAX), label.to_owned(), k));
            }
        }
    }
    let (b, j) = (&d["before"]["x"], &d["methods"]["joint"]["x"]);
    let joint = (|| {
        let per_h = 1.0 / unz_stages::simulate::DEG_PER_H;
        let base_scale = b["odo_scale"].as_f64()?;
        Some(JointEstimate {
            azimuth_change_deg: (j["azimuth_deg"].as_f64()? - b["azimuth_deg"].as_f64()? + 180.0)
                .rem_euclid(360.0)
                - 180.0,
            azimuth_sigma_deg: j["sigma"]["azimuth_deg"].as_f64()?,
            drift_z_deg_h: j["drift_rad_s"][2].as_f64()? * per_h,
            drift_z_sigma_deg_h: j["sigma"]["drift_rad_s"][2].as_f64()? * per_h,
            odo_ppm: (j["odo_scale"].as_f64()? / base_scale - 1.0) * 1e6,
            odo_sigma_ppm: j["sigma"]["odo_scale"].as_f64()? / base_scale * 1e6,
        })
    })();
    let rrd = format!("{0}/review/{0}.rrd", o.name);
    ReportRow {
        name: o.name.clone(),
        error: o.error.clone(),
        distance_m: d["distance_m"].as_f64(),
        last_cp_error_m,
        cp_errors_m,
        joint,
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
/// a run that appears in two of them.
pub fn merge_summaries(outs: &[PathBuf], dest: &Path) -> anyhow::Result<usize> {
    let mut batches = Vec::new();
    let mut schema = None;
    let mut seen = std::collections::HashMap::new();
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
            let runs = b
                .column_by_name("run")
                .and_then(|c| c.as_any().downcast_ref::<StringArray>())
                .with_context(|| format!("{}: no run column", path.display()))?;
            for r in runs.iter().flatten() {
                if let Some(other) = seen.insert(r.to_owned(), path.clone()) {
                    bail!(
                        "run {r:?} is in both {} and {}",
                        other.display(),
                        path.display()
                    );
                }
            }
        }
        schema.get_or_insert(s);
        batches.extend(bs);
    }
    let schema = schema.context("nothing to merge")?;
    let merged = arrow::compute::concat_batches(&schema, &batches)?;
    write_batch(dest, &merged)?;
    Ok(merged.num_rows())
}
