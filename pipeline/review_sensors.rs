//! `derive/sensors.parquet`: the derive's per-sample sensor series in the review
//! recording's blocks ([`SensorBlocks`]) and its time base ([`RunTimes`]). The derive
//! stage takes them while it holds the run's increments, so that the review reads a table
//! of one row per block instead of streaming the run's per-sample series again, and no
//! stage keeps the velocity increments in memory for it.

use std::path::Path;
use std::sync::Arc;

use anyhow::Context;
use arrow::array::{Float64Array, Int64Array, RecordBatch};
use unz_formats::parquet_io::{
    ParquetSink, for_each_batch, for_each_batch_of, read_schema, row_capacity_hint,
};
use unz_formats::schema::{self, derived_cols, sensors_cols, sensors_meta};
use unz_formats::split_doubles::{for_each_split_values, read_split_doubles};
use unz_formats::tables::{f64_column, i64_column, vec3_column, vec3_to_array};
use unz_stages::derive::{Derived, ns_since};
use unz_viz::review::{SensorBlocks, SensorBlocksBuilder, SensorSample};

/// The derive's time base as the review reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunTimes {
    /// IMU time of the first sample, ns.
    pub t0_ns: i64,
    /// Nominal sample period, s.
    pub nominal_dt_s: f64,
    /// Time of the last sample since the first, s.
    pub duration_s: f64,
    /// IMU samples.
    pub samples: usize,
}

/// What the review reads of the derive's per-sample series: its sensor blocks and time
/// base (the content of `sensors.parquet`).
#[derive(Debug, Clone, PartialEq)]
pub struct ReviewSensors {
    /// The sensor series in the recording's blocks.
    pub blocks: SensorBlocks,
    /// The derive's time base.
    pub times: RunTimes,
}

/// [`ReviewSensors`] of a whole derive, as it is stored
/// ([`crate::derive_io::as_stored`]), its velocity increments included.
pub fn review_sensors(d: &Derived) -> ReviewSensors {
    let mut b = SensorBlocksBuilder::at_series_rate(d.nominal_dt_s).with_room_for(d.t_s.len());
    for ((k, speed), t_s) in d
        .odometer_speeds(0..d.t_s.len())
        .enumerate()
        .zip(d.t_s.iter())
    {
        b.push(SensorSample {
            t_s,
            dt_s: d.dt_s[k],
            dtheta_rad: d.dtheta_rad.get(k),
            dvel_mps: d.dvel_mps[k],
            u_mps: speed.u_mps,
            u_dot_mps2: speed.u_dot_mps2,
            ru_mps2: speed.ru_mps2,
        });
    }
    ReviewSensors {
        blocks: b.finish(),
        times: RunTimes {
            t0_ns: d.t0_ns,
            nominal_dt_s: d.nominal_dt_s,
            duration_s: d.t_s.last().unwrap_or(0.0),
            samples: d.t_s.len(),
        },
    }
}

/// Writes `s` to `path` (atomically), 65 536 blocks at a time. The blocks' times are
/// stored in whole nanoseconds of the log's time base: those of a stored derive are, so
/// they read back bit for bit.
pub fn write_review_sensors(s: &ReviewSensors, path: &Path) -> anyhow::Result<()> {
    write_in_batches(s, path, 1 << 16)
}

/// [`write_review_sensors`] `rows` blocks at a time.
fn write_in_batches(s: &ReviewSensors, path: &Path, rows: usize) -> anyhow::Result<()> {
    let (b, t) = (&s.blocks, &s.times);
    let schema = schema::sensors([
        (sensors_meta::STEP, b.step.to_string()),
        (sensors_meta::T0_NS, t.t0_ns.to_string()),
        (sensors_meta::NOMINAL_DT_S, t.nominal_dt_s.to_string()),
        (sensors_meta::DURATION_S, t.duration_s.to_string()),
        (sensors_meta::SAMPLES, t.samples.to_string()),
    ]);
    let mut sink = ParquetSink::create(path, schema.clone())?;
    let n = b.t_s.len();
    for lo in (0..n).step_by(rows.max(1)) {
        let r = lo..(lo + rows.max(1)).min(n);
        let f64s = |v: &[f64]| Arc::new(Float64Array::from(v[r.clone()].to_vec()));
        let vec3s = |v: &[Vec<f64>; 3]| {
            let rows: Vec<[f64; 3]> = r.clone().map(|k| [v[0][k], v[1][k], v[2][k]]).collect();
            vec3_to_array(&rows)
        };
        let batch = RecordBatch::try_new(
            schema.clone(),
            vec![
                Arc::new(Int64Array::from_iter_values(
                    b.t_s[r.clone()].iter().map(|&t_s| ns_since(t.t0_ns, t_s)),
                )),
                Arc::new(Int64Array::from(b.sample[r.clone()].to_vec())),
                f64s(&b.u_mps),
                f64s(&b.u_dot_mps2),
                f64s(&b.ru_mps2),
                vec3s(&b.gyro_deg_s),
                vec3s(&b.accel_mps2),
            ],
        )?;
        sink.write(&batch)?;
    }
    sink.finish()?;
    Ok(())
}

/// Reads what [`write_review_sensors`] wrote: the float columns with their byte streams
/// joined ([`read_split_doubles`], [`for_each_split_values`]) where their layout is the
/// tables', else every column through Arrow, batch by batch.
pub fn read_review_sensors(path: &Path) -> anyhow::Result<ReviewSensors> {
    let schema = read_schema(path)?;
    let m = schema.metadata();
    let t0_ns: i64 = meta(m, sensors_meta::T0_NS, path)?;
    let mut blocks = match read_blocks_split(path, t0_ns)? {
        Some(blocks) => blocks,
        None => read_blocks_arrow(path, t0_ns)?,
    };
    blocks.step = meta(m, sensors_meta::STEP, path)?;
    Ok(ReviewSensors {
        blocks,
        times: RunTimes {
            t0_ns,
            nominal_dt_s: meta(m, sensors_meta::NOMINAL_DT_S, path)?,
            duration_s: meta(m, sensors_meta::DURATION_S, path)?,
            samples: meta(m, sensors_meta::SAMPLES, path)?,
        },
    })
}

/// The blocks' times (s since `t0_ns`) and first samples of a batch, appended.
fn extend_times(
    blocks: &mut SensorBlocks,
    batch: &RecordBatch,
    t0_ns: i64,
) -> Result<(), unz_formats::FormatError> {
    blocks.t_s.extend(
        i64_column(batch, schema::T_NS)?
            .iter()
            .map(|&t| (t - t0_ns) as f64 * 1e-9),
    );
    blocks
        .sample
        .extend(i64_column(batch, sensors_cols::SAMPLE)?);
    Ok(())
}

/// [`read_review_sensors`]' blocks through Arrow.
fn read_blocks_arrow(path: &Path, t0_ns: i64) -> anyhow::Result<SensorBlocks> {
    let mut blocks = SensorBlocks::default();
    blocks.reserve_exact(row_capacity_hint(path)?);
    for_each_batch(path, |batch| {
        extend_times(&mut blocks, batch, t0_ns)?;
        blocks.u_mps.extend(f64_column(batch, derived_cols::U_MPS)?);
        blocks
            .u_dot_mps2
            .extend(f64_column(batch, derived_cols::U_DOT_MPS2)?);
        blocks
            .ru_mps2
            .extend(f64_column(batch, derived_cols::RU_MPS2)?);
        for (name, out) in [
            (sensors_cols::GYRO_DEG_S, &mut blocks.gyro_deg_s),
            (sensors_cols::ACCEL_MPS2, &mut blocks.accel_mps2),
        ] {
            for v in vec3_column(batch, name)? {
                for (axis, x) in out.iter_mut().zip(v) {
                    axis.push(x);
                }
            }
        }
        Ok(())
    })?;
    Ok(blocks)
}

/// [`read_review_sensors`]' blocks with the floats' byte streams joined (each page's
/// values straight into their series), the times and samples through Arrow; `None` when
/// a float column is not of the tables' layout.
fn read_blocks_split(path: &Path, t0_ns: i64) -> anyhow::Result<Option<SensorBlocks>> {
    let mut blocks = SensorBlocks::default();
    // Room for the file's rows in the series filled as the pages come.
    let rows = row_capacity_hint(path)?;
    for series in blocks.gyro_deg_s.iter_mut().chain(&mut blocks.accel_mps2) {
        series.reserve_exact(rows);
    }
    blocks.t_s.reserve_exact(rows);
    blocks.sample.reserve_exact(rows);
    for (name, out) in [
        (derived_cols::U_MPS, &mut blocks.u_mps),
        (derived_cols::U_DOT_MPS2, &mut blocks.u_dot_mps2),
        (derived_cols::RU_MPS2, &mut blocks.ru_mps2),
    ] {
        match read_split_doubles(path, name, 1)? {
            Some(v) => *out = v,
            None => return Ok(None),
        }
    }
    // A vector column's values page by page, each row's three to the three axes.
    for (name, out) in [
        (sensors_cols::GYRO_DEG_S, &mut blocks.gyro_deg_s),
        (sensors_cols::ACCEL_MPS2, &mut blocks.accel_mps2),
    ] {
        let leaf = format!("{name}.list.item");
        let whole = for_each_split_values::<f64>(path, &leaf, 3, |first, values| {
            for (i, &v) in values.iter().enumerate() {
                out[(first + i) % 3].push(v);
            }
        })?;
        if !whole {
            return Ok(None);
        }
    }
    for_each_batch_of(path, &[schema::T_NS, sensors_cols::SAMPLE], |batch| {
        extend_times(&mut blocks, batch, t0_ns)
    })?;
    let rows = blocks.t_s.len();
    let lengths: [usize; 9] = [
        blocks.u_mps.len(),
        blocks.u_dot_mps2.len(),
        blocks.ru_mps2.len(),
        blocks.gyro_deg_s[0].len(),
        blocks.gyro_deg_s[1].len(),
        blocks.gyro_deg_s[2].len(),
        blocks.accel_mps2[0].len(),
        blocks.accel_mps2[1].len(),
        blocks.accel_mps2[2].len(),
    ];
    anyhow::ensure!(
        lengths.iter().all(|&n| n == rows),
        "{}: columns of {lengths:?} rows for {rows} times",
        path.display()
    );
    Ok(Some(blocks))
}

/// The schema metadata `key` of `path`, parsed.
fn meta<T: std::str::FromStr>(
    m: &std::collections::HashMap<String, String>,
    key: &str,
    path: &Path,
) -> anyhow::Result<T>
where
    T::Err: std::error::Error + Send + Sync + 'static,
{
    m.get(key)
        .with_context(|| format!("{} lacks metadata {key}", path.display()))?
        .parse()
        .with_context(|| format!("{}: metadata {key}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::artifacts::files;

    /// Every column's values as bits (-0.0 and 0.0 would pass `==`).
    fn bits(b: &SensorBlocks) -> Vec<Vec<u64>> {
        let mut out: Vec<Vec<u64>> = [&b.t_s, &b.u_mps, &b.u_dot_mps2, &b.ru_mps2]
            .into_iter()
            .chain(&b.gyro_deg_s)
            .chain(&b.accel_mps2)
            .map(|v| v.iter().map(|x| x.to_bits()).collect())
            .collect();
        out.push(b.sample.iter().map(|&s| s as u64).collect());
        out
    }

    /// The derive stage's `sensors.parquet` holds the blocks of the derive as it is stored
    /// (read back whole from the derive's and the ingest's files), bit for bit, with its time base; the chain
    /// keeps the derive without the velocity increments.
    #[test]
    fn the_sensor_file_holds_the_blocks_of_the_stored_derive() {
        let tmp = tempfile::tempdir().unwrap();
        let chain = crate::simulate_io::simulated_ctx(tmp.path(), "sensors", 5, 700.0).unwrap();
        let params = crate::flow::Params::default();
        let derive_dir = crate::flow::ensure_derive(&chain, &params).unwrap();
        let kept = chain.kept_derived().expect("the chain's derive");
        assert!(
            kept.dvel_mps.is_empty(),
            "kept without the velocity increments"
        );
        let stored =
            crate::derive_io::load_derived(&crate::derive_io::StoredDerive::of(&chain.layout()))
                .unwrap();
        let want = review_sensors(&stored);
        let got = read_review_sensors(&derive_dir.join(files::SENSORS)).unwrap();
        assert!(
            want.blocks.t_s.len() > 1000,
            "{} blocks",
            want.blocks.t_s.len()
        );
        assert_eq!(got.blocks.step, want.blocks.step);
        assert_eq!(bits(&got.blocks), bits(&want.blocks));
        // Written in several batches (the last one short), it reads back the same.
        let path = tmp.path().join("batches.parquet");
        write_in_batches(&want, &path, 999).unwrap();
        assert_eq!(read_review_sensors(&path).unwrap(), got);
        // Page by page (taken: the tables' layout) and through Arrow, the same blocks.
        let t0 = got.times.t0_ns;
        for file in [derive_dir.join(files::SENSORS), path.clone()] {
            let split = read_blocks_split(&file, t0)
                .unwrap()
                .expect("the tables' layout");
            assert_eq!(bits(&split), bits(&read_blocks_arrow(&file, t0).unwrap()));
            assert_eq!(bits(&split), bits(&got.blocks));
        }
        assert_eq!(got.times.t0_ns, want.times.t0_ns);
        assert_eq!(got.times.samples, want.times.samples);
        assert_eq!(
            got.times.nominal_dt_s.to_bits(),
            want.times.nominal_dt_s.to_bits()
        );
        assert_eq!(
            got.times.duration_s.to_bits(),
            want.times.duration_s.to_bits()
        );
    }
}
