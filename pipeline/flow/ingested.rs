//! What the derive reads of the ingest: its IMU and odometer tables, loaded column by
//! column with room for the file's rows.

use std::path::Path;

use anyhow::bail;
use arrow::array::RecordBatch;
use arrow::datatypes::{UInt16Type, UInt64Type};
use unz_formats::error::FormatError;
use unz_formats::manifest::LogFormat;
use unz_formats::parquet_io::{for_each_batch, for_each_batch_of, row_capacity_hint};
use unz_formats::raw::MAX_TOLERANCE_PERIODS;
use unz_formats::schema;
use unz_formats::schema::DistanceSource;
use unz_formats::split_doubles::{read_split_doubles, read_split_vec3};
use unz_formats::tables::{ImuTable, OdometerTable, f64_column, i64_column, u8_column, values_of};
use unz_stages::derive::{DeriveParams, Derived, IncrementTimes, RawSeries, derive_owned};
use unz_stages::lost_samples::{LostSamples, SeqSteps};
use unz_stages::odo_rebridge::FailedRows;
use unz_stages::time_base::TagTimes;

use crate::artifacts::files;
use crate::ingest::WrittenSeries;

pub(super) fn load_table<T: Default>(
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

/// [`ImuTable::SERIES_COLUMNS`] of `imu.parquet` with the increments' byte streams joined
/// ([`read_split_vec3`]: the columns a page at a time into the run's series, where
/// Arrow's list reader copies them twice over), the times and status through Arrow;
/// `None` when an increment column is not of the tables' layout.
fn load_imu_split(path: &Path) -> anyhow::Result<Option<ImuTable>> {
    let (Some(dtheta_rad), Some(dvel_mps)) = (
        read_split_vec3(path, schema::DTHETA_RAD)?,
        read_split_vec3(path, schema::DVEL_MPS)?,
    ) else {
        return Ok(None);
    };
    let mut imu = ImuTable {
        dtheta_rad,
        dvel_mps,
        ..ImuTable::default()
    };
    imu.t_ns.reserve_exact(imu.dtheta_rad.len());
    imu.status.reserve_exact(imu.dtheta_rad.len());
    for_each_batch_of(path, &[schema::T_NS, schema::STATUS], |b| {
        imu.t_ns.extend(i64_column(b, schema::T_NS)?);
        imu.status
            .extend_from_slice(values_of::<UInt16Type>(b, schema::STATUS)?);
        Ok(())
    })?;
    let rows = imu.t_ns.len();
    anyhow::ensure!(
        imu.dtheta_rad.len() == rows && imu.dvel_mps.len() == rows && imu.status.len() == rows,
        "{}: {} times, {} and {} increments, {} status",
        path.display(),
        rows,
        imu.dtheta_rad.len(),
        imu.dvel_mps.len(),
        imu.status.len()
    );
    Ok(Some(imu))
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
    /// Rows whose distances are not the odometer's readings (its failures, bridged or
    /// held), in order.
    pub failed: Vec<FailedRows>,
}

/// Failed rows of `odometer.parquet` with the time tags of the first and the last.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FailedSpan {
    /// The rows.
    pub rows: FailedRows,
    /// The first row's time tag, ns.
    pub first_t_ns: i64,
    /// The last row's, ns.
    pub last_t_ns: i64,
}

/// Adds the failed rows of a batch of `odometer.parquet`'s `distance_source`, its first
/// row `first_row`, to `failed` (in order; runs of one kind join across batches).
fn extend_failed(
    failed: &mut Vec<FailedRows>,
    first_row: usize,
    b: &RecordBatch,
) -> Result<(), unz_formats::FormatError> {
    for (k, code) in u8_column(b, schema::DISTANCE_SOURCE)?
        .into_iter()
        .enumerate()
    {
        let bridged = match DistanceSource::of_code(code) {
            Some(DistanceSource::Reading) => continue,
            Some(DistanceSource::Bridged) => true,
            // Held, or a code no writer makes: not the odometer's reading.
            _ => false,
        };
        let row = first_row + k;
        match failed.last_mut() {
            Some(f) if f.first + f.len == row && f.bridged == bridged => f.len += 1,
            _ => failed.push(FailedRows {
                first: row,
                len: 1,
                bridged,
            }),
        }
    }
    Ok(())
}

/// The ingested IMU and odometer tables: what derive reads.
pub struct IngestedSeries {
    imu: ImuTable,
    /// How the derive tells the samples that close a stretch of lost ones.
    lost: LostSamples,
    odo: OdometerTable,
}

/// Where an ingested odometer's rows lie against the IMU's log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometerOverlap {
    /// Rows of `odometer.parquet`.
    pub rows: usize,
    /// Rows whose time tags, with the offset configured, fall within the IMU's log.
    pub within: usize,
    /// The odometer's first and last time tags, ns (as written, without the offset).
    pub odometer_span_ns: [i64; 2],
    /// The IMU's, ns.
    pub imu_span_ns: [i64; 2],
}

impl IngestedSeries {
    /// Loads `imu.parquet` and `odometer.parquet` of an ingest folder, a log of `format`:
    /// the columns derive reads (of a binary log's sequence numbers, only where they step
    /// by more than one; not the odometer's pulse counts).
    pub fn load(ingest_dir: &Path, format: LogFormat) -> anyhow::Result<Self> {
        let path = ingest_dir.join(files::IMU);
        let imu = match load_imu_split(&path)? {
            Some(imu) => imu,
            None => load_columns(
                &path,
                &ImuTable::SERIES_COLUMNS,
                ImuTable::with_series_capacity,
                ImuTable::extend_series_from_batch,
            )?,
        };
        let lost = lost_samples(format, || {
            let mut steps = SeqSteps::default();
            for_each_batch_of(&path, &[schema::SEQ], |b| {
                steps.extend(values_of::<UInt64Type>(b, schema::SEQ)?.iter().copied());
                Ok(())
            })?;
            Ok(steps)
        })?;
        Self::checked(imu, lost, Self::load_odometer(ingest_dir)?)
    }

    /// The series an ingest of a log of `format` kept as it wrote them
    /// ([`WrittenSeries`]): what [`Self::load`] reads back from its files, without
    /// decoding them.
    pub fn from_written(written: WrittenSeries, format: LogFormat) -> anyhow::Result<Self> {
        if written.odometer.is_empty() {
            bail!(NO_ODOMETER);
        }
        let lost = lost_samples(format, || Ok(written.seq_steps))?;
        Self::checked(written.imu, lost, written.odometer)
    }

    /// The tables, unless the IMU's is empty.
    fn checked(imu: ImuTable, lost: LostSamples, odo: OdometerTable) -> anyhow::Result<Self> {
        if imu.is_empty() {
            bail!("the raw log has no IMU record");
        }
        Ok(Self { imu, lost, odo })
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
    ///
    /// The distances are read with their byte streams joined ([`read_split_doubles`])
    /// where their layout is the tables', else with the times through Arrow.
    pub fn load_odometer_tags(ingest_dir: &Path) -> anyhow::Result<OdometerTags> {
        let path = ingest_dir.join(files::ODOMETER);
        let rows = row_capacity_hint(&path)?;
        let split = read_split_doubles(&path, schema::DISTANCE_M, 1)?;
        let by_arrow = split.is_none();
        let mut odo = OdometerTags {
            t_ns: TagTimes::with_room_for(rows),
            distance_m: split.unwrap_or_else(|| Vec::with_capacity(rows)),
            failed: Vec::new(),
        };
        let columns: &[&str] = if by_arrow {
            &[schema::T_NS, schema::DISTANCE_M, schema::DISTANCE_SOURCE]
        } else {
            &[schema::T_NS, schema::DISTANCE_SOURCE]
        };
        let mut read = 0;
        for_each_batch_of(&path, columns, |b| {
            odo.t_ns.extend(i64_column(b, schema::T_NS)?);
            if by_arrow {
                odo.distance_m.extend(f64_column(b, schema::DISTANCE_M)?);
            }
            extend_failed(&mut odo.failed, read, b)?;
            read += b.num_rows();
            Ok(())
        })?;
        anyhow::ensure!(
            odo.distance_m.len() == read,
            "{}: {} distances for {read} times",
            path.display(),
            odo.distance_m.len()
        );
        if odo.distance_m.is_empty() {
            bail!(NO_ODOMETER);
        }
        Ok(odo)
    }

    /// The rows of `odometer.parquet` of an ingest folder whose distances are not the
    /// odometer's readings, with the time tags of each span's first and last row, and
    /// the table's rows (its `distance_source` and `t_ns` columns: what the review shows).
    pub fn load_failed_rows(ingest_dir: &Path) -> anyhow::Result<(Vec<FailedSpan>, usize)> {
        let mut failed = Vec::new();
        let mut times: Vec<[i64; 2]> = Vec::new();
        let mut rows = 0;
        let path = ingest_dir.join(files::ODOMETER);
        for_each_batch_of(&path, &[schema::T_NS, schema::DISTANCE_SOURCE], |b| {
            extend_failed(&mut failed, rows, b)?;
            let t_ns = i64_column(b, schema::T_NS)?;
            let batch = rows..rows + t_ns.len();
            // Spans not wholly before this batch: those begun in it, and the last one
            // (which may have begun in an earlier batch and end in this one).
            let from = times.len().saturating_sub(1);
            times.resize(failed.len(), [0; 2]);
            for (f, t) in failed[from..].iter().zip(&mut times[from..]) {
                if batch.contains(&f.first) {
                    t[0] = t_ns[f.first - rows];
                }
                let last = f.first + f.len - 1;
                if batch.contains(&last) {
                    t[1] = t_ns[last - rows];
                }
            }
            rows = batch.end;
            Ok(())
        })?;
        let spans = failed
            .into_iter()
            .zip(times)
            .map(|(rows, [first_t_ns, last_t_ns])| FailedSpan {
                rows,
                first_t_ns,
                last_t_ns,
            })
            .collect();
        Ok((spans, rows))
    }

    /// Where the odometer's rows lie against the IMU's log, their time tags moved by
    /// `offset_s` (the derive's `odo_time_offset_s`).
    pub fn odometer_overlap(&self, offset_s: f64) -> OdometerOverlap {
        let span =
            |t: &[i64]| [t.first().copied(), t.last().copied()].map(Option::unwrap_or_default);
        let imu_span_ns = span(&self.imu.t_ns);
        let offset_ns = (offset_s * 1e9).round() as i64;
        let within = (self.odo.t_ns.iter())
            .filter(|&&t| (imu_span_ns[0]..=imu_span_ns[1]).contains(&t.saturating_add(offset_ns)))
            .count();
        OdometerOverlap {
            rows: self.odo.t_ns.len(),
            within,
            odometer_span_ns: span(&self.odo.t_ns),
            imu_span_ns,
        }
    }

    /// Samples whose status flags an IMU built-in-test failure (bit 0) and an odometer
    /// failure (bit 1).
    pub fn failure_counts(&self) -> (usize, usize) {
        let count = |bit: u16| self.imu.status.iter().filter(|s| *s & bit != 0).count();
        (count(1), count(2))
    }

    /// Derives the run, the IMU's increments repaired in place and its time tags made its
    /// times in place (no copy of the run's length): [`derive_owned`]. The odometer's
    /// table goes once its increments are taken, before the samples' intervals are made.
    /// A binary log's samples that close a stretch of lost ones are told by its `seq`
    /// (a tag late within the recorder's jitter is none), a text log's by the tags'
    /// intervals ([`LostSamples`]).
    pub fn derive(self, params: &DeriveParams, g_mps2: f64) -> Derived {
        // The status flags are counted already (failure_counts), and what the derive reads
        // of the sequence numbers is in `lost`: they go now.
        let ImuTable {
            t_ns,
            seq,
            dtheta_rad,
            dvel_mps,
            status,
        } = self.imu;
        drop((seq, status));
        let (lost, odo) = (self.lost, self.odo);
        let increments = move |at: IncrementTimes<'_>| {
            at.of(&RawSeries {
                imu_t_ns: &[],
                dtheta_rad: &[],
                dvel_mps: &[],
                odo_t_ns: (&odo.t_ns).into(),
                odo_distance_m: &odo.distance_m,
            })
        };
        derive_owned(
            t_ns.into(),
            dtheta_rad,
            dvel_mps,
            increments,
            &lost,
            params,
            g_mps2,
        )
    }
}

/// The longest interval, in periods, between two tags the reader's clock kept one `seq`
/// apart: each within [`MAX_TOLERANCE_PERIODS`] of its `seq`'s time.
const ONE_STEP_PERIODS_KEPT: f64 = (1 + 2 * MAX_TOLERANCE_PERIODS) as f64;

/// The longest interval, in periods, between two lines of a text log a slot apart
/// (`unz_formats::slot_clock`): under two, each within half a period of its slot on a
/// clock that follows them; beyond, only a line the derive moves (a first or last line
/// apart, a tag going back) or a clock taken afresh, which its interval tells.
const ONE_SLOT_PERIODS_KEPT: f64 = 2.0;

/// The rule a log of `format` tells its lost samples by: its `seq` (its steps over one
/// from `seq_steps`): a binary log's recorder's, a text log's slots.
fn lost_samples(
    format: LogFormat,
    seq_steps: impl FnOnce() -> anyhow::Result<SeqSteps>,
) -> anyhow::Result<LostSamples> {
    let longest_one_step_periods = match format {
        LogFormat::UnzBinary => ONE_STEP_PERIODS_KEPT,
        LogFormat::KfGins => ONE_SLOT_PERIODS_KEPT,
    };
    Ok(LostSamples::BySeq {
        steps: seq_steps()?.finish(),
        longest_one_step_periods,
    })
}

/// The first row of the ingest's `imu.parquet` (in `ingest_dir`) that `first` finds in a
/// batch of its `columns` (given with the batch's first row): read a batch at a time,
/// never the table whole, since only a run that fails asks. `None` without one, or when
/// the file cannot be read.
fn first_imu_row(
    ingest_dir: &Path,
    columns: &[&str],
    mut first: impl FnMut(&RecordBatch, usize) -> Result<Option<usize>, FormatError>,
) -> Option<usize> {
    let (mut found, mut row) = (None, 0);
    for_each_batch_of(&ingest_dir.join(files::IMU), columns, |b| {
        if found.is_none() {
            found = first(b, row)?;
        }
        row += b.num_rows();
        Ok(())
    })
    .ok()?;
    found
}

/// The first IMU sample of an ingest whose status flags an odometer failure (bit 1).
pub fn first_odometer_flagged(ingest_dir: &Path) -> Option<usize> {
    first_imu_row(ingest_dir, &[schema::STATUS], |b, row| {
        let status = values_of::<UInt16Type>(b, schema::STATUS)?;
        Ok(status.iter().position(|s| s & 2 != 0).map(|i| row + i))
    })
}

/// The first IMU sample of an ingest whose time tag the derive repairs
/// ([`first_time_not_increasing`]), its tags read alone; `nominal_s` is the derive's
/// nominal interval.
pub fn first_time_tag_not_increasing(ingest_dir: &Path, nominal_s: f64) -> Option<usize> {
    let mut t_ns = Vec::new();
    for_each_batch_of(&ingest_dir.join(files::IMU), &[schema::T_NS], |b| {
        t_ns.extend_from_slice(values_of::<arrow::datatypes::Int64Type>(b, schema::T_NS)?);
        Ok(())
    })
    .ok()?;
    first_time_not_increasing(&t_ns, nominal_s)
}

/// The first of time tags `t_ns` the derive repairs, by its own rule
/// ([`unz_stages::derive::repaired_time`], with its nominal interval `nominal_s`): the
/// first not after the one before, or one that leapt forward alone.
pub fn first_time_not_increasing(t_ns: &[i64], nominal_s: f64) -> Option<usize> {
    let t0 = *t_ns.first()?;
    let t_s = |k: usize| unz_stages::derive::seconds_since(t0, t_ns[k]);
    let mut prev_t_s = -nominal_s;
    for k in 0..t_ns.len() {
        let next_t_s = || (k + 1 < t_ns.len()).then(|| t_s(k + 1));
        if unz_stages::derive::repaired_time(k, prev_t_s, t_s(k), next_t_s, nominal_s).is_some() {
            return Some(k);
        }
        prev_t_s = t_s(k);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use unz_formats::parquet_io::write_batch;

    /// The first tag the derive repairs: the first not after the one before it, a tag
    /// going back or standing still; none in a log whose time advances.
    #[test]
    fn the_first_time_tag_not_increasing_is_found() {
        let mut t: Vec<i64> = (0..20_000)
            .map(|k| 5_000_000_000 + k * 10_000_000)
            .collect();
        assert_eq!(first_time_not_increasing(&t, 0.01), None);
        t[17_000] = t[16_999] - 1;
        t[18_000] = t[17_999];
        assert_eq!(first_time_not_increasing(&t, 0.01), Some(17_000));
        t[12_000] = t[11_999];
        assert_eq!(first_time_not_increasing(&t, 0.01), Some(12_000));
        assert_eq!(first_time_not_increasing(&[], 0.01), None);
    }

    /// Tags beyond an i64 of nanoseconds from the first are held at its bound, as the
    /// derive holds them: they stand still there, and the first after the one that
    /// reached it is repaired (wrapped, the one that reached it would go back).
    #[test]
    fn tags_beyond_an_i64_of_nanoseconds_from_the_first_are_held_at_its_bound() {
        let t = [-7e18 as i64, 9e18 as i64, 9e18 as i64 + 10_000_000];
        assert_eq!(first_time_not_increasing(&t, 0.01), Some(2));
    }

    /// An ingested IMU table read with its increments' byte streams joined is the one
    /// Arrow reads, bit for bit (a run over several of the reader's batches); a table of
    /// another layout goes through Arrow.
    #[test]
    fn the_imu_read_page_by_page_is_arrows() {
        let tmp = tempfile::tempdir().unwrap();
        let ctx = crate::simulate_io::simulated_ctx(tmp.path(), "imu", 9, 900.0).unwrap();
        let dir = crate::flow::ensure_ingest(&ctx, &crate::flow::Params::default()).unwrap();
        let path = dir.join(files::IMU);
        let arrow = load_columns(
            &path,
            &ImuTable::SERIES_COLUMNS,
            ImuTable::with_series_capacity,
            ImuTable::extend_series_from_batch,
        )
        .unwrap();
        assert_eq!(arrow.t_ns.len(), 90_000);
        let split = load_imu_split(&path).unwrap().expect("the tables' layout");
        let bits = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(split.t_ns, arrow.t_ns);
        assert_eq!(split.status, arrow.status);
        assert_eq!(bits(&split.dtheta_rad), bits(&arrow.dtheta_rad));
        assert_eq!(bits(&split.dvel_mps), bits(&arrow.dvel_mps));
        assert!(split.seq.is_empty() && arrow.seq.is_empty());
        // The same rows in Arrow's plain encodings.
        let plain = tmp.path().join("plain.parquet");
        crate::picked_rows::plain_copy(&path, &plain);
        assert!(load_imu_split(&plain).unwrap().is_none());
    }

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
            // Failed rows: bridged from 20 000 for 3 000, held from 23 000 for 1 000 (and
            // a code no writer makes after them), bridged again from 140 000 to the end.
            source: (0..t_ns.len())
                .map(|k| match k {
                    20_000..23_000 | 140_000.. => 1,
                    23_000..24_000 => 2,
                    24_000 => 9,
                    _ => 0,
                })
                .collect(),
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
        assert_eq!(plain.distance_m, table.distance_m);
        assert_eq!(plain.t_ns, table.t_ns);
        // The same table in Arrow's plain encodings: the distances through Arrow, alike.
        let plain_dir = tempfile::tempdir().unwrap();
        crate::picked_rows::plain_copy(&path, &plain_dir.path().join(files::ODOMETER));
        assert_eq!(
            IngestedSeries::load_odometer_tags(plain_dir.path()).unwrap(),
            tags
        );
        let failed = |first, len, bridged| FailedRows {
            first,
            len,
            bridged,
        };
        assert_eq!(
            tags.failed,
            [
                failed(20_000, 3000, true),
                failed(23_000, 1001, false),
                failed(140_000, 10_000, true)
            ]
        );
        // The review's reading: the same spans, each with its first and last row's tags
        // (the last span ends in a later batch than it begins).
        let (spans, rows) = IngestedSeries::load_failed_rows(dir.path()).unwrap();
        assert_eq!(rows, table.t_ns.len());
        assert_eq!(
            spans.iter().map(|s| s.rows).collect::<Vec<_>>(),
            tags.failed
        );
        for s in &spans {
            let last = s.rows.first + s.rows.len - 1;
            assert_eq!(
                (s.first_t_ns, s.last_t_ns),
                (table.t_ns[s.rows.first], table.t_ns[last]),
                "{s:?}"
            );
        }

        let empty = OdometerTable::default();
        write_batch(&path, &empty.to_batch(schema::odometer(None)).unwrap()).unwrap();
        let err = IngestedSeries::load_odometer_tags(dir.path())
            .unwrap_err()
            .to_string();
        assert!(err.contains("no odometer data"), "{err}");
    }
}
