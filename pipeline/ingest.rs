//! Stage 1, ingest: a run's raw log → `imu.parquet`, `odometer.parquet`, `marks.parquet`
//! (zstd), `raw.mcap` (ROS 2 messages for Foxglove and Rerun) and `ingest.json` (the accounting of
//! §1.4 of the raw-format spec), plus `ingest_events.json` locating the first faults.
//!
//! The log is streamed: memory is bounded by the reader's buffer, one batch of rows and
//! the samples an odometer failure holds back until it is bridged (at most 100 000;
//! `crate::odometer_bridge`), or for a text log the readings and the IMU's samples around
//! its odometer file's gaps (`crate::odometer_gaps`) or, with an 8th column, the IMU's
//! samples over the last 141 s and the readings a stand may still replace
//! (`crate::odometer_column`), whatever the file size. Bad records
//! never stop the stage; an unreadable file does, with an error naming it.

use std::io::BufReader;
use std::path::{Path, PathBuf};

use crate::artifacts::files;
use crate::file_hashes::HashingRead;
use crate::flow::site_gravity_mps2;
use crate::odometer_bridge::{Given, OdometerBridger, OdometerSample};
use crate::odometer_column::ColumnBridger;
use crate::odometer_gaps::{GapBridger, file_readings, find_gaps, tag_ns};
use crate::odometer_range::OdometerRange;
use crate::raw_mcap::RawMcapWriter;
use anyhow::Context;
use arrow::array::RecordBatch;
use serde::Serialize;
use unz_formats::atomic::write_json_atomic;
use unz_formats::error::FileError;
use unz_formats::kfgins::{KfGinsReader, LAND_SPEED_RANGE_MPS, OdometerFileReader, TextSample};
use unz_formats::manifest::{LogFormat, OdometerKind, RunManifest};
use unz_formats::mcap_io::McapCompression;
use unz_formats::parquet_io::ParquetSink;
use unz_formats::parquet_thread::ParquetThread;
use unz_formats::raw::{Accepted, IMU_PAYLOAD_LEN, RawReader, frame_len};
use unz_formats::schema::DistanceSource;
use unz_formats::speed_floor::{SpeedFloor, SpeedFloorReport};
use unz_formats::speed_spikes::{SpeedSpikes, Verdict};
use unz_formats::tables::{ImuTable, MarksTable, OdometerTable};
use unz_formats::{IngestEvents, IngestReport, TextClockStep, schema};
use unz_stages::imu_axes::ImuAxes;
use unz_stages::imu_mounting;
use unz_stages::lost_samples::SeqSteps;

/// The most control-point marks a binary log may hold (a 12-hour run marking a point a
/// minute holds 720): a log with more fails its run. Each is held in order among the
/// samples while a standing odometer count is judged: a damaged log of a million marks in
/// a row took the ingest to 310 MB, and more would take any memory.
const MAX_MARKS: u64 = 100_000;

/// Rows per Parquet batch.
const BATCH_ROWS: usize = 1 << 16;

/// The most samples the ingest makes room for before reading a raw log (8.4 M: 23 hours
/// at 100 Hz); a longer log's columns grow as they fill. A file's size is no promise of
/// its samples: a sparse raw log of 64 GiB (holes read as zeros) asked for 34 GB for one
/// column, which the kernel refused, and the process aborted with every run of its
/// campaign.
const ROWS_HINT_MAX: usize = 1 << 23;

/// Room for as many samples as a raw log of `file_len` bytes can hold (its length, not a
/// field of it: no more than the file's size says), up to [`ROWS_HINT_MAX`].
fn rows_hint(file_len: u64) -> usize {
    let rows = usize::try_from(file_len).unwrap_or(usize::MAX) / frame_len(IMU_PAYLOAD_LEN);
    rows.min(ROWS_HINT_MAX)
}

/// Output files of the ingest stage.
pub const OUTPUTS: [&str; 6] = [
    files::IMU,
    files::ODOMETER,
    files::MARKS,
    files::RAW_MCAP,
    files::INGEST_REPORT,
    files::INGEST_EVENTS,
];

/// What the stage did.
#[derive(Debug, Clone)]
pub struct IngestOutcome {
    /// Output folder.
    pub dir: PathBuf,
    /// The accounting.
    pub report: IngestReport,
    /// Odometer rows written.
    pub odometer_rows: usize,
    /// The tables' series as written, when [`IngestOptions::keep_series`] asked for them.
    pub series: Option<WrittenSeries>,
}

/// The columns of `imu.parquet` and `odometer.parquet` a derive reads
/// ([`ImuTable::SERIES_COLUMNS`], [`OdometerTable::SERIES_COLUMNS`]), as written: what
/// reading them back gives, bit for bit, without the files' decoding.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WrittenSeries {
    /// The IMU's series (`seq` left empty).
    pub imu: ImuTable,
    /// Where the IMU's `seq` stepped by more than one (what the derive reads of it).
    pub seq_steps: SeqSteps,
    /// The odometer's series (`pulses` and `source` left empty).
    pub odometer: OdometerTable,
}

impl WrittenSeries {
    /// Empty, with room for `rows` rows of each table: kept whole beside the ingest's
    /// buffers, the series are allocated once instead of grown in steps among them.
    fn with_room_for(rows: usize) -> Self {
        Self {
            imu: ImuTable::with_series_capacity(rows),
            seq_steps: SeqSteps::default(),
            odometer: OdometerTable::with_series_capacity(rows),
        }
    }

    /// Appends the series columns of IMU rows about to be written.
    fn extend_imu(&mut self, rows: &ImuTable) {
        self.imu.t_ns.extend_from_slice(&rows.t_ns);
        self.imu.dtheta_rad.extend_from_slice(&rows.dtheta_rad);
        self.imu.dvel_mps.extend_from_slice(&rows.dvel_mps);
        self.imu.status.extend_from_slice(&rows.status);
        self.seq_steps.extend(rows.seq.iter().copied());
    }

    /// Appends the series columns of odometer rows about to be written.
    fn extend_odometer(&mut self, rows: &OdometerTable) {
        self.odometer.t_ns.extend_from_slice(&rows.t_ns);
        self.odometer.distance_m.extend_from_slice(&rows.distance_m);
    }
}

/// Parameters of the ingest stage (`[ingest]` in a config file or a run's `[params]`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IngestParams {
    /// Compression of `raw.mcap`'s chunks: `none` (default, the fastest ingest), `lz4`
    /// (two thirds of the size) or `zstd` (about half).
    pub raw_mcap_compression: McapCompression,
}

/// Options of one ingest.
#[derive(Debug, Clone, Copy)]
pub struct IngestOptions {
    /// Write `raw.mcap` too, compressed so.
    pub mcap: Option<McapCompression>,
    /// The odometer's lag as configured, s (the derive's `odo_time_offset_s`, negated):
    /// an odometer failure's bridge searches its lag about it.
    pub odo_lag_prior_s: f64,
    /// The log's IMU axes on the vehicle (`[vehicle] imu_axes`): each sample's
    /// increments are turned into the body's FRD as they are read, before anything
    /// (the odometer's judgements among them) looks at them.
    pub imu_axes: ImuAxes,
    /// The IMU's mounting beyond those axes (`[vehicle] imu_mounting_deg`): the turn
    /// from them into the body's, after the axes' ([`unz_stages::imu_mounting`]); None
    /// for none.
    pub imu_mounting: Option<nalgebra::Rotation3<f64>>,
    /// Keep the series a derive reads in memory as they are written
    /// ([`IngestOutcome::series`]): for a derive that follows in the same process.
    pub keep_series: bool,
    /// The longest gap a run bridges, s (the derive's `max_gap_s`): a text log's first or
    /// last line apart from the others across a longer interval is reported so, not as
    /// lost samples ([`IngestReport::first_line_apart_s`]).
    pub max_gap_s: f64,
}

/// The status bit of an odometer failure (the raw-format spec's §1.2).
const STATUS_ODOMETER_FAILED: u16 = 1 << 1;

/// A binary log's row, held while the odometer's failure around it is bridged.
enum Row {
    Imu {
        t_ns: i64,
        seq: u64,
        dtheta_rad: [f64; 3],
        dvel_mps: [f64; 3],
        status: u16,
        pulses: i64,
    },
    Mark {
        t_ns: i64,
        point_id: u32,
    },
}

/// A table's Parquet file, encoded on the reading thread or on a thread of its own.
enum TableSink {
    Here(Box<ParquetSink>),
    Thread(ParquetThread),
}

impl TableSink {
    fn write(&mut self, batch: RecordBatch) -> Result<(), FileError> {
        match self {
            TableSink::Here(s) => s.write(&batch),
            TableSink::Thread(s) => s.write(batch),
        }
    }

    fn rows(&self) -> usize {
        match self {
            TableSink::Here(s) => s.rows(),
            TableSink::Thread(s) => s.rows(),
        }
    }

    fn finish(self) -> Result<(), FileError> {
        match self {
            TableSink::Here(s) => s.finish(),
            TableSink::Thread(s) => s.finish(),
        }
    }
}

/// Table sinks of one ingest.
struct Sinks {
    imu: TableSink,
    odo: TableSink,
    imu_rows: ImuTable,
    odo_rows: OdometerTable,
    marks: MarksTable,
    imu_schema: arrow::datatypes::SchemaRef,
    odo_schema: arrow::datatypes::SchemaRef,
    marks_schema: arrow::datatypes::SchemaRef,
    mcap: Option<RawMcapWriter>,
    /// The odometer's steps against a land vehicle's speed.
    odo_range: OdometerRange,
    /// The series written so far, when kept.
    kept: Option<WrittenSeries>,
}

impl Sinks {
    fn create(
        dir: &Path,
        origin_ns: Option<i64>,
        odo_m_per_pulse: Option<f64>,
        options: &IngestOptions,
        rows_hint: usize,
    ) -> anyhow::Result<Self> {
        let mcap = options.mcap;
        let imu_schema = schema::imu(origin_ns);
        let odo_schema = schema::odometer_scaled(origin_ns, odo_m_per_pulse);
        // With `raw.mcap` on its own thread, each table's columns are encoded on a thread
        // of its own while the reading goes on; with `raw.mcap`'s chunks compressed
        // (its thread the busier), the IMU table's on the reading thread. Session 70,
        // uncompressed: the reading thread 1 200 profile samples a pass against 390 for
        // the MCAP writer and 160 for the odometer's table; the IMU table on a thread of
        // its own took the full ingest to a median 141 MB/s against 121.5 (30
        // alternations) and the 12-hour ingest stage to 1.48 s against 1.84 (medians of
        // five). Session 36, on another host and before the CRC's and the hashing's
        // changes, had found the opposite: 161 MB/s with it on the reading thread, 151 on
        // its own. Spread over the pool batch by batch, the tables contended with the MCAP
        // writer. Without `raw.mcap`, side by side.
        let imu = ParquetSink::create(&dir.join(files::IMU), imu_schema.clone())?;
        let odo = ParquetSink::create(&dir.join(files::ODOMETER), odo_schema.clone())?;
        let on_a_thread = |sink: ParquetSink, name: &str| -> anyhow::Result<TableSink> {
            Ok(TableSink::Thread(ParquetThread::spawn(
                sink.on_this_thread(),
                name,
            )?))
        };
        let (imu, odo) = match mcap {
            Some(McapCompression::None) => (
                on_a_thread(imu, "imu.parquet")?,
                on_a_thread(odo, "odometer.parquet")?,
            ),
            Some(_) => (
                TableSink::Here(Box::new(imu.on_this_thread())),
                on_a_thread(odo, "odometer.parquet")?,
            ),
            None => (
                TableSink::Here(Box::new(imu)),
                TableSink::Here(Box::new(odo)),
            ),
        };
        Ok(Self {
            imu,
            odo,
            // A batch's rows, taken with room for the next ([`ImuTable::take_batch`]).
            imu_rows: ImuTable::with_room(BATCH_ROWS.min(rows_hint)),
            odo_rows: OdometerTable::with_room(BATCH_ROWS.min(rows_hint)),
            marks: MarksTable::default(),
            imu_schema,
            odo_schema,
            marks_schema: schema::marks(origin_ns),
            mcap: match mcap {
                Some(compression) => Some(RawMcapWriter::create(
                    &dir.join(files::RAW_MCAP),
                    origin_ns.unwrap_or(0),
                    compression,
                )?),
                None => None,
            },
            odo_range: OdometerRange::default(),
            kept: options
                .keep_series
                .then(|| WrittenSeries::with_room_for(rows_hint)),
        })
    }

    /// Hands each table's rows to its writer once they fill a batch (whatever they
    /// hold, when `force`). Asked after every record: the common answer, nothing due, is
    /// taken inline (the call was 11 M of a 40-minute ingest's 358 M instructions on the
    /// reading thread).
    #[inline]
    fn flush(&mut self, force: bool) -> anyhow::Result<()> {
        if force || self.imu_rows.len() >= BATCH_ROWS || self.odo_rows.len() >= BATCH_ROWS {
            self.write_batches(force)
        } else {
            Ok(())
        }
    }

    /// Writes the batches [`Self::flush`] found due: each table's rows once they fill a
    /// batch, or whatever they hold when `force`.
    #[inline(never)]
    fn write_batches(&mut self, force: bool) -> anyhow::Result<()> {
        let due = |rows: usize| rows > 0 && (force || rows >= BATCH_ROWS);
        if due(self.imu_rows.len()) {
            if let Some(kept) = &mut self.kept {
                kept.extend_imu(&self.imu_rows);
            }
            self.imu
                .write(self.imu_rows.take_batch(self.imu_schema.clone())?)?;
        }
        if due(self.odo_rows.len()) {
            if let Some(kept) = &mut self.kept {
                kept.extend_odometer(&self.odo_rows);
            }
            self.odo
                .write(self.odo_rows.take_batch(self.odo_schema.clone())?)?;
        }
        Ok(())
    }

    /// Appends an odometer sample whose distance is the route's, from `source`.
    fn push_odometer(&mut self, t_ns: i64, (distance_m, source): Given, pulses: Option<i64>) {
        self.odo_rows.t_ns.push(t_ns);
        self.odo_rows.distance_m.push(distance_m);
        self.odo_rows.pulses.push(pulses);
        self.odo_rows.source.push(source as u8);
        if let Some(m) = &mut self.mcap {
            m.odometer(t_ns, distance_m);
        }
    }

    /// Appends a row of a binary log, an IMU sample with the route's distance.
    fn give(&mut self, row: Row, distance: Option<Given>, nominal_dt_s: f64) {
        match row {
            Row::Imu {
                t_ns,
                seq,
                dtheta_rad,
                dvel_mps,
                status,
                pulses,
            } => {
                let rows = &mut self.imu_rows;
                rows.t_ns.push(t_ns);
                rows.seq.push(seq);
                rows.dtheta_rad.push(dtheta_rad);
                rows.dvel_mps.push(dvel_mps);
                rows.status.push(status);
                if let Some(m) = &mut self.mcap {
                    m.imu(t_ns, nominal_dt_s, seq, dtheta_rad, dvel_mps, status);
                }
                // Every IMU sample is given its distance.
                let held = (f64::NAN, DistanceSource::Held);
                self.push_odometer(t_ns, distance.unwrap_or(held), Some(pulses));
            }
            Row::Mark { t_ns, point_id } => {
                self.marks.t_ns.push(t_ns);
                self.marks.point_id.push(point_id);
                if let Some(mc) = &mut self.mcap {
                    mc.mark(t_ns, point_id);
                }
            }
        }
    }

    /// Writes the marks and closes every file (renaming them into place); returns the
    /// odometer's rows, its range check (the steps replaced for their speed, the first's
    /// time), and the series kept.
    fn finish(
        mut self,
        dir: &Path,
    ) -> anyhow::Result<(usize, OdometerRange, Option<WrittenSeries>)> {
        self.flush(true)?;
        let odo_rows = self.odo.rows();
        self.imu.finish()?;
        self.odo.finish()?;
        unz_formats::parquet_io::write_batch(
            &dir.join(files::MARKS),
            &self.marks.to_batch(self.marks_schema.clone())?,
        )?;
        if let Some(m) = self.mcap {
            m.finish()?;
        }
        Ok((odo_rows, self.odo_range, self.kept))
    }
}

/// Ingests the run described by `manifest` into `dir`.
pub fn ingest(
    manifest: &RunManifest,
    dir: &Path,
    options: IngestOptions,
) -> anyhow::Result<IngestOutcome> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let Streamed {
        report,
        events,
        odometer_rows,
        odometer_range,
        odometer_file,
        series,
    } = match manifest.format {
        LogFormat::UnzBinary => ingest_binary(manifest, dir, options)?,
        LogFormat::KfGins => {
            let streamed = ingest_text(manifest, dir, options, &[])?;
            match steps_to_follow(manifest, &streamed.report) {
                // Read again, its odometer file's gaps and stands found on the log's clock
                // at its start too: the file's account and the bridges' IMU samples on
                // one clock.
                Some(steps) => ingest_text(manifest, dir, options, &steps)?,
                None => streamed,
            }
        }
    };
    // The account of the first faults is written even for a log that fails below: its
    // messages point to it.
    let events_path = dir.join(files::INGEST_EVENTS);
    write_json_atomic(&events_path, &events)?;
    if report.imu_accepted == 0 {
        anyhow::bail!(no_imu_sample(manifest, &report, &events, &events_path));
    }
    if odometer_rows == 0 {
        let file = odometer_file.as_deref();
        anyhow::bail!(no_odometer_reading(manifest, file, &events, &events_path));
    }
    // A few corrupt odometer steps are replaced and counted; many are a broken odometer.
    if report.odometer_out_of_range * 100 > odometer_rows as u64 {
        anyhow::bail!(
            "{} of {} odometer steps are beyond a land vehicle's speed ({} m/s): corrupt \
             counts or readings{}",
            report.odometer_out_of_range,
            odometer_rows,
            LAND_SPEED_RANGE_MPS,
            (odometer_range.first_ns).map_or_else(String::new, |t_ns| {
                let place = odometer_place(manifest, odometer_file.as_deref(), t_ns);
                format!(" (the first {place})")
            })
        );
    }
    write_json_atomic(&dir.join(files::INGEST_REPORT), &report)?;
    Ok(IngestOutcome {
        dir: dir.to_path_buf(),
        report,
        odometer_rows,
        series,
    })
}

/// Why a log gave no IMU sample, from its account and first faults (`events`, written to
/// `events_path`): a text log's first line rejected and why, or a binary log's records
/// read and bytes skipped.
fn no_imu_sample(
    manifest: &RunManifest,
    report: &IngestReport,
    events: &IngestEvents,
    events_path: &Path,
) -> String {
    let log = manifest.named(&manifest.raw).display();
    let listed = format!("{} lists the first faults", events_path.display());
    match manifest.format {
        LogFormat::KfGins => match events.line_faults.first() {
            Some(first) => format!(
                "{log} has no IMU sample (lines rejected: {}; the first, line {}: {}); \
                     {listed}",
                report.rejected.malformed_line.unwrap_or(0),
                first.line,
                first.reason
            ),
            None => format!(
                "{log} has no IMU sample: it holds no record line (empty, or blank and \
                     comment lines alone)"
            ),
        },
        LogFormat::UnzBinary => format!(
            "{log} has no IMU record after its header: {} records read, {} rejected, {} bytes \
             skipped while resynchronising; {listed}",
            report.records_read,
            report.rejected_total(),
            report.bytes_skipped
        ),
    }
}

/// Why a text log's run has no odometer reading: its odometer file's lines all rejected
/// (the first and why, from `events`, written to `events_path`) or none in it, or neither
/// an 8th column nor a file.
fn no_odometer_reading(
    manifest: &RunManifest,
    file: Option<&Path>,
    events: &IngestEvents,
    events_path: &Path,
) -> String {
    let Some(file) = file else {
        return format!(
            "the run has no odometer data: {} has no 8th column (the speed) and the manifest \
             names no [odometer] file",
            manifest.named(&manifest.raw).display()
        );
    };
    let name = manifest.named(file).display();
    let faults = &events.odometer_file_faults;
    // A file of more columns names the setting on its first line of numbers, which a
    // header line may precede.
    let columns = (faults.iter().skip(1))
        .find(|f| f.reason.contains("[odometer] value_column"))
        .map(|f| format!("; line {}: {}", f.line, f.reason))
        .unwrap_or_default();
    match faults.first() {
        Some(first) => format!(
            "the odometer file {name} gave no reading (the first line rejected, line {}: \
             {}{columns}); {} lists the first faults",
            first.line,
            first.reason,
            events_path.display()
        ),
        None => format!(
            "the odometer file {name} gave no reading: it holds no reading line (empty, or blank \
             and comment lines alone)"
        ),
    }
}

/// What a log's stream gave: its accounting and first faults, the odometer's rows, range
/// check and file (a text log's separate one, when its readings came from it), and the
/// series kept for the derive.
struct Streamed {
    report: IngestReport,
    /// The first faults, located (`ingest_events.json`).
    events: IngestEvents,
    odometer_rows: usize,
    odometer_range: OdometerRange,
    odometer_file: Option<PathBuf>,
    series: Option<WrittenSeries>,
}

/// Where the odometer's reading at `t_ns` is: "at byte offset N of LOG" or "at line N of
/// LOG" (the IMU record or line that carries it), or "at its reading of t = T s in FILE"
/// (a separate file's, whose readings no IMU sample carries).
fn odometer_place(manifest: &RunManifest, file: Option<&Path>, t_ns: i64) -> String {
    let t = seconds(t_ns);
    match file {
        Some(file) => format!(
            "at its reading of t = {t} s in {}",
            manifest.named(file).display()
        ),
        None => match imu_sample_place(manifest, KeptSample::TagNs(t_ns)) {
            Some(place) => format!("at {place}"),
            None => format!("at t = {t} s"),
        },
    }
}

/// A time tag, ns, in seconds as a decimal: exact, without trailing zeros.
pub(crate) fn seconds(t_ns: i64) -> String {
    let sign = if t_ns < 0 { "-" } else { "" };
    let (s, ns) = (
        t_ns.unsigned_abs() / 1_000_000_000,
        t_ns.unsigned_abs() % 1_000_000_000,
    );
    let fraction = format!("{ns:09}");
    match fraction.trim_end_matches('0') {
        "" => format!("{sign}{s}"),
        f => format!("{sign}{s}.{f}"),
    }
}

/// Opens a file `manifest` names, checking that what was opened is inside its folder, to
/// be read front to back: its hash is taken as it is read, for the stage's record.
fn open(manifest: &RunManifest, path: &Path) -> anyhow::Result<HashingRead> {
    let file = manifest
        .open_named(path)
        .map_err(|e| unz_formats::error::open_error_in_file(path, e))?;
    Ok(HashingRead::new(file, path))
}

/// An IMU sample the ingest kept, as a failing stage names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeptSample {
    /// Its row of `imu.parquet` (0-based).
    Row(usize),
    /// The first with this time tag, ns, as the ingest tags it.
    TagNs(i64),
}

/// Where an IMU sample the ingest kept is in the run's raw log: "byte offset N of LOG" or
/// "line N of LOG", the log as its manifest names it. The log is read again up to the
/// sample, so only a run that fails asks; None when the log cannot be read or holds no
/// such sample.
pub fn imu_sample_place(manifest: &RunManifest, sample: KeptSample) -> Option<String> {
    let path = &manifest.raw;
    let file = manifest.open_named(path).ok()?;
    let place = match manifest.format {
        LogFormat::UnzBinary => {
            let offset = unz_formats::raw::find_imu_record(file, |row, s| match sample {
                KeptSample::Row(k) => row == k as u64,
                KeptSample::TagNs(t_ns) => record_tag_ns(s.t_us) == t_ns,
            });
            format!("byte offset {}", offset.ok()??)
        }
        LogFormat::KfGins => {
            let src = BufReader::new(file);
            let line = unz_formats::kfgins::find_sample_line(src, |row, s| match sample {
                KeptSample::Row(k) => row == k as u64,
                KeptSample::TagNs(t_ns) => tag_ns(s.t_s) == t_ns,
            });
            format!("line {}", line.ok()??)
        }
    };
    Some(format!("{place} of {}", manifest.named(path).display()))
}

/// A binary record's time (µs from the header's start time, the recorder's clock steps
/// taken out: [`unz_formats::raw::ImuSample::t_us`]) as the ingest tags it, ns; a time
/// beyond i64's nanoseconds saturates.
fn record_tag_ns(t_us: u64) -> i64 {
    i64::try_from(t_us)
        .unwrap_or(i64::MAX / 1000)
        .saturating_mul(1000)
}

fn ingest_binary(
    manifest: &RunManifest,
    dir: &Path,
    options: IngestOptions,
) -> anyhow::Result<Streamed> {
    let path = &manifest.raw;
    let mut reader = RawReader::new(open(manifest, path)?).map_err(|e| e.in_file(path))?;
    let header = reader.header().clone();
    let origin_ns = header.start_time_us.checked_mul(1000);
    let scale = manifest
        .odometer
        .scale_m_per_pulse
        .unwrap_or(header.odo_lsb_m);
    let nominal_dt_s = header.sample_period_s();
    let rows_hint = std::fs::metadata(path).map_or(0, |m| rows_hint(m.len()));
    let mut sinks = Sinks::create(dir, origin_ns, Some(scale), &options, rows_hint)?;
    let mut first_pulses = None;
    // The odometer's failures (status bit 1) are bridged: their samples, and the marks
    // among them, are held back until they are.
    let mut bridger = OdometerBridger::new(
        site_gravity_mps2(manifest),
        scale,
        nominal_dt_s,
        options.odo_lag_prior_s,
    );
    let give = |sinks: &mut Sinks, bridger: &mut OdometerBridger<Row>| {
        for (row, distance) in bridger.ready() {
            sinks.give(row, distance, nominal_dt_s);
        }
        sinks.flush(false)
    };
    let mut marks = 0u64;
    while let Some(rec) = reader.next_record().map_err(|e| e.in_file(path))? {
        match rec {
            Accepted::Imu(s) => {
                let t_ns = record_tag_ns(s.t_us);
                // The counts are turned (whole numbers: a zero stays +0.0), then scaled.
                // A mounting turns the scaled increments.
                let axes = options.imu_axes;
                let mount = |v: [f64; 3]| match &options.imu_mounting {
                    Some(r) => imu_mounting::to_body(r, v),
                    None => v,
                };
                let dtheta_rad = mount(
                    axes.to_body(s.raw.dtheta.map(i64::from))
                        .map(|c| c as f64 * header.dtheta_lsb_rad),
                );
                let dvel_mps = mount(
                    axes.to_body(s.raw.dvel.map(i64::from))
                        .map(|c| c as f64 * header.dvel_lsb_mps),
                );
                let p0 = *first_pulses.get_or_insert(s.odo_pulses);
                let failed = s.raw.status & STATUS_ODOMETER_FAILED != 0;
                // A failed odometer's count is not read, nor judged against a land
                // vehicle's speed.
                let distance_m = if failed {
                    f64::NAN
                } else {
                    sinks
                        .odo_range
                        .step(t_ns, (s.odo_pulses - p0) as f64 * scale)
                };
                let sample = OdometerSample {
                    t_s: t_ns as f64 * 1e-9,
                    dtheta_rad,
                    dvel_mps,
                    distance_m,
                    failed,
                };
                let row = Row::Imu {
                    t_ns,
                    seq: s.seq,
                    dtheta_rad,
                    dvel_mps,
                    status: s.raw.status,
                    pulses: s.odo_pulses,
                };
                if let Some((row, given)) = bridger.sample(sample, row) {
                    sinks.give(row, Some(given), nominal_dt_s);
                }
            }
            Accepted::Mark(m) => {
                marks += 1;
                if marks > MAX_MARKS {
                    anyhow::bail!(
                        "{} holds more than {MAX_MARKS} control-point marks, the next at byte \
                         offset {}: a crew marks a control point with a press of its key, and \
                         so many marks are a damaged log (held in order among the samples, \
                         they would fill the memory)",
                        manifest.named(path).display(),
                        reader.record_offset()
                    );
                }
                let t_ns = record_tag_ns(m.t_us);
                bridger.other(Row::Mark {
                    t_ns,
                    point_id: m.raw.point_id,
                });
            }
        }
        give(&mut sinks, &mut bridger)?;
    }
    bridger.finish();
    give(&mut sinks, &mut bridger)?;
    let (odometer_rows, odometer_range, series) = sinks.finish(dir)?;
    let (mut report, events, events_total) = reader.into_report();
    report.odometer_out_of_range = odometer_range.out_of_range;
    report.odometer_failures = bridger.failures().cloned();
    Ok(Streamed {
        report,
        events: IngestEvents {
            raw: manifest.named(path).to_path_buf(),
            events_total,
            events,
            line_faults: Vec::new(),
            odometer_file_faults: Vec::new(),
        },
        odometer_rows,
        odometer_range,
        odometer_file: None,
        series,
    })
}

/// A text log's clock steps (`report`'s, its first reading's) for its separate odometer
/// file to follow where its tags show them ([`OdometerFileReader::on_log_clock`]): `None`
/// without a file, without a step, or with more steps than the account lists (none is
/// followed then; the file's account counts them as not shown).
fn steps_to_follow(manifest: &RunManifest, report: &IngestReport) -> Option<Vec<TextClockStep>> {
    let steps = report.text_clock_steps_back + report.text_clock_steps_forward;
    let listed = steps == report.text_clock_steps.len() as u64;
    let file = manifest.odometer.file.is_some() && manifest.odometer.kind.is_some();
    (file && steps > 0 && listed).then(|| report.text_clock_steps.clone())
}

/// Ingests a text log and its separate odometer file, if any, that file's tags moved by
/// the log's clock steps `followed` where they show them (none: as written; the account
/// then counts the log's steps as not shown).
fn ingest_text(
    manifest: &RunManifest,
    dir: &Path,
    options: IngestOptions,
    followed: &[TextClockStep],
) -> anyhow::Result<Streamed> {
    let path = &manifest.raw;
    let mut reader = KfGinsReader::new(BufReader::with_capacity(1 << 16, open(manifest, path)?))
        .with_max_gap_s(options.max_gap_s);
    let period = reader
        .period_s()
        .map_err(|e| e.in_file(path))?
        .unwrap_or(0.0);
    // The manifest's odometer file, when it names one, is the odometer; otherwise the
    // 8th column. (The column won before: a log's 8th column of anything, a temperature
    // say, was read as the speed over the file named, and the run went "ok" kilometres
    // off.)
    let odometer_file = (manifest.odometer.file.as_ref()).zip(manifest.odometer.kind);
    let column = reader.columns() == Some(8) && odometer_file.is_none();
    // Without a file, `[odometer] kind` names the 8th column's unit (m/s by default).
    let column_kind = match manifest.odometer.kind {
        Some(kind) if column && manifest.odometer.file.is_none() => {
            if !kind.is_speed() {
                anyhow::bail!(
                    "[odometer] kind = \"distance_m\" without a file names the 8th column's \
                     unit, and the 8th column is a speed (\"speed_mps\" or \"speed_kmh\") \
                     (in {})",
                    manifest.path.display()
                );
            }
            kind
        }
        _ => OdometerKind::SpeedMps,
    };
    let floor_mps = manifest.odometer.speed_floor_mps;
    let log_first_s = reader.first_tag_s();
    // The odometer file, read twice for speeds (its gaps and stands first), alike.
    let open_odometer = |file: &Path, kind| -> anyhow::Result<_> {
        Ok(
            OdometerFileReader::new(BufReader::new(open(manifest, file)?), kind)
                .with_value_column(manifest.odometer.value_column)
                .with_value_header(manifest.odometer.value_header.as_deref())
                .with_speed_floor(floor_mps)
                .beside_log_from(log_first_s)
                .on_log_clock(followed),
        )
    };
    if floor_mps.is_some() && !column && odometer_file.is_none() {
        anyhow::bail!(
            "[odometer] speed_floor_mps is set, but {} has no odometer speeds: 7 columns, and \
             no [odometer] file (in {})",
            manifest.named(path).display(),
            manifest.path.display()
        );
    }
    // A speed file's gaps and stands are found first, its readings around them kept, so
    // that the IMU's samples over them can be kept as they stream by; the 8th column's
    // as the log streams.
    let found = match odometer_file {
        Some((file, kind)) if kind.is_speed() => {
            let mut odo = open_odometer(file, kind)?;
            Some(find_gaps(|| file_readings(&mut odo)).map_err(|e| e.in_file(file))?)
        }
        _ => None,
    };
    let mut gaps = found
        .filter(|(found, more)| !found.is_empty() || *more > 0)
        .map(|(found, more)| {
            GapBridger::new(
                found,
                more,
                site_gravity_mps2(manifest),
                options.odo_lag_prior_s,
            )
        });
    let mut sinks = Sinks::create(dir, None, None, &options, 0)?;
    let new_column = || {
        let g_mps2 = site_gravity_mps2(manifest);
        (
            SpeedSpikes::default(),
            SpeedColumn::new(floor_mps),
            ColumnBridger::new(g_mps2, options.odo_lag_prior_s),
        )
    };
    let mut column = column.then(new_column);
    while let Some(mut s) = reader.next_sample().map_err(|e| e.in_file(path))? {
        // A log whose first lines leave the 8th column blank: its speeds from the first
        // given, when no file is the odometer.
        if column.is_none() && odometer_file.is_none() && s.speed_mps.is_some() {
            column = Some(new_column());
        }
        s.dtheta_rad = options.imu_axes.to_body(s.dtheta_rad);
        s.dvel_mps = options.imu_axes.to_body(s.dvel_mps);
        if let Some(r) = &options.imu_mounting {
            s.dtheta_rad = imu_mounting::to_body(r, s.dtheta_rad);
            s.dvel_mps = imu_mounting::to_body(r, s.dvel_mps);
        }
        let t_ns = tag_ns(s.t_s);
        // A text log's sequence number is its line's slot: lines lost are its steps.
        let seq = s.slot;
        let rows = &mut sinks.imu_rows;
        rows.t_ns.push(t_ns);
        rows.seq.push(seq);
        rows.dtheta_rad.push(s.dtheta_rad);
        rows.dvel_mps.push(s.dvel_mps);
        rows.status.push(0);
        if let Some(m) = &mut sinks.mcap {
            m.imu(t_ns, period, seq, s.dtheta_rad, s.dvel_mps, 0);
        }
        if let Some(g) = &mut gaps {
            g.sample(t_ns, s.dtheta_rad, s.dvel_mps);
        }
        if let Some((spikes, speed, bridger)) = &mut column {
            s.speed_mps = s.speed_mps.map(|v| column_kind.si(v));
            // Speeds beyond a land vehicle's are no reading for the spikes' judgement.
            let v = (s.speed_mps).filter(|v| v.abs() <= LAND_SPEED_RANGE_MPS);
            spikes.push(v.map(|v| (s.t_s, v)), s);
            column_readings(spikes, speed, bridger, &mut sinks);
        }
        sinks.flush(false)?;
    }
    if let Some((spikes, speed, bridger)) = &mut column {
        spikes.finish();
        column_readings(spikes, speed, bridger, &mut sinks);
    }
    let mut gaps = gaps.map(GapBridger::finish);
    let mut file_report = None;
    let mut file_spikes = (0, 0);
    let mut speed_floor = (column.as_ref()).and_then(|(_, speed, _)| speed.floor_report());
    if let Some((file, kind)) = odometer_file {
        let mut odo = open_odometer(file, kind)?;
        while let Some(o) = odo.next_sample().map_err(|e| e.in_file(file))? {
            let t_ns = tag_ns(o.t_s);
            let d = sinks.odo_range.step(t_ns, o.distance_m);
            match &mut gaps {
                Some(g) => g.give(t_ns, d, |t, given| sinks.push_odometer(t, given, None)),
                None => sinks.push_odometer(t_ns, (d, DistanceSource::Reading), None),
            }
            sinks.flush(false)?;
        }
        let mut r = odo.report().clone();
        let log = reader.report();
        if followed.is_empty() {
            // None followed (the log read once, or more steps than are listed).
            r.clock_steps_not_shown = log.text_clock_steps_back + log.text_clock_steps_forward;
        }
        file_report = Some((r, odo.faults().0.to_vec()));
        file_spikes = odo.spikes();
        speed_floor = odo.speed_floor();
    }
    let failures = match column {
        Some((spikes, _, bridger)) => {
            let mut f = bridger.finish(|t, given| sinks.push_odometer(t, given, None));
            (f.spikes, f.jumps_kept) = (spikes.spikes, spikes.jumps_kept);
            Some(f)
        }
        None => {
            let (spikes, jumps_kept) = file_spikes;
            let mut f = gaps.map(|g| g.failures().clone()).unwrap_or_default();
            (f.spikes, f.jumps_kept) = (spikes, jumps_kept);
            Some(f)
        }
    };
    // Stands the IMU found standing are no failure: nothing to report.
    let bridged = failures.filter(|f| *f != unz_formats::OdometerFailures::default());
    let (odometer_rows, odometer_range, series) = sinks.finish(dir)?;
    let mut report = reader.report().clone();
    report.odometer_out_of_range = odometer_range.out_of_range;
    report.odometer_failures = bridged;
    report.odometer_file = file_report.as_ref().map(|(r, _)| r.clone());
    report.speed_floor = speed_floor;
    report.speed_column_unread = odometer_file.is_some() && reader.columns() == Some(8);
    let (faults, total) = reader.faults();
    Ok(Streamed {
        report,
        events: IngestEvents {
            raw: manifest.named(path).to_path_buf(),
            events_total: total,
            events: Vec::new(),
            line_faults: faults.to_vec(),
            odometer_file_faults: file_report.map_or(Vec::new(), |(_, faults)| faults),
        },
        odometer_rows,
        odometer_range,
        odometer_file: odometer_file.map(|(file, _)| file.to_path_buf()),
        series,
    })
}

/// The 8th column's samples the spikes' judgement has decided, through the trapezoid to
/// the bridger (a spike's sample goes on without its speed).
fn column_readings(
    spikes: &mut SpeedSpikes<TextSample>,
    speed: &mut SpeedColumn,
    bridger: &mut ColumnBridger,
    sinks: &mut Sinks,
) {
    while let Some((s, verdict)) = spikes.pop() {
        let reading = match verdict {
            Verdict::Spike(_) => None,
            Verdict::Kept | Verdict::NoSpeed => speed.reading(&s, &mut sinks.odo_range),
        };
        let sample = (tag_ns(s.t_s), s.dtheta_rad, s.dvel_mps);
        bridger.sample(sample, reading, |t, given| {
            sinks.push_odometer(t, given, None)
        });
    }
}

/// A text log's 8th column: the odometer's speed at each IMU sample, integrated into
/// distance by the trapezoid (through the manifest's speed floor, when it sets one).
#[derive(Debug, Default)]
struct SpeedColumn {
    /// The last speed taken: its time, s, speed, m/s, and distance, m.
    prev: Option<(f64, f64, f64)>,
    /// `[odometer] speed_floor_mps`.
    floor: Option<SpeedFloor>,
}

impl SpeedColumn {
    /// Integrating from the first speed, through a floor of `floor_mps` if given.
    fn new(floor_mps: Option<f64>) -> Self {
        Self {
            prev: None,
            floor: floor_mps.map(SpeedFloor::new),
        }
    }

    /// What the floor took away so far (`None` without one).
    fn floor_report(&self) -> Option<SpeedFloorReport> {
        self.floor.as_ref().map(SpeedFloor::report)
    }

    /// The distance at `t_s` with the speed `v_mps` there; `None` for a speed beyond a
    /// land vehicle's (a corrupt reading: the sample goes on without its speed). A time
    /// not after the last speed's adds nothing (the derive repairs and counts those).
    fn distance_m(&mut self, t_s: f64, v_mps: f64) -> Option<f64> {
        if v_mps.abs() > LAND_SPEED_RANGE_MPS {
            return None;
        }
        let v_mps = match &mut self.floor {
            Some(floor) => floor.read(t_s, v_mps),
            None => v_mps,
        };
        let d = match self.prev {
            Some((t0, v0, d0)) if t_s > t0 => d0 + 0.5 * (v0 + v_mps) * (t_s - t0),
            Some((_, _, d0)) => d0,
            None => 0.0,
        };
        self.prev = Some((t_s, v_mps, d));
        Some(d)
    }

    /// The sample `s`'s reading: the trapezoid's distance, m, and the distance as
    /// written (through the odometer's range check, a corrupt speed counted there), m;
    /// `None` without a speed to write.
    fn reading(&mut self, s: &TextSample, range: &mut OdometerRange) -> Option<(f64, f64)> {
        let v_mps = s.speed_mps?;
        let Some(d) = self.distance_m(s.t_s, v_mps) else {
            range.refuse(tag_ns(s.t_s));
            return None;
        };
        Some((d, range.step(tag_ns(s.t_s), d)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The manifest's highest speed floor is the speed of a move, as the stand's
    /// detection judges it (the formats crate cannot name the stages' constants).
    #[test]
    fn the_highest_speed_floor_is_a_moves_speed() {
        use unz_stages::initial::{MOVE_WINDOW_S, MOVED_M};
        let max = unz_formats::speed_floor::SPEED_FLOOR_MAX_MPS;
        assert_eq!(max, MOVED_M / MOVE_WINDOW_S);
    }

    /// A time tag in seconds is its decimal, exact and without trailing zeros.
    #[test]
    fn a_time_tag_reads_as_its_decimal_seconds() {
        assert_eq!(seconds(152_843_090_000_000), "152843.09");
        assert_eq!(seconds(120_000_000_000), "120");
        assert_eq!(seconds(1), "0.000000001");
        assert_eq!(seconds(-1_500_000_000), "-1.5");
        assert_eq!(seconds(i64::MIN), "-9223372036.854775808");
        assert_eq!(seconds(0), "0");
    }

    /// The room asked for follows the log's size up to a day's samples: a sparse file of
    /// a terabyte (or one that claims any size) asks for no more than 2^23 rows.
    #[test]
    fn the_room_asked_for_follows_the_file_up_to_a_day() {
        let frame = frame_len(IMU_PAYLOAD_LEN) as u64;
        assert_eq!(rows_hint(0), 0);
        assert_eq!(rows_hint(1000 * frame + 3), 1000);
        // 12 hours at 100 Hz fit under the bound.
        assert_eq!(rows_hint(4_320_000 * frame), 4_320_000);
        assert_eq!(rows_hint(1 << 40), ROWS_HINT_MAX);
        assert_eq!(rows_hint(u64::MAX), ROWS_HINT_MAX);
    }
}
