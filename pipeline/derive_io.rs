//! Parquet form of the derive stage's outputs: `derived.parquet` (per IMU sample: the
//! repaired time base and the odometer's terms), `imu_repairs.parquet` (the IMU samples
//! whose increments the derive replaced), `epochs.parquet` (per ΔTg epoch) and
//! `blocks.parquet` (the filtered series per block of F), and loading them back whole.
//!
//! The IMU's increments are not stored again: every sample's are the ingest's
//! `imu.parquet`'s but for the few in `imu_repairs.parquet`, so a load reads them there
//! (the derive's largest columns, which it wrote a second time and hashed for the cache).

use crate::artifacts::{RunLayout, StageName, files};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, bail};
use arrow::array::{AsArray, BooleanArray, Float64Array, Int64Array, RecordBatch, UInt64Array};
use unz_formats::parquet_io::{
    ParquetSink, for_each_batch_of, for_each_batch_of_first, read_table, row_capacity_hint,
    write_batch,
};
use unz_formats::schema::{
    self, DTHETA_RAD, DVEL_MPS, T_NS, VALID, derived_cols, derived_meta, epochs_cols,
    filtered_cols, imu_repairs_cols,
};
use unz_formats::split_doubles::{for_each_split_values, read_split_doubles, read_split_vec3};
use unz_formats::tables::{f64_column, i64_column, u64_column, vec3_column, vec3_to_array};
use unz_stages::angle_increments::{AngleIncrements, AngleIncrementsBuilder};
use unz_stages::derive::{Derived, Epochs, OdometerSpeed, ns_since};
use unz_stages::odo_rebridge::WindowVelocities;
use unz_stages::time_base::{NanoTimes, TimeBase};

fn f64s(v: &[f64]) -> Arc<Float64Array> {
    Arc::new(Float64Array::from(v.to_vec()))
}

/// Writes `derived.parquet`, `imu_repairs.parquet`, `epochs.parquet` and
/// `blocks.parquet` into `dir`.
pub fn write_derived(d: &Derived, dir: &Path) -> anyhow::Result<()> {
    let axes_check = d
        .axes_check
        .map(|c| serde_json::to_string(&c))
        .transpose()?;
    let odometer_clock = (d.odometer_clock.map(|c| serde_json::to_string(&c))).transpose()?;
    let schema = schema::derived(
        [
            (derived_meta::BLOCK, d.block.to_string()),
            (derived_meta::NOMINAL_DT_S, d.nominal_dt_s.to_string()),
            (derived_meta::REPAIRED_TIMES, d.repaired_times.to_string()),
            (derived_meta::FILLED_GAPS, d.filled_gaps.to_string()),
            (
                derived_meta::IMU_FAILURES,
                d.imu_failure_samples.to_string(),
            ),
            (
                derived_meta::ODO_FAILURES,
                d.odometer_failure_samples.to_string(),
            ),
            (
                derived_meta::OUT_OF_RANGE,
                d.out_of_range_samples.to_string(),
            ),
        ]
        .into_iter()
        .chain(axes_check.map(|c| (derived_meta::IMU_AXES_CHECK, c)))
        .chain(odometer_clock.map(|c| (derived_meta::ODOMETER_CLOCK, c))),
    );
    // In batches of 65 536 rows: the columns of one batch are copied at a time, whatever
    // the run's length.
    const ROWS: usize = 1 << 16;
    let mut sink = ParquetSink::create(&dir.join(files::DERIVED), schema.clone())?;
    let n = d.t_s.len();
    for lo in (0..n).step_by(ROWS) {
        let r = lo..(lo + ROWS).min(n);
        // u, u̇ and ru are computed for the file, not kept by the derive.
        let speeds: Vec<OdometerSpeed> = d.odometer_speeds(r.clone()).collect();
        let speed = |f: fn(&OdometerSpeed) -> f64| {
            Arc::new(Float64Array::from_iter_values(speeds.iter().map(f)))
        };
        let batch = RecordBatch::try_new(
            schema.clone(),
            vec![
                Arc::new(Int64Array::from_iter_values(d.t_ns(r.clone()))),
                f64s(&d.dt_s[r.clone()]),
                f64s(&d.odo_dist_m[r.clone()]),
                speed(|s| s.u_mps),
                speed(|s| s.u_dot_mps2),
                speed(|s| s.ru_mps2),
            ],
        )?;
        sink.write(&batch)?;
    }
    sink.finish()?;

    let replaced = &d.replaced_increments;
    let batch = RecordBatch::try_new(
        schema::imu_repairs(),
        vec![
            Arc::new(UInt64Array::from_iter_values(
                replaced.iter().map(|&k| k as u64),
            )),
            Arc::new(Int64Array::from_iter_values(
                replaced.iter().map(|&k| d.t_ns_at(k)),
            )),
            vec3_to_array(
                &replaced
                    .iter()
                    .map(|&k| d.dtheta_rad.get(k))
                    .collect::<Vec<_>>(),
            ),
            vec3_to_array(&replaced.iter().map(|&k| d.dvel_mps[k]).collect::<Vec<_>>()),
        ],
    )?;
    write_batch(&dir.join(files::IMU_REPAIRS), &batch)?;

    let e = &d.epochs;
    let at = |v: &[f64]| f64s(&e.block.iter().map(|&j| v[j]).collect::<Vec<_>>());
    let schema = schema::epochs();
    let batch = RecordBatch::try_new(
        schema,
        vec![
            Arc::new(Int64Array::from(d.epoch_t_ns())),
            Arc::new(UInt64Array::from(
                e.block.iter().map(|&b| b as u64).collect::<Vec<_>>(),
            )),
            f64s(&e.theta_p_rad),
            f64s(&e.phi_p_rad),
            f64s(&e.theta_p_per_yaw),
            f64s(&e.phi_p_per_yaw),
            f64s(&e.theta_p_per_bias),
            f64s(&e.phi_p_per_bias),
            Arc::new(BooleanArray::from(e.valid.clone())),
            at(&d.ax_f),
            at(&d.ay_f),
            at(&d.u_dot_f),
            at(&d.ru_f),
        ],
    )?;
    write_batch(&dir.join(files::EPOCHS), &batch)?;

    let batch = RecordBatch::try_new(
        schema::blocks(),
        vec![
            f64s(&d.ax_f),
            f64s(&d.ay_f),
            f64s(&d.u_dot_f),
            f64s(&d.ru_f),
            f64s(&d.r_moving_f),
            f64s(&d.moving_dot_f),
        ],
    )?;
    write_batch(&dir.join(files::BLOCKS), &batch)?;
    Ok(())
}

/// `d` as [`load_derived`] gives it back after [`write_derived`]: the times are stored
/// in whole nanoseconds, so the ones that are not (a repaired sample's, the epochs') come
/// back within half of one, and the first sample out of range is not stored. A stage
/// handed the derive in memory then computes exactly what it computes from the cache.
pub fn as_stored(mut d: Derived) -> Derived {
    let t0_ns = d.t_s.first().map_or(0, |t| d.ns_of(t));
    let epoch_t_ns = d.epoch_t_ns();
    // `ns_of`, then nanoseconds from the first stored time: the compact form a load
    // gives.
    let was_t0_ns = d.t0_ns;
    d.t_s = TimeBase::from_nanos(d.t_s.iter().map(|t| ns_since(was_t0_ns, t) - t0_ns));
    d.epochs.t_s = epoch_t_ns
        .iter()
        .map(|t| (t - t0_ns) as f64 * 1e-9)
        .collect();
    d.t0_ns = t0_ns;
    // Not stored: what only a failing derive names.
    d.first_out_of_range = None;
    d
}

/// Where a stored derive is read: its folder, and the ingest's, whose `imu.parquet` holds
/// the increments of every sample the derive did not replace.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredDerive {
    /// The derive stage's folder.
    pub derive_dir: PathBuf,
    /// The ingest stage's folder.
    pub ingest_dir: PathBuf,
}

impl StoredDerive {
    /// The stored derive of a run.
    pub fn of(layout: &RunLayout) -> Self {
        Self {
            derive_dir: layout.dir(StageName::Derive),
            ingest_dir: layout.dir(StageName::Ingest),
        }
    }
}

/// Loads what [`write_derived`] wrote: the derive whole, counts and filtered series
/// included (u, u̇ and ru, which the derive computes where it reads them, are not read
/// back).
pub fn load_derived(at: &StoredDerive) -> anyhow::Result<Derived> {
    load_derived_of(&at.derive_dir, Some(&at.ingest_dir), Columns::All)
}

/// [`load_derived`] without the velocity increments (left empty): what navigation passes
/// read; the alignment reads the static start's ([`read_velocity_prefix`]).
pub fn load_derived_for_navigation(at: &StoredDerive) -> anyhow::Result<Derived> {
    load_derived_of(
        &at.derive_dir,
        Some(&at.ingest_dir),
        Columns::WithoutVelocity,
    )
}

/// [`load_derived`] without the per-sample increments and intervals (left empty): the
/// times, the filtered block series and the epochs, all the criteria read (the derive's
/// folder alone).
pub fn load_derived_times(derive_dir: &Path) -> anyhow::Result<Derived> {
    load_derived_of(derive_dir, None, Columns::Times)
}

/// The velocity increments of the first `n` samples of the stored derive (all of them
/// when it has fewer; the ingest's batches after them are not decoded).
pub fn read_velocity_prefix(at: &StoredDerive, n: usize) -> anyhow::Result<Vec<[f64; 3]>> {
    let mut prefix = velocities_over(at, std::slice::from_ref(&(0..n)))?;
    Ok(prefix.pop().unwrap_or_default())
}

/// The velocity increments of the stored derive over each of `ranges` (sample indices,
/// in order and not overlapping; the ingest's batches after the last are not decoded).
pub fn read_velocity_ranges(
    at: &StoredDerive,
    ranges: &[std::ops::Range<usize>],
) -> anyhow::Result<WindowVelocities> {
    let out = velocities_over(at, ranges)?;
    anyhow::ensure!(
        out.iter().zip(ranges).all(|(o, r)| o.len() == r.len()),
        "{} has fewer rows than the derive's samples",
        at.ingest_dir.join(files::IMU).display()
    );
    Ok(out)
}

/// The velocity increments of the stored derive over each of `ranges` (sample indices,
/// in order and not overlapping), each cut short where the samples end.
fn velocities_over(
    at: &StoredDerive,
    ranges: &[std::ops::Range<usize>],
) -> anyhow::Result<WindowVelocities> {
    let mut out: WindowVelocities = ranges.iter().map(|r| Vec::with_capacity(r.len())).collect();
    let Some(end) = ranges.iter().map(|r| r.end).max().filter(|&e| e > 0) else {
        return Ok(out);
    };
    let mut first_row = 0;
    // No row past the last range's end is decoded.
    for_each_batch_of_first(&at.ingest_dir.join(files::IMU), &[DVEL_MPS], end, |b| {
        let rows = first_row..first_row + b.num_rows();
        if ranges
            .iter()
            .any(|r| r.start < rows.end && rows.start < r.end)
        {
            let v = vec3_column(b, DVEL_MPS)?;
            for (r, o) in ranges.iter().zip(&mut out) {
                let (from, to) = (r.start.max(rows.start), r.end.min(rows.end));
                if from < to {
                    o.extend_from_slice(&v[from - rows.start..to - rows.start]);
                }
            }
        }
        first_row = rows.end;
        Ok(())
    })?;
    let repairs = ImuRepairs::read(&at.derive_dir)?;
    for (r, o) in ranges.iter().zip(&mut out) {
        repairs.apply(Increment::Velocity, r.start..r.start + o.len(), o);
    }
    Ok(out)
}

/// Which increments of a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Increment {
    Angle,
    Velocity,
}

/// What `imu_repairs.parquet` holds: the samples whose increments the derive replaced,
/// in order, and the increments it uses there.
#[derive(Debug, Default)]
struct ImuRepairs {
    sample: Vec<usize>,
    dtheta_rad: Vec<[f64; 3]>,
    dvel_mps: Vec<[f64; 3]>,
}

impl ImuRepairs {
    /// Reads the table of `derive_dir`.
    fn read(derive_dir: &Path) -> anyhow::Result<Self> {
        let path = derive_dir.join(files::IMU_REPAIRS);
        let (_, t) = read_table(&path)?;
        let read = || -> Result<Self, unz_formats::FormatError> {
            Ok(Self {
                sample: (u64_column(&t, imu_repairs_cols::SAMPLE)?.into_iter())
                    .map(|k| k as usize)
                    .collect(),
                dtheta_rad: vec3_column(&t, DTHETA_RAD)?,
                dvel_mps: vec3_column(&t, DVEL_MPS)?,
            })
        };
        let repairs = read().map_err(|e| e.in_file(&path))?;
        // The derive's own file, but read with care all the same: in order, in range.
        if let Some(w) = repairs.sample.windows(2).find(|w| w[1] <= w[0]) {
            bail!(
                "{}: samples not in increasing order ({} then {})",
                path.display(),
                w[0],
                w[1]
            );
        }
        Ok(repairs)
    }

    /// Writes the repairs of `which` increments over the samples `rows` into `out`, their
    /// increments as ingested (`out[i]` is sample `rows.start + i`'s).
    fn apply(&self, which: Increment, rows: std::ops::Range<usize>, out: &mut [[f64; 3]]) {
        self.apply_with(which, rows.clone(), |k, v| out[k - rows.start] = v);
    }

    /// `set(k, increments)` for each repaired sample `k` within `rows`, in order, with the
    /// increments the derive uses there.
    fn apply_with(
        &self,
        which: Increment,
        rows: std::ops::Range<usize>,
        mut set: impl FnMut(usize, [f64; 3]),
    ) {
        let values = match which {
            Increment::Angle => &self.dtheta_rad,
            Increment::Velocity => &self.dvel_mps,
        };
        let first = self.sample.partition_point(|&k| k < rows.start);
        for (&k, v) in self.sample[first..].iter().zip(&values[first..]) {
            if k >= rows.end {
                break;
            }
            set(k, *v);
        }
    }
}

/// Which per-sample columns of the stored derive a load reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Columns {
    All,
    WithoutVelocity,
    Times,
}

/// Loads the stored derive in `dir`; the IMU's increments (which `columns` asks for)
/// from the ingest's `imu.parquet` in `ingest_dir`, repaired.
fn load_derived_of(
    dir: &Path,
    ingest_dir: Option<&Path>,
    columns: Columns,
) -> anyhow::Result<Derived> {
    let path = dir.join(files::DERIVED);
    let (bpath, epath) = (dir.join(files::BLOCKS), dir.join(files::EPOCHS));
    // Column by column, batch by batch, each column sized to the file's rows once: the
    // run's series without the file's batches beside them, nor a column grown twice
    // over. Times go to seconds from the first as they are read.
    let rows = row_capacity_hint(&path)?;
    let per_sample = |wanted: bool| if wanted { rows } else { 0 };
    let (with_nav, with_velocity) = (columns != Columns::Times, columns == Columns::All);
    let imu = match ingest_dir {
        Some(ingest) => Some(ingest.join(files::IMU)),
        None if with_nav => bail!("the derive's increments are read with the ingest's"),
        None => None,
    };
    // Three readers side by side, as the cores take them: the derive's times and scalars,
    // the ingest's increments (the larger part), the filter's blocks and the epochs.
    let scalars = || -> anyhow::Result<_> {
        let mut t0_ns: Option<i64> = None;
        let mut t_s = NanoTimes::builder().with_room_for(rows);
        // The intervals and the odometer's increments by split_doubles, else through
        // Arrow with the times.
        let fast = if with_nav {
            let read = |name: &str| read_split_doubles(&path, name, 1);
            match (read(derived_cols::DT_S)?, read(derived_cols::ODO_DIST_M)?) {
                (Some(dt_s), Some(odo_dist_m)) => Some((dt_s, odo_dist_m)),
                _ => None,
            }
        } else {
            Some((Vec::new(), Vec::new()))
        };
        let through_arrow = fast.is_none();
        let mut dt_s = Vec::with_capacity(if through_arrow { rows } else { 0 });
        let mut odo_dist_m = Vec::with_capacity(if through_arrow { rows } else { 0 });
        let names: &[&str] = if through_arrow {
            &[T_NS, derived_cols::DT_S, derived_cols::ODO_DIST_M]
        } else {
            &[T_NS]
        };
        let schema = for_each_batch_of(&path, names, |b| {
            let t_ns = i64_column(b, T_NS)?;
            let t0 = *t0_ns.get_or_insert(t_ns.first().copied().unwrap_or(0));
            for t in t_ns.iter() {
                t_s.push(t - t0);
            }
            if through_arrow {
                dt_s.extend(f64_column(b, derived_cols::DT_S)?);
                odo_dist_m.extend(f64_column(b, derived_cols::ODO_DIST_M)?);
            }
            Ok(())
        })?;
        let (dt_s, odo_dist_m) = fast.unwrap_or((dt_s, odo_dist_m));
        Ok((schema, t0_ns, t_s, dt_s, odo_dist_m))
    };
    let tables = || -> anyhow::Result<_> {
        let (_, blocks) = read_table(&bpath)?;
        let (_, epochs) = read_table(&epath)?;
        Ok((blocks, epochs))
    };
    let vectors = || -> anyhow::Result<_> {
        let names: &[&str] = match (with_nav, with_velocity) {
            (_, true) => &[DTHETA_RAD, DVEL_MPS],
            (true, false) => &[DTHETA_RAD],
            (false, false) => return Ok((AngleIncrements::default(), Vec::new(), Vec::new())),
        };
        let Some(imu) = &imu else {
            return Ok((AngleIncrements::default(), Vec::new(), Vec::new()));
        };
        // Each column's byte streams joined here (split_doubles), else through Arrow. The
        // angle increments go to their held form as each page comes
        // ([`AngleIncrementsBuilder`]: a binary log's in f32, never in f64 first).
        let fast_angles = || -> anyhow::Result<Option<AngleIncrements>> {
            if !with_nav {
                return Ok(Some(AngleIncrements::default()));
            }
            let mut angles = AngleIncrementsBuilder::with_room_for(rows);
            let leaf = format!("{DTHETA_RAD}.list.item");
            let whole = for_each_split_values::<f64>(imu, &leaf, 3, |_, values| {
                angles.extend_from_values(values);
            })?;
            Ok(whole.then(|| angles.finish()).flatten())
        };
        let fast_velocities = || -> anyhow::Result<Option<Vec<[f64; 3]>>> {
            Ok(if with_velocity {
                read_split_vec3(imu, DVEL_MPS)?
            } else {
                Some(Vec::new())
            })
        };
        // Through Arrow, each column sized to the file's rows once; the columns read
        // above take room only once their layout is known (the velocities sized to their
        // values, the angles to the derive's rows).
        let (mut dtheta_rad, mut dvel_mps) = match (fast_angles()?, fast_velocities()?) {
            (Some(angles), Some(velocities)) => (angles, velocities),
            _ => {
                let mut angles = Vec::with_capacity(per_sample(with_nav));
                let mut velocities = Vec::with_capacity(per_sample(with_velocity));
                for_each_batch_of(imu, names, |b| {
                    if with_nav {
                        angles.extend(vec3_column(b, DTHETA_RAD)?);
                    }
                    if with_velocity {
                        velocities.extend(vec3_column(b, DVEL_MPS)?);
                    }
                    Ok(())
                })?;
                (AngleIncrements::compact(angles), velocities)
            }
        };
        let repairs = ImuRepairs::read(dir)?;
        if let Some(&k) = repairs.sample.last().filter(|&&k| k >= dtheta_rad.len()) {
            bail!(
                "{}: sample {k} repaired, of {} samples",
                dir.join(files::IMU_REPAIRS).display(),
                dtheta_rad.len()
            );
        }
        let all = 0..dtheta_rad.len();
        repairs.apply_with(Increment::Angle, all.clone(), |k, v| dtheta_rad.set(k, v));
        if with_velocity {
            repairs.apply(Increment::Velocity, all, &mut dvel_mps);
        }
        Ok((dtheta_rad, dvel_mps, repairs.sample))
    };
    let (scalars, (vectors, tables)) = rayon::join(scalars, || rayon::join(vectors, tables));
    let ((schema, t0_ns, t_s, dt_s, odo_dist_m), (dtheta_rad, dvel_mps, replaced), (bl, e)) =
        (scalars?, vectors?, tables?);
    anyhow::ensure!(
        !with_nav || dtheta_rad.len() == dt_s.len(),
        "{} has {} rows, {} {} (the ingest it was derived from: derive again)",
        path.display(),
        dt_s.len(),
        imu.as_deref().unwrap_or(Path::new("")).display(),
        dtheta_rad.len()
    );
    let meta = |k: &str| -> anyhow::Result<String> {
        schema
            .metadata()
            .get(k)
            .cloned()
            .with_context(|| format!("{} lacks metadata {k}", path.display()))
    };
    let mut d = Derived {
        t0_ns: t0_ns.unwrap_or(0),
        nominal_dt_s: meta(derived_meta::NOMINAL_DT_S)?.parse()?,
        t_s: TimeBase::Nanos(Arc::new(t_s.finish())),
        dt_s: dt_s.into(),
        dtheta_rad: Arc::new(dtheta_rad),
        dvel_mps: dvel_mps.into(),
        replaced_increments: replaced,
        odo_dist_m,
        block: meta(derived_meta::BLOCK)?.parse()?,
        repaired_times: meta(derived_meta::REPAIRED_TIMES)?.parse()?,
        filled_gaps: meta(derived_meta::FILLED_GAPS)?.parse()?,
        imu_failure_samples: meta(derived_meta::IMU_FAILURES)?.parse()?,
        out_of_range_samples: meta(derived_meta::OUT_OF_RANGE)?.parse()?,
        odometer_failure_samples: meta(derived_meta::ODO_FAILURES)?.parse()?,
        axes_check: (schema.metadata().get(derived_meta::IMU_AXES_CHECK))
            .map(|c| serde_json::from_str(c))
            .transpose()
            .with_context(|| format!("{}: {}", path.display(), derived_meta::IMU_AXES_CHECK))?,
        odometer_clock: (schema.metadata().get(derived_meta::ODOMETER_CLOCK))
            .map(|c| serde_json::from_str(c))
            .transpose()
            .with_context(|| format!("{}: {}", path.display(), derived_meta::ODOMETER_CLOCK))?,
        ..Derived::default()
    };
    d.ax_f = f64_column(&bl, filtered_cols::AX_F_MPS2)?.into();
    d.ay_f = f64_column(&bl, filtered_cols::AY_F_MPS2)?.into();
    d.u_dot_f = f64_column(&bl, filtered_cols::U_DOT_F_MPS2)?;
    d.ru_f = f64_column(&bl, filtered_cols::RU_F_MPS2)?;
    d.r_moving_f = f64_column(&bl, filtered_cols::R_MOVING_F_RAD_S)?;
    d.moving_dot_f = f64_column(&bl, filtered_cols::MOVING_DOT_F_PER_S)?;
    let blocks = u64_column(&e, epochs_cols::BLOCK).map_err(|err| err.in_file(&epath))?;
    let valid = e
        .column_by_name(VALID)
        .and_then(|c| c.as_boolean_opt())
        .with_context(|| format!("{}: no Boolean column {VALID:?}", epath.display()))?;
    d.epochs = Epochs {
        block: blocks.into_iter().map(|b| b as usize).collect(),
        t_s: i64_column(&e, T_NS)?
            .iter()
            .map(|t| (t - d.t0_ns) as f64 * 1e-9)
            .collect(),
        theta_p_rad: f64_column(&e, epochs_cols::THETA_P_RAD)?,
        phi_p_rad: f64_column(&e, epochs_cols::PHI_P_RAD)?,
        theta_p_per_yaw: f64_column(&e, epochs_cols::THETA_P_PER_YAW)?,
        phi_p_per_yaw: f64_column(&e, epochs_cols::PHI_P_PER_YAW)?,
        theta_p_per_bias: f64_column(&e, epochs_cols::THETA_P_PER_BIAS)?,
        phi_p_per_bias: f64_column(&e, epochs_cols::PHI_P_PER_BIAS)?,
        valid: (0..valid.len()).map(|i| valid.value(i)).collect(),
    };
    let n_blocks = d.t_s.len().div_ceil(d.block.max(1));
    if d.epochs.block.iter().any(|&j| j >= n_blocks) {
        bail!("{}: epoch block beyond the samples", epath.display());
    }
    if d.ax_f.len() != n_blocks {
        bail!(
            "{}: {} blocks for {} samples of {} (expected {n_blocks})",
            bpath.display(),
            d.ax_f.len(),
            d.t_s.len(),
            d.block
        );
    }
    Ok(d)
}

/// The filtered acceleration terms at the ΔTg epochs, as `epochs.parquet` holds them
/// beside the references (what the review plots under Kryt1; a load of the derive reads
/// them per block from `blocks.parquet` instead).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EpochTerms {
    /// Filtered forward specific force, m/s².
    pub ax_f_mps2: Vec<f64>,
    /// Filtered lateral specific force, m/s².
    pub ay_f_mps2: Vec<f64>,
    /// Filtered odometer acceleration u̇, m/s².
    pub u_dot_f_mps2: Vec<f64>,
    /// Filtered centripetal term ru, m/s².
    pub ru_f_mps2: Vec<f64>,
}

/// Reads the filtered terms of `epochs.parquet` in `dir`.
pub fn read_epoch_terms(dir: &Path) -> anyhow::Result<EpochTerms> {
    let path = dir.join(files::EPOCHS);
    let (_, e) = read_table(&path)?;
    let column = |name: &str| {
        f64_column(&e, name).with_context(|| format!("cannot read {}", path.display()))
    };
    Ok(EpochTerms {
        ax_f_mps2: column(filtered_cols::AX_F_MPS2)?,
        ay_f_mps2: column(filtered_cols::AY_F_MPS2)?,
        u_dot_f_mps2: column(filtered_cols::U_DOT_F_MPS2)?,
        ru_f_mps2: column(filtered_cols::RU_F_MPS2)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use unz_stages::derive::{DeriveParams, RawSeries, derive};

    /// Ingested columns: IMU times, angle and velocity increments, odometer times and
    /// distances.
    type Columns = (Vec<i64>, Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<i64>, Vec<f64>);

    /// A drive with turns and speed changes, the odometer at its own rate, one time tag
    /// that goes back (repaired by derive), a gap of 4 samples before sample 20 000 and
    /// a saturated accelerometer count at 25 000 (their increments replaced).
    fn raw() -> Columns {
        let n = 30_000;
        let mut t: Vec<i64> = (0..n)
            .map(|k| 1_000_000_000 + k * 10_000_000 + 40_000_000 * i64::from(k >= 20_000))
            .collect();
        t[12_345] = t[12_344] - 1;
        let dtheta = (0..n)
            .map(|k| {
                let s = k as f64 * 0.01;
                [
                    1e-5 * (s * 0.7).sin(),
                    2e-5 * (s * 0.3).cos(),
                    2e-3 * (s * 0.05).sin(),
                ]
            })
            .collect();
        let dvel = (0..n)
            .map(|k| {
                let s = k as f64 * 0.01;
                [0.01 * (s * 0.1).sin(), 0.002 * (s * 0.2).cos(), -0.0981]
            })
            .collect();
        let odo_t: Vec<i64> = (0..n / 10)
            .map(|k| 1_000_000_000 + k * 100_000_000)
            .collect();
        let odo_d = (0..n / 10)
            .map(|k| {
                let s = k as f64 * 0.1;
                8.0 * s + 30.0 * (s * 0.01).sin()
            })
            .collect();
        let mut dvel: Vec<[f64; 3]> = dvel;
        dvel[25_000][1] = 1e3;
        (t, dtheta, dvel, odo_t, odo_d)
    }

    /// Writes the ingest's IMU table of `c` into `dir`, as the ingest stores it.
    fn write_imu(c: &Columns, dir: &Path) {
        let n = c.0.len();
        let table = unz_formats::tables::ImuTable {
            t_ns: c.0.clone(),
            seq: (0..n as u64).collect(),
            dtheta_rad: c.1.clone(),
            dvel_mps: c.2.clone(),
            status: vec![0; n],
        };
        let batch = table.to_batch(schema::imu(None)).unwrap();
        write_batch(&dir.join(files::IMU), &batch).unwrap();
    }

    /// The derive of the ingested columns `c`.
    fn derived_of(c: &Columns) -> Derived {
        let (t, dth, dv, ot, od) = c;
        let series = RawSeries {
            imu_t_ns: t,
            dtheta_rad: dth,
            dvel_mps: dv,
            odo_t_ns: ot.into(),
            odo_distance_m: od,
        };
        derive(&series, &DeriveParams::default(), 9.81)
    }

    /// `c`'s IMU table and its derive `d` stored as the stages store them, in a
    /// temporary folder (kept as long as the first value is).
    fn stored(c: &Columns, d: &Derived) -> (tempfile::TempDir, StoredDerive) {
        let tmp = tempfile::tempdir().unwrap();
        let stored = StoredDerive {
            derive_dir: tmp.path().join("derive"),
            ingest_dir: tmp.path().join("ingest"),
        };
        std::fs::create_dir_all(&stored.derive_dir).unwrap();
        std::fs::create_dir_all(&stored.ingest_dir).unwrap();
        write_imu(c, &stored.ingest_dir);
        write_derived(d, &stored.derive_dir).unwrap();
        (tmp, stored)
    }

    /// The tables of `stored` copied in Arrow's plain encodings (read through Arrow, not
    /// by their byte streams), in a temporary folder.
    fn plain_copy_of(stored: &StoredDerive) -> (tempfile::TempDir, StoredDerive) {
        let tmp = tempfile::tempdir().unwrap();
        let plain = StoredDerive {
            derive_dir: tmp.path().join("derive"),
            ingest_dir: tmp.path().join("ingest"),
        };
        for (from, to) in [
            (&stored.derive_dir, &plain.derive_dir),
            (&stored.ingest_dir, &plain.ingest_dir),
        ] {
            std::fs::create_dir_all(to).unwrap();
            for f in std::fs::read_dir(from).unwrap() {
                let f = f.unwrap().path();
                crate::picked_rows::plain_copy(&f, &to.join(f.file_name().unwrap()));
            }
        }
        (tmp, plain)
    }

    /// A binary log's angle increments (counts of 2⁻²⁶ rad) load in f32, as the derive
    /// held them, read a page at a time into that form; a repaired sample whose increment
    /// is not an f32 (the one after a gap, scaled) turns them to f64 as the derive did.
    /// Bit for bit either way, by byte streams or through Arrow.
    #[test]
    fn a_binary_logs_angle_increments_load_in_the_form_the_derive_held() {
        let lsb = (-26f64).exp2();
        for with_gap in [false, true] {
            let mut columns = raw();
            for v in columns.1.iter_mut().flatten() {
                *v = (*v / lsb).round() * lsb;
            }
            if !with_gap {
                // No gap, and no saturated count: no increment replaced.
                for (k, t) in columns.0.iter_mut().enumerate().skip(20_000) {
                    *t = 1_000_000_000 + k as i64 * 10_000_000;
                }
                columns.2[25_000][1] = columns.2[24_999][1];
            }
            let d = derived_of(&columns);
            assert_eq!(d.dtheta_rad.is_single(), !with_gap, "gap {with_gap}");
            let (_tmp, stored) = stored(&columns, &d);
            let (_plain_tmp, plain) = plain_copy_of(&stored);
            for at in [&stored, &plain] {
                let nav = load_derived_for_navigation(at).unwrap();
                assert_eq!(nav.dtheta_rad.is_single(), !with_gap, "gap {with_gap}");
                let bits = |a: &unz_stages::angle_increments::AngleIncrements| {
                    a.view()
                        .iter()
                        .map(|v| v.map(f64::to_bits))
                        .collect::<Vec<_>>()
                };
                assert!(
                    bits(&nav.dtheta_rad) == bits(&d.dtheta_rad),
                    "gap {with_gap}"
                );
            }
        }
    }

    #[test]
    fn the_derive_loads_back_whole() {
        let columns = raw();
        let (t, dth, dv, ot, od) = &columns;
        let d = derived_of(&columns);
        assert!(d.repaired_times == 1 && !d.u_dot_f.is_empty());
        assert_eq!(d.replaced_increments, [20_000, 25_000]);
        let (_tmp, stored) = stored(&columns, &d);
        // The derive stores its two replaced samples' increments only.
        let (_, repairs) = read_table(&stored.derive_dir.join(files::IMU_REPAIRS)).unwrap();
        assert_eq!(repairs.num_rows(), 2);
        assert_eq!(i64_column(&repairs, T_NS).unwrap(), [t[20_000], t[25_000]]);
        let loaded = load_derived(&stored).unwrap();
        // Every series bit for bit, but the times that are not whole nanoseconds (the
        // repaired sample's, the epochs'): stored in nanoseconds, they come back within
        // half of one.
        let k = 12_345;
        assert!((loaded.t_s.get(k) - d.t_s.get(k)).abs() <= 0.5e-9);
        let mut same_times = loaded.clone();
        same_times.t_s = {
            let mut t = loaded.t_s.to_vec();
            t[k] = d.t_s.get(k);
            t.into()
        };
        assert_eq!(loaded.epochs.t_s.len(), d.epochs.t_s.len());
        for (a, b) in loaded.epochs.t_s.iter().zip(&d.epochs.t_s) {
            assert!((a - b).abs() <= 0.5e-9, "epoch at {b} s loads as {a} s");
        }
        same_times.epochs.t_s.clone_from(&d.epochs.t_s);
        // Not stored: what only a failing derive names.
        assert_eq!(same_times.first_out_of_range, None);
        same_times.first_out_of_range = d.first_out_of_range;
        // Field by field first, so that a failure names the field, not the whole run.
        macro_rules! same {
            ($($f:ident).+) => {
                assert!(same_times.$($f).+ == d.$($f).+, "{} differs", stringify!($($f).+));
            };
        }
        same!(t0_ns);
        same!(nominal_dt_s);
        same!(t_s);
        same!(dt_s);
        same!(dtheta_rad);
        same!(dvel_mps);
        same!(replaced_increments);
        same!(odo_dist_m);
        same!(ax_f);
        same!(ay_f);
        same!(u_dot_f);
        same!(ru_f);
        same!(r_moving_f);
        same!(moving_dot_f);
        same!(block);
        same!(epochs.block);
        same!(epochs.t_s);
        same!(epochs.theta_p_rad);
        same!(epochs.phi_p_rad);
        same!(epochs.theta_p_per_yaw);
        same!(epochs.phi_p_per_yaw);
        same!(epochs.theta_p_per_bias);
        same!(epochs.phi_p_per_bias);
        same!(epochs.valid);
        assert!(same_times == d);
        // The file's u, u̇, ru and r are eqs 9–11 and the yaw rate of the derive.
        let (_, table) = read_table(&stored.derive_dir.join(files::DERIVED)).unwrap();
        let column = |name: &str| f64_column(&table, name).unwrap();
        let n = d.t_s.len();
        let speeds: Vec<_> = d.odometer_speeds(0..n).collect();
        assert_eq!(
            column(derived_cols::U_MPS),
            speeds.iter().map(|s| s.u_mps).collect::<Vec<_>>()
        );
        assert_eq!(
            column(derived_cols::U_DOT_MPS2),
            speeds.iter().map(|s| s.u_dot_mps2).collect::<Vec<_>>()
        );
        assert_eq!(
            column(derived_cols::RU_MPS2),
            speeds.iter().map(|s| s.ru_mps2).collect::<Vec<_>>()
        );
        assert!(speeds.iter().any(|s| s.u_mps > 1.0 && s.ru_mps2 != 0.0));
        // The epochs' filtered terms (what the review reads) are the blocks' at the epochs.
        let terms = read_epoch_terms(&stored.derive_dir).unwrap();
        let at = |v: &[f64]| d.epochs.block.iter().map(|&j| v[j]).collect::<Vec<_>>();
        assert_eq!(terms.ax_f_mps2, at(&d.ax_f));
        assert_eq!(terms.ay_f_mps2, at(&d.ay_f));
        assert_eq!(terms.u_dot_f_mps2, at(&d.u_dot_f));
        assert_eq!(terms.ru_f_mps2, at(&d.ru_f));
        assert!(terms.ax_f_mps2.len() > 10 && terms.ru_f_mps2.iter().any(|&v| v != 0.0));
        // The times-only load is the whole one without the per-sample increments.
        let times = load_derived_times(&stored.derive_dir).unwrap();
        assert!(times.dtheta_rad.is_empty() && times.odo_dist_m.is_empty());
        assert!(
            times
                == Derived {
                    dt_s: Default::default(),
                    dtheta_rad: Default::default(),
                    dvel_mps: Default::default(),
                    replaced_increments: Vec::new(),
                    odo_dist_m: Vec::new(),
                    ..loaded.clone()
                }
        );
        // The navigation load is the whole one without the velocity increments, whose
        // first samples come apart (asking for more than the run gives the run's).
        let nav = load_derived_for_navigation(&stored).unwrap();
        assert!(
            nav == Derived {
                dvel_mps: Default::default(),
                ..loaded.clone()
            }
        );
        // The same tables in Arrow's plain encodings (read through Arrow, not by their
        // byte streams), the same.
        let (_plain_tmp, plain) = plain_copy_of(&stored);
        assert!(load_derived(&plain).unwrap() == loaded);
        assert!(load_derived_for_navigation(&plain).unwrap() == nav);
        for n in [0, 1, 100, 70_000, 1 << 20] {
            let prefix = read_velocity_prefix(&stored, n).unwrap();
            assert_eq!(prefix[..], loaded.dvel_mps[..n.min(loaded.dvel_mps.len())]);
        }
        // So do stretches of them, across batches and repaired samples (one the last of
        // its stretch, one the first); beyond the run, an error.
        let n = loaded.dvel_mps.len();
        let ranges = [0..3, 100..100, 1000..20_001, 25_000..25_010, n - 5..n];
        let stretches = read_velocity_ranges(&stored, &ranges).unwrap();
        for (r, v) in ranges.iter().zip(&stretches) {
            assert_eq!(v[..], loaded.dvel_mps[r.clone()], "{r:?}");
        }
        let beyond = [0..1, n - 5..n + 1];
        assert!(read_velocity_ranges(&stored, &beyond).is_err());
        // The repaired samples' are the derive's, not the ingest's.
        assert_ne!(dv[25_000], loaded.dvel_mps[25_000]);
        assert_eq!(stretches[3][0], d.dvel_mps[25_000]);
        // A derive of another ingest (more rows than it has) is no derive of this one.
        let shorter: Columns = (
            t[..29_000].to_vec(),
            dth[..29_000].to_vec(),
            dv[..29_000].to_vec(),
            ot.clone(),
            od.clone(),
        );
        write_imu(&shorter, &stored.ingest_dir);
        let err = load_derived(&stored).unwrap_err().to_string();
        assert!(err.contains("derive again"), "{err}");
        // What a stage is handed in memory is what it would load, bit for bit.
        assert!(
            as_stored(d) == loaded,
            "as_stored differs from the loaded derive"
        );
    }
}
