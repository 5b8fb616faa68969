//! The chain of stages for one run: each `ensure_*` brings the stages before it up to
//! date (through their stage records), then skips or runs its own.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, bail};
use arrow::array::RecordBatch;
use serde::{Deserialize, Serialize};
use unz_formats::atomic::write_json_atomic;
use unz_formats::manifest::RunManifest;
use unz_formats::parquet_io::{
    for_each_batch, for_each_batch_of, read_schema, row_capacity_hint, write_batch,
};
use unz_formats::schema::{self, META_ODO_M_PER_PULSE};
use unz_formats::tables::{
    CriteriaTable, ImuTable, MarksTable, OdometerTable, f64_column, i64_column,
};
use unz_stages::criteria::{
    self, BlockAttitude, ControlPointFix, KalmanParams, Kryt1Series, Kryt2, Row3Blocks,
};
use unz_stages::derive::{DeriveParams, Derived, RawSeries, derive_owned};
use unz_stages::earth::{self, Geodetic};
use unz_stages::filter::LowPass;
use unz_stages::initial::{
    AlignParams, InitialReport, InitialRequest, Source, initial_settings_with_velocity,
    static_samples,
};
use unz_stages::strapdown::{NavInputs, NavSettings, NavTrack, navigate};
use unz_stages::time_base::TagTimes;

use crate::artifacts::{RunLayout, StageName, files};
use crate::derive_io::{
    as_stored, load_derived_for_navigation, load_derived_times, read_velocity_prefix, write_derived,
};
use crate::ingest::{OUTPUTS as INGEST_OUTPUTS, ingest};
use crate::nav_writer::NavWriter;
use crate::review_sensors::{review_sensors, write_review_sensors};
use crate::stage::{Stage, params_hash};

/// Parameters of every stage (defaults built in).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// ingest.
    pub ingest: crate::ingest::IngestParams,
    /// derive.
    pub derive: DeriveParams,
    /// Alignment.
    pub align: AlignParams,
    /// Kalman filter of the criteria.
    pub kalman: KalmanParams,
    /// DISUPT methods.
    pub disupt: unz_stages::disupt::DisuptParams,
}

/// Initial settings forced on the command line.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Overrides {
    /// Initial azimuth, degrees.
    pub azimuth_deg: Option<f64>,
    /// Gyro drifts, rad/s.
    pub drift_rad_s: Option<[f64; 3]>,
    /// Metres per odometer pulse.
    pub odo_scale_m_per_pulse: Option<f64>,
}

/// One run being processed.
pub struct RunCtx {
    /// Its manifest.
    pub manifest: RunManifest,
    /// Output root.
    pub out: PathBuf,
    /// Say on stderr which stages ran and which were skipped.
    pub verbose: bool,
    /// What each stage did: (stage, computed (not cached), wall s), in order.
    pub log: std::sync::Mutex<Vec<(String, bool, f64)>>,
    /// A progress line showing the stage being worked on (campaigns on a terminal).
    pub progress: Option<indicatif::ProgressBar>,
    /// The derive stage's output in memory: the stages after it in the same process share
    /// it instead of each decoding `derived.parquet`. Set when the derive is computed or
    /// first loaded, as [`crate::derive_io::load_derived`] gives it back but without the
    /// velocity increments (only the alignment's static start reads them, from the file,
    /// and the review's sensor blocks, taken by the derive stage into `sensors.parquet`);
    /// cleared when it is recomputed.
    derived: std::sync::Mutex<Option<Arc<Derived>>>,
}

impl RunCtx {
    /// A context for the run described by `manifest`, writing under `out`.
    pub fn new(manifest: RunManifest, out: PathBuf, verbose: bool) -> Self {
        Self {
            manifest,
            out,
            verbose,
            log: std::sync::Mutex::new(Vec::new()),
            progress: None,
            derived: std::sync::Mutex::new(None),
        }
    }

    /// The derive in `derive_dir` (brought up to date by the caller): the one in memory,
    /// else loaded without its velocity increments and kept. Its `dvel_mps` is then empty:
    /// [`load_case`] reads the static start's apart.
    pub fn derived(&self, derive_dir: &Path) -> anyhow::Result<Arc<Derived>> {
        let mut memo = self.derived.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(d) = memo.as_ref() {
            return Ok(d.clone());
        }
        let d = Arc::new(load_derived_for_navigation(derive_dir)?);
        *memo = Some(d.clone());
        Ok(d)
    }

    /// The derive in memory, when the chain holds it (nothing is loaded).
    pub fn kept_derived(&self) -> Option<Arc<Derived>> {
        self.derived
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Takes the derive out of memory, when the chain holds it: the last stage that reads
    /// it owns it then.
    pub fn take_kept_derived(&self) -> Option<Arc<Derived>> {
        self.derived
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
    }

    fn set_derived(&self, d: Option<Arc<Derived>>) {
        *self.derived.lock().unwrap_or_else(|e| e.into_inner()) = d;
    }

    fn record(&self, stage: &str, computed: bool, wall_s: f64) {
        if let Ok(mut log) = self.log.lock() {
            log.push((stage.to_owned(), computed, wall_s));
        }
    }
}

impl RunCtx {
    /// Where this run's artifacts live.
    pub fn layout(&self) -> RunLayout {
        RunLayout::new(&self.out, &self.manifest.name)
    }

    /// Says `what` of `stage` when verbose.
    pub fn say(&self, stage: &str, what: &str) {
        if self.verbose {
            eprintln!("{}: {stage}: {what}", self.manifest.name);
        }
    }

    /// Runs `body` unless `stage` is up to date; then records it.
    pub fn run_stage(
        &self,
        stage: &Stage<'_>,
        body: impl FnOnce() -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        let t0 = std::time::Instant::now();
        if let Some(p) = &self.progress {
            p.set_message(format!("{}: {}", self.manifest.name, stage.name));
        }
        if stage.is_up_to_date()? {
            self.say(stage.name, "up to date, skipped");
            self.record(stage.name, false, t0.elapsed().as_secs_f64());
            return Ok(());
        }
        stage.invalidate()?;
        body().with_context(|| format!("{}: stage {} failed", self.manifest.name, stage.name))?;
        stage.commit()?;
        let wall_s = t0.elapsed().as_secs_f64();
        self.say(stage.name, &format!("done in {wall_s:.2} s"));
        self.record(stage.name, true, wall_s);
        Ok(())
    }
}

/// Stage 1.
pub fn ensure_ingest(ctx: &RunCtx, params: &Params) -> anyhow::Result<PathBuf> {
    let m = &ctx.manifest;
    let dir = ctx.layout().create(StageName::Ingest)?;
    let mut inputs = vec![m.path.clone(), m.raw.clone()];
    inputs.extend(m.odometer.file.clone());
    let stage = Stage {
        dir: dir.clone(),
        name: "ingest",
        version: 1,
        params_hash: params_hash(&(m.odometer.scale_m_per_pulse, params.ingest))?,
        inputs,
        outputs: &INGEST_OUTPUTS,
    };
    ctx.run_stage(&stage, || ingest(m, &dir, params.ingest.into()).map(|_| ()))?;
    Ok(dir)
}

fn load_table<T: Default>(
    path: &Path,
    extend: impl Fn(&mut T, &RecordBatch) -> Result<(), unz_formats::FormatError>,
) -> anyhow::Result<(T, arrow::datatypes::SchemaRef)> {
    let mut t = T::default();
    let schema = for_each_batch(path, |b| extend(&mut t, b))?;
    Ok((t, schema))
}

/// [`load_table`] of the top-level `columns` only (the others are not decoded), into the
/// table `with_capacity` makes with room for the file's rows
/// ([`row_capacity_hint`]), so that no column grows twice over.
fn load_columns<T>(
    path: &Path,
    columns: &[&str],
    with_capacity: impl FnOnce(usize) -> T,
    extend: impl Fn(&mut T, &RecordBatch) -> Result<(), unz_formats::FormatError>,
) -> anyhow::Result<T> {
    let mut t = with_capacity(row_capacity_hint(path)?);
    for_each_batch_of(path, columns, |b| extend(&mut t, b))?;
    Ok(t)
}

/// Stage 2.
pub fn ensure_derive(ctx: &RunCtx, params: &Params) -> anyhow::Result<PathBuf> {
    let ingest_dir = ensure_ingest(ctx, params)?;
    let m = &ctx.manifest;
    let dir = ctx.layout().create(StageName::Derive)?;
    let inputs = vec![
        ingest_dir.join(files::IMU),
        ingest_dir.join(files::ODOMETER),
    ];
    let stage = Stage {
        dir: dir.clone(),
        name: "derive",
        version: 6,
        // The review's sensor blocks are taken here, at the recording's series rate.
        params_hash: params_hash(&(&params.derive, unz_viz::recording::SERIES_RATE_HZ))?,
        inputs,
        outputs: &[files::DERIVED, files::EPOCHS, files::BLOCKS, files::SENSORS],
    };
    ctx.run_stage(&stage, || {
        ctx.set_derived(None);
        let raw = IngestedSeries::load(&ingest_dir)?;
        let counts = raw.failure_counts();
        let mut d = raw.derive(&params.derive, site_gravity_mps2(m));
        (d.imu_failure_samples, d.odometer_failure_samples) = counts;
        // A run whose odometer is flagged failed over much of it has no dead reckoning
        // worth correcting; a short failure is counted and reported (navigate.json).
        if d.odometer_failure_samples * 10 > d.t_s.len() {
            bail!(
                "the odometer is flagged failed (status bit 1) on {} of {} samples",
                d.odometer_failure_samples,
                d.t_s.len()
            );
        }
        // A corrupt sample that passed the CRC (a 2^-16 chance per damaged frame) or a
        // saturated one is replaced and counted; many are a broken instrument or log.
        if d.out_of_range_samples * 100 > d.t_s.len() {
            bail!(
                "{} of {} IMU samples exceed the IMU's range ({:.0} °/s, {:.0} m/s²): saturated \
                 or corrupt increments",
                d.out_of_range_samples,
                d.t_s.len(),
                unz_stages::derive::GYRO_RANGE_RAD_S.to_degrees(),
                unz_stages::derive::ACCEL_RANGE_MPS2
            );
        }
        // A few tags going back are repaired and counted; a time base that does not
        // advance (constant or saturated tags) is no time base.
        if d.repaired_times * 100 > d.t_s.len() {
            bail!(
                "{} of {} IMU time tags do not increase (constant, saturated or going back): \
                 the log's time base is broken",
                d.repaired_times,
                d.t_s.len()
            );
        }
        ensure_finite("angle increment", d.dtheta_rad.iter().flatten().copied())?;
        ensure_finite("velocity increment", d.dvel_mps.iter().flatten().copied())?;
        ensure_finite("odometer distance", d.odo_dist_m.iter().copied())?;
        ensure_finite("accelerometer pitch", d.epochs.theta_p_rad.iter().copied())?;
        ensure_finite("accelerometer roll", d.epochs.phi_p_rad.iter().copied())?;
        write_derived(&d, &dir)?;
        let mut d = as_stored(d);
        // Beyond the static start (which the alignment reads from the file), only the
        // review reads the velocity increments: its blocks are taken now, and the chain
        // keeps the derive without them.
        write_review_sensors(&review_sensors(&d), &dir.join(files::SENSORS))?;
        d.dvel_mps = Arc::default();
        ctx.set_derived(Some(Arc::new(d)));
        Ok(())
    })?;
    Ok(dir)
}

/// Fails unless every value is finite, naming the quantity and the first sample that is
/// not: a stage never records outputs that went to Inf or NaN.
pub fn ensure_finite(what: &str, values: impl IntoIterator<Item = f64>) -> anyhow::Result<()> {
    if let Some((k, v)) = values.into_iter().enumerate().find(|(_, v)| !v.is_finite()) {
        bail!("{what} is {v} at sample {k}: the input's scales or values are not physical");
    }
    Ok(())
}

/// Normal gravity at the run's site, m/s² (derive's g).
pub fn site_gravity_mps2(m: &RunManifest) -> f64 {
    earth::normal_gravity_mps2(m.site.latitude_deg.to_radians(), m.site.height_m)
}

/// Why a run without an odometer table cannot be derived.
const NO_ODOMETER: &str = "the run has no odometer data (no 8th column and no odometer file)";

/// An ingested odometer as the lag's re-derives read it, its time tags compact.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OdometerTags {
    /// Time tags, ns in the log's time base.
    pub t_ns: TagTimes,
    /// Cumulative distance, m.
    pub distance_m: Vec<f64>,
}

/// The ingested IMU and odometer tables: what derive reads.
pub struct IngestedSeries {
    imu: ImuTable,
    odo: OdometerTable,
}

impl IngestedSeries {
    /// Loads `imu.parquet` and `odometer.parquet` of an ingest folder: the columns derive
    /// reads (not the IMU's sequence numbers nor the odometer's pulse counts).
    pub fn load(ingest_dir: &Path) -> anyhow::Result<Self> {
        let imu = load_columns(
            &ingest_dir.join(files::IMU),
            &ImuTable::SERIES_COLUMNS,
            ImuTable::with_series_capacity,
            ImuTable::extend_series_from_batch,
        )?;
        if imu.is_empty() {
            bail!("the raw log has no IMU record");
        }
        let odo = Self::load_odometer(ingest_dir)?;
        Ok(Self { imu, odo })
    }

    /// Loads `odometer.parquet` of an ingest folder alone, its times and distances (all a
    /// re-derive at another odometer timing reads).
    pub fn load_odometer(ingest_dir: &Path) -> anyhow::Result<OdometerTable> {
        let odo = load_columns(
            &ingest_dir.join(files::ODOMETER),
            &OdometerTable::SERIES_COLUMNS,
            OdometerTable::with_series_capacity,
            OdometerTable::extend_series_from_batch,
        )?;
        if odo.is_empty() {
            bail!(NO_ODOMETER);
        }
        Ok(odo)
    }

    /// [`Self::load_odometer`] with the time tags compact ([`TagTimes`]: half the
    /// memory), for the disupt stage, which holds the ingested odometer while the methods
    /// run (35 → 17 MB of times at 12 h at 100 Hz).
    pub fn load_odometer_tags(ingest_dir: &Path) -> anyhow::Result<OdometerTags> {
        let path = ingest_dir.join(files::ODOMETER);
        let rows = row_capacity_hint(&path)?;
        let mut odo = OdometerTags {
            t_ns: TagTimes::with_room_for(rows),
            distance_m: Vec::with_capacity(rows),
        };
        for_each_batch_of(&path, &[schema::T_NS, schema::DISTANCE_M], |b| {
            // Columns of one batch: as many times as distances.
            odo.t_ns.extend(i64_column(b, schema::T_NS)?);
            odo.distance_m.extend(f64_column(b, schema::DISTANCE_M)?);
            Ok(())
        })?;
        if odo.distance_m.is_empty() {
            bail!(NO_ODOMETER);
        }
        Ok(odo)
    }

    /// Samples whose status flags an IMU built-in-test failure (bit 0) and an odometer
    /// failure (bit 1).
    pub fn failure_counts(&self) -> (usize, usize) {
        let count = |bit: u16| self.imu.status.iter().filter(|s| *s & bit != 0).count();
        (count(1), count(2))
    }

    /// Derives the run, the IMU's increments repaired in place (no copy of the run's
    /// length): [`derive_owned`].
    pub fn derive(self, params: &DeriveParams, g_mps2: f64) -> Derived {
        // The status flags are counted already (failure_counts), the sequence numbers not
        // read: they go now, and the time tags once the time base is made.
        let ImuTable {
            t_ns,
            seq,
            dtheta_rad,
            dvel_mps,
            status,
        } = self.imu;
        drop((seq, status));
        let odometer = RawSeries {
            imu_t_ns: &[],
            dtheta_rad: &[],
            dvel_mps: &[],
            odo_t_ns: (&self.odo.t_ns).into(),
            odo_distance_m: &self.odo.distance_m,
        };
        derive_owned(t_ns.into(), dtheta_rad, dvel_mps, &odometer, params, g_mps2)
    }
}

/// Everything a navigation pass needs, loaded once.
pub struct NavCase {
    /// Derived series (shared with the run's other stages in this process).
    pub derived: Arc<Derived>,
    /// Control points matched to samples.
    pub fixes: Vec<ControlPointFix>,
    /// Settings of the pass.
    pub settings: NavSettings,
    /// How they were found.
    pub initial: InitialReport,
}

impl NavCase {
    /// The navigation inputs.
    pub fn inputs(&self) -> NavInputs<'_> {
        NavInputs {
            dt_s: &self.derived.dt_s,
            dtheta_rad: &self.derived.dtheta_rad,
            odo_dist_m: &self.derived.odo_dist_m,
        }
    }

    /// Runs the navigation into `track`.
    pub fn navigate(&self, track: &mut NavTrack) {
        navigate(&self.inputs(), &self.settings, track);
    }
}

/// Matches the manifest's control points: by their mark record, else by `t_s`.
pub fn match_control_points(
    m: &RunManifest,
    marks: &MarksTable,
    d: &Derived,
) -> anyhow::Result<Vec<ControlPointFix>> {
    let log_t_s = |t_ns: i64| t_ns as f64 * 1e-9;
    // The first mark of each point id.
    let mut first_mark = std::collections::HashMap::new();
    for (i, &id) in marks.point_id.iter().enumerate() {
        first_mark.entry(id).or_insert(i);
    }
    m.control_points
        .iter()
        .map(|cp| {
            let t_s = first_mark
                .get(&cp.id)
                .map(|&i| log_t_s(marks.t_ns[i]))
                .or(cp.t_s)
                .with_context(|| {
                    format!(
                        "control point {} matches no mark record and has no t_s",
                        cp.id
                    )
                })?;
            let rel = t_s - log_t_s(d.t0_ns);
            let Some(last) = d.t_s.last() else {
                bail!("no samples")
            };
            if rel < 0.0 || rel > last + d.nominal_dt_s {
                bail!("control point {} at t_s = {t_s} is outside the log", cp.id);
            }
            let sample = d.t_s.partition_point(|t| t < rel).min(d.t_s.len() - 1);
            Ok(ControlPointFix {
                id: cp.id,
                sample,
                t_s,
                lat_rad: cp.position.latitude_deg.to_radians(),
                lon_rad: cp.position.longitude_deg.to_radians(),
                h_m: cp.position.height_m,
            })
        })
        .collect()
}

/// Where the run starts: the manifest's site.
pub fn start_position(m: &RunManifest) -> Geodetic {
    Geodetic::from_deg(m.site.latitude_deg, m.site.longitude_deg, m.site.height_m)
}

/// Loads a navigation case of the run with `overrides` (derive must be up to date).
pub fn load_case(ctx: &RunCtx, params: &Params, overrides: &Overrides) -> anyhow::Result<NavCase> {
    let derive_dir = ensure_derive(ctx, params)?;
    let m = &ctx.manifest;
    let ingest_dir = ctx.layout().dir(StageName::Ingest);
    let derived = ctx.derived(&derive_dir)?;
    let (marks, _) = load_table::<MarksTable>(
        &ingest_dir.join(files::MARKS),
        MarksTable::extend_from_batch,
    )?;
    let odo_schema = read_schema(&ingest_dir.join(files::ODOMETER))?;
    let fixes = match_control_points(m, &marks, &derived)
        .with_context(|| format!("in {}", m.path.display()))?;
    let ingest_scale: Option<f64> = odo_schema
        .metadata()
        .get(META_ODO_M_PER_PULSE)
        .and_then(|s| s.parse().ok());
    let odo_scale = match (overrides.odo_scale_m_per_pulse, ingest_scale) {
        (Some(s), Some(used)) => s / used,
        (Some(s), None) => s,
        (None, _) => 1.0,
    };
    let i = &m.initial;
    let req = InitialRequest {
        azimuth_deg: overrides
            .azimuth_deg
            .map(|v| (v, Source::Override))
            .or(i.azimuth_deg.map(|v| (v, Source::Manifest))),
        pitch_deg: i.pitch_deg.map(|v| (v, Source::Manifest)),
        roll_deg: i.roll_deg.map(|v| (v, Source::Manifest)),
        drift_rad_s: overrides
            .drift_rad_s
            .map(|v| (v, Source::Override))
            .or(i.drift_rad_s.map(|v| (v, Source::Manifest))),
        static_s: i.static_s,
        odo_scale,
    };
    // The alignment reads the velocity increments of the static start only: read apart
    // when the derive was loaded without them.
    let prefix;
    let dvel_mps: &[[f64; 3]] = if derived.dvel_mps.len() == derived.t_s.len() {
        &derived.dvel_mps
    } else {
        prefix = read_velocity_prefix(&derive_dir, static_samples(&derived, &req))?;
        &prefix
    };
    let (settings, initial) =
        initial_settings_with_velocity(&derived, dvel_mps, &req, &params.align, start_position(m));
    if initial.gyrocompass_skipped.is_some() && fixes.is_empty() {
        bail!(
            "the run has neither a static start nor a control point: without a static start \
             there is no gyrocompass heading, and without a control point DISUPT cannot find \
             the azimuth (in {})",
            m.path.display()
        );
    }
    Ok(NavCase {
        derived,
        fixes,
        settings,
        initial,
    })
}

/// Summary of a navigation pass (`navigate.json`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct NavigateSummary {
    /// Initial settings and alignment.
    pub initial: InitialReport,
    /// Samples navigated.
    pub samples: usize,
    /// Duration, s.
    pub duration_s: f64,
    /// Distance travelled, m.
    pub distance_m: f64,
    /// Position errors at the control points.
    pub control_points: Vec<Kryt2>,
    /// Time tags derive repaired (not after the previous one).
    pub repaired_times: usize,
    /// Samples that closed a gap in the log and were scaled to it.
    pub filled_gaps: usize,
    /// Samples whose status flags an IMU built-in-test failure.
    #[serde(default)]
    pub imu_failure_samples: usize,
    /// Samples whose status flags an odometer failure (a run fails above a tenth).
    #[serde(default)]
    pub odometer_failure_samples: usize,
    /// Samples whose increments exceeded the IMU's range, replaced by the previous
    /// sample's rates (a run fails above a hundredth).
    #[serde(default)]
    pub out_of_range_samples: usize,
}

/// Stage 3a: navigation.
pub fn ensure_navigate(
    ctx: &RunCtx,
    params: &Params,
    overrides: &Overrides,
) -> anyhow::Result<PathBuf> {
    let derive_dir = ensure_derive(ctx, params)?;
    let m = &ctx.manifest;
    let dir = ctx.layout().create(StageName::Navigate)?;
    let ingest_dir = ctx.layout().dir(StageName::Ingest);
    let inputs = vec![
        m.path.clone(),
        derive_dir.join(files::DERIVED),
        ingest_dir.join(files::MARKS),
        ingest_dir.join(files::ODOMETER),
    ];
    let stage = Stage {
        dir: dir.clone(),
        name: "navigate",
        version: 3,
        params_hash: params_hash(&(params.align, overrides))?,
        inputs,
        outputs: &[files::NAV, files::NAVIGATE_REPORT],
    };
    ctx.run_stage(&stage, || {
        let case = load_case(ctx, params, overrides)?;
        // The pass writes nav.parquet as it runs, keeping the positions at the control
        // points.
        let fix_samples: Vec<usize> = case.fixes.iter().map(|f| f.sample).collect();
        let mut nav = NavWriter::create(
            &dir.join(files::NAV),
            &case.derived,
            case.settings.start(),
            None,
            &fix_samples,
        )?;
        unz_stages::strapdown::run(&case.inputs(), &case.settings, &mut nav);
        let nav = nav.finish("navigated")?;
        let summary = NavigateSummary {
            initial: case.initial,
            samples: nav.samples,
            duration_s: case.derived.t_s.last().unwrap_or(0.0),
            distance_m: nav.distance_m,
            control_points: criteria::kryt2_at(&case.fixes, |k| {
                nav.at(k).map(|s| (s.lat_rad, s.lon_rad))
            }),
            repaired_times: case.derived.repaired_times,
            filled_gaps: case.derived.filled_gaps,
            imu_failure_samples: case.derived.imu_failure_samples,
            out_of_range_samples: case.derived.out_of_range_samples,
            odometer_failure_samples: case.derived.odometer_failure_samples,
        };
        write_json_atomic(&dir.join(files::NAVIGATE_REPORT), &summary)?;
        Ok(())
    })?;
    Ok(dir)
}

/// `criteria.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CriteriaSummary {
    /// Kryt1, rad.
    pub kryt1_rad: f64,
    /// Epochs.
    pub epochs: usize,
    /// Epochs used (not gated).
    pub valid_epochs: usize,
    /// Kryt2 at every control point.
    pub control_points: Vec<Kryt2>,
    /// Kryt2 at the last control point, m.
    pub kryt2_m: Option<f64>,
}

/// (sample, latitude rad, longitude rad).
type Position = (usize, f64, f64);

/// What the criteria read of `nav.parquet` (`samples` rows), batch by batch (the track is
/// never held whole): the attitude per block of `block` samples, and the positions
/// (sample, latitude rad, longitude rad) at the samples `at`.
fn read_nav_for_criteria(
    path: &Path,
    samples: usize,
    block: usize,
    at: &[usize],
) -> anyhow::Result<(BlockAttitude, Vec<Position>)> {
    let mut blocks = Row3Blocks::for_samples(samples, block);
    let mut positions = Vec::new();
    let mut k0 = 0;
    use unz_formats::schema::nav_cols::{HEADING_DEG, LAT_DEG, LON_DEG, PITCH_DEG, ROLL_DEG};
    let columns = [LAT_DEG, LON_DEG, ROLL_DEG, PITCH_DEG, HEADING_DEG];
    for_each_batch_of(path, &columns, |b| {
        let rad = |n: &str| -> Result<Vec<f64>, unz_formats::FormatError> {
            Ok(f64_column(b, n)?.into_iter().map(f64::to_radians).collect())
        };
        let (roll, pitch, heading) = (rad(ROLL_DEG)?, rad(PITCH_DEG)?, rad(HEADING_DEG)?);
        for k in 0..roll.len() {
            let q = unz_stages::attitude::Euler {
                roll_rad: roll[k],
                pitch_rad: pitch[k],
                heading_rad: heading[k],
            }
            .to_quat_b_to_n();
            blocks.push(&[q.w, q.i, q.j, q.k]);
        }
        let n = roll.len();
        let here: Vec<usize> = at
            .iter()
            .copied()
            .filter(|&s| (k0..k0 + n).contains(&s))
            .collect();
        if !here.is_empty() {
            let (lat, lon) = (rad(LAT_DEG)?, rad(LON_DEG)?);
            positions.extend(here.iter().map(|&s| (s, lat[s - k0], lon[s - k0])));
        }
        k0 += n;
        Ok(())
    })?;
    Ok((blocks.finish(), positions))
}

/// Stage 3b: the criteria of the navigated track.
pub fn ensure_criteria(
    ctx: &RunCtx,
    params: &Params,
    overrides: &Overrides,
) -> anyhow::Result<(PathBuf, CriteriaSummary)> {
    let nav_dir = ensure_navigate(ctx, params, overrides)?;
    let m = &ctx.manifest;
    let derive_dir = ctx.layout().dir(StageName::Derive);
    let ingest_dir = ctx.layout().dir(StageName::Ingest);
    let dir = ctx.layout().create(StageName::Criteria)?;
    let inputs = vec![
        m.path.clone(),
        nav_dir.join(files::NAV),
        derive_dir.join(files::DERIVED),
        derive_dir.join(files::EPOCHS),
        ingest_dir.join(files::MARKS),
    ];
    let stage = Stage {
        dir: dir.clone(),
        name: "criteria",
        version: 1,
        params_hash: params_hash(&(params.kalman, params.derive.filter))?,
        inputs,
        outputs: &[files::CRITERIA, files::CRITERIA_REPORT],
    };
    ctx.run_stage(&stage, || {
        // The criteria read the derive's times and epochs only: without the chain's derive
        // in memory, only those are loaded.
        let d = match ctx.kept_derived() {
            Some(d) => d,
            None => Arc::new(load_derived_times(&derive_dir)?),
        };
        let (marks, _) = load_table::<MarksTable>(
            &ingest_dir.join(files::MARKS),
            MarksTable::extend_from_batch,
        )?;
        let fixes = match_control_points(m, &marks, &d)
            .with_context(|| format!("in {}", m.path.display()))?;
        let lp = LowPass::new(&params.derive.filter, d.nominal_dt_s);
        let fix_samples: Vec<usize> = fixes.iter().map(|f| f.sample).collect();
        let (blocks, positions) = read_nav_for_criteria(
            &nav_dir.join(files::NAV),
            d.t_s.len(),
            lp.block,
            &fix_samples,
        )?;
        let mut series = Kryt1Series::default();
        let k1 =
            criteria::kryt1_from_blocks(&d.epochs, &lp, blocks, &params.kalman, Some(&mut series));
        write_criteria_parquet(&dir.join(files::CRITERIA), &d, &series)?;
        let cps = criteria::kryt2_at(&fixes, |k| {
            positions
                .iter()
                .find(|p| p.0 == k)
                .map(|&(_, lat, lon)| (lat, lon))
        });
        let summary = CriteriaSummary {
            kryt1_rad: k1,
            epochs: d.epochs.t_s.len(),
            valid_epochs: d.epochs.valid.iter().filter(|v| **v).count(),
            kryt2_m: cps.last().map(|c| c.kryt2_m),
            control_points: cps,
        };
        write_json_atomic(&dir.join(files::CRITERIA_REPORT), &summary)?;
        Ok(())
    })?;
    let summary = serde_json::from_slice(&std::fs::read(dir.join(files::CRITERIA_REPORT))?)?;
    Ok((dir, summary))
}

fn write_criteria_parquet(path: &Path, d: &Derived, s: &Kryt1Series) -> anyhow::Result<()> {
    let e = &d.epochs;
    let table = CriteriaTable {
        t_ns: d.epoch_t_ns(),
        theta_n_rad: s.theta_n_rad.clone(),
        phi_n_rad: s.phi_n_rad.clone(),
        theta_p_rad: e.theta_p_rad.clone(),
        phi_p_rad: e.phi_p_rad.clone(),
        d_theta_rad: s.d_theta_rad.clone(),
        d_phi_rad: s.d_phi_rad.clone(),
        kf_d_theta_rad: s.kf_theta_rad.clone(),
        kf_d_phi_rad: s.kf_phi_rad.clone(),
        kryt1_cum: s.kryt1_cum.clone(),
        valid: e.valid.clone(),
    };
    write_batch(path, &table.to_batch(schema::criteria())?)?;
    Ok(())
}

/// Loads `criteria.parquet`.
pub fn load_criteria(path: &Path) -> anyhow::Result<CriteriaTable> {
    let (table, _) = load_table::<CriteriaTable>(path, CriteriaTable::extend_from_batch)?;
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;
    use unz_formats::parquet_io::write_batch;

    /// The compact load gives the tags and distances the plain one gives, across the
    /// reader's batches, a gap and a tag going back; an odometer-less run is refused.
    #[test]
    fn the_compact_odometer_is_the_ingested_one() {
        let n = 150_000_i64;
        let t_ns: Vec<i64> = (0..n)
            .map(|k| {
                let gap = if k >= 70_000 { 9_000_000_000 } else { 0 };
                let back = if k == 100_000 { -20_000_000 } else { 0 };
                5_000_000 + k * 10_000_000 + gap + back
            })
            .collect();
        let table = OdometerTable {
            distance_m: t_ns.iter().map(|&t| t as f64 * 1e-8).collect(),
            pulses: vec![None; t_ns.len()],
            t_ns,
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(files::ODOMETER);
        write_batch(&path, &table.to_batch(schema::odometer(None)).unwrap()).unwrap();
        let plain = IngestedSeries::load_odometer(dir.path()).unwrap();
        let tags = IngestedSeries::load_odometer_tags(dir.path()).unwrap();
        assert_eq!(tags.t_ns.len(), table.t_ns.len());
        assert_eq!(tags.t_ns.iter().collect::<Vec<_>>(), plain.t_ns);
        assert_eq!(tags.distance_m, plain.distance_m);
        assert_eq!(plain.t_ns, table.t_ns);

        let empty = OdometerTable::default();
        write_batch(&path, &empty.to_batch(schema::odometer(None)).unwrap()).unwrap();
        let err = IngestedSeries::load_odometer_tags(dir.path())
            .unwrap_err()
            .to_string();
        assert!(err.contains("no odometer data"), "{err}");
    }
}
