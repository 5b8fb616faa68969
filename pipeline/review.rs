//! Stage 6, review: one Rerun recording per run, `OUT/<name>/review/<name>.rrd`, built
//! from the cached tables of the stages before it (derive, criteria, disupt, and the
//! sweep when one exists). It never navigates: the trajectories of every method come
//! from the disupt stage's `tracks.parquet`.
//!
//! A simulated run's `truth.parquet` beside its `run.toml` is shown as the truth track.

use std::path::{Path, PathBuf};

use anyhow::Context;
use unz_formats::parquet_io::{read_schema, read_table};
use unz_formats::schema::{nav_cols, sweep_cols};
use unz_formats::tables::f64_column;
use unz_stages::criteria::Kryt2;
use unz_stages::derive::seconds_since;
use unz_stages::earth::Geodetic;
use unz_viz::review::{
    ControlPointView, EpochSeries, Kryt1Curve, OdometerFailure, Review, RouteSigmaView,
    SensorBlocks, Sweep, Track,
};

use crate::artifacts::{StageName, files};
use crate::derive_io::read_epoch_terms;
use crate::disupt_stage::{DisuptOut, Method, ensure_disupt};
use crate::flow::{
    IngestedSeries, Overrides, Params, RunCtx, ensure_criteria, load_criteria, start_position,
};
use crate::method_tables::{
    KRYT1_SERIES, MethodTrack, TRACK_RATE_HZ, TRACKS, decimation_step, read_kryt1_series,
    read_tracks,
};
use crate::picked_rows::{picked_columns, picked_times};
use crate::review_sensors::{RunTimes, read_review_sensors};
use crate::stage::{Stage, params_hash};

/// What the review stage wrote.
#[derive(Debug, Clone)]
pub struct ReviewOutput {
    /// The recording.
    pub rrd: PathBuf,
    /// Its size, bytes.
    pub bytes: u64,
}

/// The file name of a run's recording.
pub fn rrd_name(run: &str) -> String {
    format!("{run}.rrd")
}

/// A simulated run's truth, when its folder has one (a regular file, not a link).
fn truth_path(ctx: &RunCtx) -> Option<PathBuf> {
    let p = ctx.manifest.path.parent()?.join("truth.parquet");
    std::fs::symlink_metadata(&p)
        .ok()
        .filter(std::fs::Metadata::is_file)
        .map(|_| p)
}

/// The sweep's table, when `unz sweep` ran for this run.
fn sweep_path(ctx: &RunCtx) -> Option<PathBuf> {
    let p = ctx
        .out
        .join(&ctx.manifest.name)
        .join("sweep")
        .join("sweep.parquet");
    p.is_file().then_some(p)
}

/// Stage 6.
pub fn ensure_review(ctx: &RunCtx, params: &Params) -> anyhow::Result<ReviewOutput> {
    let disupt_dir = ensure_disupt(ctx, params, Method::All)?;
    let (criteria_dir, _) = ensure_criteria(ctx, params, &Overrides::default())?;
    let m = &ctx.manifest;
    let derive_dir = ctx.layout().dir(StageName::Derive);
    let dir = ctx.layout().create(StageName::Review)?;
    let truth = truth_path(ctx);
    let sweep = sweep_path(ctx);
    let mut inputs = vec![
        m.path.clone(),
        derive_dir.join(files::SENSORS),
        derive_dir.join(files::EPOCHS),
        criteria_dir.join(files::CRITERIA),
        disupt_dir.join(files::DISUPT_REPORT),
        disupt_dir.join(files::DISUPT_TABLES),
        disupt_dir.join(files::CORRECTED_NAV),
        disupt_dir.join(TRACKS),
        disupt_dir.join(KRYT1_SERIES),
        ctx.layout().dir(StageName::Ingest).join(files::ODOMETER),
    ];
    inputs.extend(truth.iter().cloned());
    inputs.extend(sweep.iter().cloned());
    let name = rrd_name(&m.name);
    let outputs = [name.as_str()];
    let stage = Stage {
        dir: dir.clone(),
        name: "review",
        // 4: the odometer's failures on the speed's plot.
        // 5: a point the route comes back to has an error per visit.
        version: 5,
        params_hash: params_hash(&(
            unz_viz::recording::SERIES_RATE_HZ,
            unz_viz::recording::POSE_RATE_HZ,
        ))?,
        inputs,
        outputs: &outputs,
        hashed_as_read: vec![],
    };
    ctx.run_stage(&stage, || {
        let review = build_review(
            ctx,
            &derive_dir,
            &criteria_dir,
            &disupt_dir,
            truth.as_deref(),
            sweep.as_deref(),
        )?;
        ctx.say(
            "review",
            &format!("read the tables{}", crate::memory::rss_suffix()),
        );
        unz_viz::recording::write_rrd(&review, &dir.join(&name))?;
        ctx.say(
            "review",
            &format!("wrote the recording{}", crate::memory::rss_suffix()),
        );
        Ok(())
    })?;
    let rrd = dir.join(&name);
    let bytes = std::fs::metadata(&rrd)
        .with_context(|| format!("cannot read {}", rrd.display()))?
        .len();
    Ok(ReviewOutput { rrd, bytes })
}

/// The derive's sensor series in the recording's blocks, and its time base, from
/// `sensors.parquet` (taken by the derive stage: the run's per-sample series are not read
/// here).
fn sensor_blocks(ctx: &RunCtx, derive_dir: &Path) -> anyhow::Result<(SensorBlocks, RunTimes)> {
    // The review is the last stage to read the chain's derive: it goes now.
    drop(ctx.take_kept_derived());
    let s = read_review_sensors(&derive_dir.join(files::SENSORS))?;
    Ok((s.blocks, s.times))
}

/// Reads the cached tables into a [`Review`]. After the sensors' table (which gives the
/// run's times), the other files are read side by side: the epochs' series, the tracks,
/// the truth and the disupt stage's reports (a 12-hour run's tracks and truth took 0.19
/// and 0.17 s of the 0.55 s its tables took one after the other).
pub fn build_review(
    ctx: &RunCtx,
    derive_dir: &Path,
    criteria_dir: &Path,
    disupt_dir: &Path,
    truth: Option<&Path>,
    sweep: Option<&Path>,
) -> anyhow::Result<Review> {
    let m = &ctx.manifest;
    let (sensors, d) = sensor_blocks(ctx, derive_dir)?;
    let rel =
        |t_ns: &[i64]| -> Vec<f64> { (t_ns.iter()).map(|&t| seconds_since(d.t0_ns, t)).collect() };
    let start = start_position(m);
    let ((epochs, tracks), (truth, reports)) = rayon::join(
        || {
            rayon::join(
                || epoch_series(derive_dir, criteria_dir, &rel),
                || read_tracks(&disupt_dir.join(TRACKS)),
            )
        },
        || {
            rayon::join(
                || {
                    truth
                        .map(|p| truth_track(p, &rel, start, d.nominal_dt_s))
                        .transpose()
                },
                || read_reports(ctx, disupt_dir, &rel, d.nominal_dt_s),
            )
        },
    );
    // Errors in the order the files were read one after the other.
    let epochs = epochs?;
    let mut tracks: Vec<Track> = tracks?
        .into_iter()
        .map(|t| track_view(t, &rel, start.h_m))
        .collect();
    tracks.extend(truth?);
    let reports = reports?;
    let dj = &reports.dj;
    let control_points = m
        .control_points
        .iter()
        .map(|cp| {
            let (lat, lon) = (cp.position.latitude_deg, cp.position.longitude_deg);
            let (north_m, east_m) = start.offset_m(lat.to_radians(), lon.to_radians());
            let mut errors = Vec::new();
            // A point the route came back to has an error per visit, named by its time.
            let mut push = |label: &str, cps: &[Kryt2]| {
                let visits: Vec<&Kryt2> = cps.iter().filter(|e| e.id == cp.id).collect();
                for e in &visits {
                    let label = match visits.len() {
                        1 => label.to_owned(),
                        _ => format!("{label} at t_s = {:.1}", e.t_s),
                    };
                    errors.push((label, e.dx_m, e.dy_m));
                }
            };
            push("initial", &dj.before.control_points);
            for method in ["oepi", "owpi", "joint"] {
                if let Some(m) = dj.methods.get(method) {
                    push(method, &m.outcome.control_points);
                }
            }
            ControlPointView {
                id: cp.id,
                lat_deg: lat,
                lon_deg: lon,
                north_m,
                east_m,
                up_m: cp.position.height_m - start.h_m,
                errors,
            }
        })
        .collect();
    let summary_markdown = format!(
        "Raw log `{}`; {:.0} s, {} IMU samples at {:.0} Hz; {:.0} m to the last control point.",
        m.raw.file_name().unwrap_or_default().to_string_lossy(),
        d.duration_s,
        d.samples,
        1.0 / d.nominal_dt_s.max(1e-9),
        dj.distance_m,
    );
    // A binary log's odometer rows are its IMU samples; a text log's are its odometer
    // file's readings, and the rows bridged across its gaps are at IMU samples, found by
    // their time tags.
    let sample_at = |t_ns: i64| sensors.sample_at(seconds_since(d.t0_ns, t_ns), d.nominal_dt_s);
    let odometer_failures = reports
        .failed
        .into_iter()
        .map(|f| {
            let (first_sample, samples) = if reports.odometer_rows == d.samples {
                (f.rows.first as i64, f.rows.len as i64)
            } else {
                let first = sample_at(f.first_t_ns);
                (first, sample_at(f.last_t_ns) - first + 1)
            };
            OdometerFailure {
                first_sample,
                samples,
                bridged: f.rows.bridged,
            }
        })
        .collect();
    Ok(Review {
        name: m.name.clone(),
        sample_dt_s: d.nominal_dt_s,
        sensors,
        odometer_failures,
        epochs,
        kryt1: reports.kryt1,
        tracks,
        vehicle_track: dj.corrected_by.clone(),
        mark_lever_arm_m: vehicle_mark(dj),
        route_sigma: reports.route_sigma,
        control_points,
        sweep: sweep.map(read_sweep).transpose()?,
        tables_markdown: reports.tables_markdown,
        summary_markdown,
    })
}

/// The criteria's epochs with the derive's filtered acceleration terms at them.
fn epoch_series(
    derive_dir: &Path,
    criteria_dir: &Path,
    rel: &(impl Fn(&[i64]) -> Vec<f64> + Sync),
) -> anyhow::Result<EpochSeries> {
    let c = load_criteria(&criteria_dir.join(files::CRITERIA))?;
    let terms = read_epoch_terms(derive_dir)?;
    Ok(EpochSeries {
        t_s: rel(&c.t_ns),
        theta_gyro_rad: c.theta_n_rad,
        phi_gyro_rad: c.phi_n_rad,
        theta_acc_rad: c.theta_p_rad,
        phi_acc_rad: c.phi_p_rad,
        d_theta_rad: c.d_theta_rad,
        d_phi_rad: c.d_phi_rad,
        kf_d_theta_rad: c.kf_d_theta_rad,
        kf_d_phi_rad: c.kf_d_phi_rad,
        ax_f_mps2: terms.ax_f_mps2,
        ay_f_mps2: terms.ay_f_mps2,
        u_dot_f_mps2: terms.u_dot_f_mps2,
        ru_f_mps2: terms.ru_f_mps2,
    })
}

/// What the review takes from the disupt stage's reports and the ingest's odometer.
struct Reports {
    kryt1: Vec<Kryt1Curve>,
    dj: DisuptOut,
    tables_markdown: String,
    route_sigma: Option<RouteSigmaView>,
    failed: Vec<crate::flow::ingested::FailedSpan>,
    /// The ingested odometer's rows.
    odometer_rows: usize,
}

/// Reads the Kryt1 curves, the disupt report and tables, the route's σ and the
/// odometer's failures.
fn read_reports(
    ctx: &RunCtx,
    disupt_dir: &Path,
    rel: &(impl Fn(&[i64]) -> Vec<f64> + Sync),
    nominal_dt_s: f64,
) -> anyhow::Result<Reports> {
    let kryt1 = read_kryt1_series(&disupt_dir.join(KRYT1_SERIES))?
        .into_iter()
        .map(|k| Kryt1Curve {
            label: k.method,
            t_s: rel(&k.t_ns),
            kryt1_cum_rad: k.kryt1_cum,
        })
        .collect();
    let json_path = disupt_dir.join(files::DISUPT_REPORT);
    let dj: DisuptOut = serde_json::from_slice(
        &std::fs::read(&json_path)
            .with_context(|| format!("cannot read {}", json_path.display()))?,
    )
    .with_context(|| format!("not a disupt report: {}", json_path.display()))?;
    let tables_path = disupt_dir.join(files::DISUPT_TABLES);
    let tables_markdown = std::fs::read_to_string(&tables_path)
        .with_context(|| format!("cannot read {}", tables_path.display()))?;
    let route_sigma = read_route_sigma(&disupt_dir.join(files::CORRECTED_NAV), rel, nominal_dt_s)?;
    let (failed, odometer_rows) =
        IngestedSeries::load_failed_rows(&ctx.layout().dir(StageName::Ingest))?;
    Ok(Reports {
        kryt1,
        dj,
        tables_markdown,
        route_sigma,
        failed,
        odometer_rows,
    })
}

fn track_view(t: MethodTrack, rel: &impl Fn(&[i64]) -> Vec<f64>, h0_m: f64) -> Track {
    let wide = |v: Vec<f32>| v.into_iter().map(f64::from).collect();
    Track {
        t_s: rel(&t.t_ns),
        up_m: t.h_m.iter().map(|&h| f64::from(h) - h0_m).collect(),
        label: t.method,
        lat_deg: t.lat_deg,
        lon_deg: t.lon_deg,
        north_m: wide(t.north_m),
        east_m: wide(t.east_m),
        roll_deg: wide(t.roll_deg),
        pitch_deg: wide(t.pitch_deg),
        heading_deg: wide(t.heading_deg),
    }
}

/// The simulator's truth, decimated like the methods' tracks.
fn truth_track(
    path: &Path,
    rel: &impl Fn(&[i64]) -> Vec<f64>,
    start: Geodetic,
    nominal_dt_s: f64,
) -> anyhow::Result<Track> {
    let step = decimation_step(nominal_dt_s, TRACK_RATE_HZ);
    let names = [
        nav_cols::LAT_DEG,
        nav_cols::LON_DEG,
        nav_cols::H_M,
        nav_cols::ROLL_DEG,
        nav_cols::PITCH_DEG,
        nav_cols::HEADING_DEG,
    ];
    let (t, cols) = decimated_columns(path, &names, step, true)?;
    let [lat, lon, h, roll, pitch, heading]: [Vec<f64>; 6] = cols
        .try_into()
        .map_err(|_| anyhow::anyhow!("{}: columns", path.display()))?;
    let (north_m, east_m) = lat
        .iter()
        .zip(&lon)
        .map(|(la, lo)| start.offset_m(la.to_radians(), lo.to_radians()))
        .unzip();
    Ok(Track {
        label: "truth".into(),
        t_s: rel(&t),
        up_m: h.iter().map(|h| h - start.h_m).collect(),
        lat_deg: lat,
        lon_deg: lon,
        north_m,
        east_m,
        roll_deg: roll,
        pitch_deg: pitch,
        heading_deg: heading,
    })
}

/// A table's kept rows: their times (ns) and each column's values.
type Decimated = (Vec<i64>, Vec<Vec<f64>>);

/// Every `step`-th row (the last one too when `with_last`) of a table's `t_ns` and of the
/// float columns `names` ([`picked_columns`]: only the rows kept are widened and copied).
fn decimated_columns(
    path: &Path,
    names: &[&str],
    step: usize,
    with_last: bool,
) -> anyhow::Result<Decimated> {
    let step = step.max(1);
    let mut last = None;
    let (mut t, mut rows, n) = picked_times(path, |k, tk| {
        last = Some(tk);
        k % step == 0
    })?;
    // The last row too, when asked and not kept already.
    if let (Some(l), Some(tl)) = (
        n.checked_sub(1).filter(|l| with_last && l % step != 0),
        last,
    ) {
        rows.push(l);
        t.push(tl);
    }
    Ok((t, picked_columns(path, names, &rows)?))
}

/// `sweep.parquet`: axis columns first (the first varies slowest), then `kryt1_rad`,
/// `kryt2_m`.
fn read_sweep(path: &Path) -> anyhow::Result<Sweep> {
    let (schema, b) = read_table(path)?;
    let mut axes = Vec::new();
    for f in schema.fields() {
        let name = f.name();
        if name == sweep_cols::KRYT1_RAD || name == sweep_cols::KRYT2_M {
            continue;
        }
        // The axis's distinct values in order of appearance.
        let mut seen = std::collections::HashSet::new();
        let values: Vec<f64> = f64_column(&b, name)?
            .into_iter()
            .filter(|v| seen.insert(v.to_bits()))
            .collect();
        axes.push((name.clone(), values));
    }
    Ok(Sweep {
        axes,
        kryt1_rad: f64_column(&b, sweep_cols::KRYT1_RAD)?,
        kryt2_m: f64_column(&b, sweep_cols::KRYT2_M)?,
    })
}

/// The corrected route's 1σ columns of `corrected_nav.parquet` at the recording's series
/// rate, when the joint fit wrote them.
fn read_route_sigma(
    path: &Path,
    rel: &impl Fn(&[i64]) -> Vec<f64>,
    dt_s: f64,
) -> anyhow::Result<Option<RouteSigmaView>> {
    if read_schema(path)?
        .field_with_name(nav_cols::SIGMA_NORTH_M)
        .is_err()
    {
        return Ok(None);
    }
    let step = decimation_step(dt_s.max(1e-6), unz_viz::recording::SERIES_RATE_HZ);
    let names = [
        nav_cols::SIGMA_NORTH_M,
        nav_cols::SIGMA_EAST_M,
        nav_cols::SIGMA_HEADING_DEG,
    ];
    let (t, cols) = decimated_columns(path, &names, step, false)?;
    let [north_m, east_m, heading_deg]: [Vec<f64>; 3] = cols
        .try_into()
        .map_err(|_| anyhow::anyhow!("{}: columns", path.display()))?;
    Ok(Some(RouteSigmaView {
        t_s: rel(&t),
        north_m,
        east_m,
        heading_deg,
    }))
}

/// The vehicle's mark from the navigated point, when away from it: the configured arm,
/// moved by the joint fit's estimate when the joint's settings made the corrected
/// navigation.
fn vehicle_mark(dj: &DisuptOut) -> Option<[f64; 3]> {
    dj.joint_mark()
        .filter(|_| dj.corrected_by.as_deref() == Some("joint"))
        .map(|(arm, _)| arm)
        .or(dj.mark_lever_arm_m)
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use arrow::array::{Float64Array, Int64Array, RecordBatch};
    use arrow::datatypes::{DataType, Field, Schema};

    use super::*;

    /// Rows across several of the reader's batches: what the decimation keeps is what
    /// the whole table picked by index gives.
    #[test]
    fn decimated_columns_are_the_rows_picked_from_the_whole_table() {
        let n = 150_001;
        let schema = Arc::new(Schema::new(vec![
            Field::new("t_ns", DataType::Int64, false),
            Field::new("a", DataType::Float64, false),
            Field::new("skipped", DataType::Float64, false),
            Field::new("b", DataType::Float64, false),
            Field::new("h", DataType::Float32, false),
        ]));
        let t: Vec<i64> = (0..n).map(|k| 1_000 + 10 * k as i64).collect();
        let a: Vec<f64> = (0..n).map(|k| (k as f64).sqrt()).collect();
        let b: Vec<f64> = (0..n).map(|k| -(k as f64) * 0.5).collect();
        let h: Vec<f32> = (0..n).map(|k| (k as f32).cbrt() - 9.0).collect();
        let batch = RecordBatch::try_new(
            schema,
            vec![
                Arc::new(Int64Array::from(t.clone())),
                Arc::new(Float64Array::from(a.clone())),
                Arc::new(Float64Array::from(b.clone())),
                Arc::new(Float64Array::from(b.clone())),
                Arc::new(arrow::array::Float32Array::from(h.clone())),
            ],
        )
        .unwrap();
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("t.parquet");
        unz_formats::parquet_io::write_batch(&path, &batch).unwrap();
        for (step, with_last) in [(7, true), (7, false), (10, true), (1, false)] {
            let (got_t, got) = decimated_columns(&path, &["a", "b"], step, with_last).unwrap();
            let mut idx: Vec<usize> = (0..n).step_by(step).collect();
            if with_last && idx.last() != Some(&(n - 1)) {
                idx.push(n - 1);
            }
            assert_eq!(got_t, idx.iter().map(|&k| t[k]).collect::<Vec<_>>());
            assert_eq!(got[0], idx.iter().map(|&k| a[k]).collect::<Vec<_>>());
            assert_eq!(got[1], idx.iter().map(|&k| b[k]).collect::<Vec<_>>());
            // The f32 column widened (both reading routes: `picked_rows`' tests).
            let (_, with_h) = decimated_columns(&path, &["h"], step, with_last).unwrap();
            assert_eq!(
                with_h[0],
                idx.iter().map(|&k| f64::from(h[k])).collect::<Vec<_>>()
            );
        }
    }
}
