//! `nav.parquet` and `corrected_nav.parquet` written while their pass runs: the pass's
//! samples go to the file [`ROWS`] at a time (encoded by another thread while the pass
//! runs on, when one is free: [`NavWriter::run_helped`]), and no track of the run's
//! length is held.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex};

use arrow::array::{ArrayRef, Float32Array, Float64Array, Int64Array, RecordBatch};
use arrow::datatypes::SchemaRef;
use rayon::prelude::*;
use unz_formats::error::{FileError, FormatError};
use unz_formats::parquet_io::{ParquetSink, TrailingColumns};
use unz_formats::schema;
use unz_formats::tables::f32_array;
use unz_stages::criteria::FixPose;
use unz_stages::derive::Derived;
use unz_stages::earth::Geodetic;
use unz_stages::euler_f32::{HeadingDeg, euler_deg_f32_into};
use unz_stages::route_sigma::RouteSigma;
use unz_stages::strapdown::{NavTrack, PassSink};

/// Rows per batch: the columns of one batch are built at a time, whatever the run's
/// length. The file is the same for any batch size; a smaller batch is less memory the
/// process touches for the first time (the batch's columns, its angles and offsets): at
/// 65 536 rows a 40-minute disupt process took 10 500 page faults, at 16 384 9 500
/// (session 77), and with session 91's other savings 7 740 at 16 384, 7 590 at 8 192.
pub const ROWS: usize = 1 << 13;

/// A navigation table being written by the pass that feeds it (a [`PassSink`]); it
/// appears under its name on [`NavWriter::finish`], when every sample was finite.
pub struct NavWriter<'a> {
    /// How the pass's rows become the file's batches.
    batches: Batches<'a>,
    /// The file, or what went wrong writing it.
    out: Out,
    /// The σ columns' encoder, until taken ([`SigmaColumns::Later`]).
    sigma_apart: Option<SigmaApart>,
    /// What the pass gave so far: the batch being filled and the samples kept.
    rows: Rows,
}

/// How a pass's rows become batches of a navigation table's file.
struct Batches<'a> {
    path: PathBuf,
    /// The schema of the batches written as the pass goes (the file's, or its columns
    /// before the route's σ when that comes later).
    schema: SchemaRef,
    derived: &'a Derived,
    start: Geodetic,
    sigma: SigmaColumns<'a>,
}

/// A navigation table's file, until an error ends it.
#[derive(Default)]
struct Out {
    file: Option<ParquetSink>,
    error: Option<FileError>,
}

/// The samples a pass gave a writer.
struct Rows {
    /// The samples of the batch being filled, from sample `lo` on.
    batch: NavTrack,
    lo: usize,
    /// The first non-finite latitude, longitude, height and attitude: (sample, value).
    first_bad: [Option<(usize, f64)>; 4],
    /// Samples whose position and distance are kept, in decreasing order (popped).
    wanted: Vec<usize>,
    kept: Vec<KeptSample>,
    samples: usize,
    last_distance_m: f64,
}

/// Batches a pass hands to the thread that helps it ([`NavWriter::run_helped`]) and
/// that thread has not yet encoded, at most: a pass that gets this far ahead waits, so
/// that what is held stays a few batches' rows (about 0.6 MB each) at any run length.
const HANDED_MAX: usize = 2;

/// What a pass and the thread that helps it share ([`NavWriter::run_helped`]).
struct Handoff {
    state: Mutex<HandoffState>,
    /// Signalled when a batch is handed or taken, and when either side is done.
    changed: Condvar,
}

#[derive(Default)]
struct HandoffState {
    /// Batches handed over, in sample order: each one's first sample and rows.
    handed: VecDeque<(usize, NavTrack)>,
    /// Whether the helper has come (batches are handed from then on).
    helping: bool,
    /// Whether the pass has ended (its last rows handed or encoded).
    pass_done: bool,
    /// Whether the helper has ended (it returns only once the pass has: else it panicked).
    helper_gone: bool,
    /// Row buffers the helper is done with, for the pass's next batches.
    spares: Vec<NavTrack>,
}

impl Handoff {
    fn lock(&self) -> std::sync::MutexGuard<'_, HandoffState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn wait<'g>(
        &self,
        guard: std::sync::MutexGuard<'g, HandoffState>,
    ) -> std::sync::MutexGuard<'g, HandoffState> {
        self.changed.wait(guard).unwrap_or_else(|e| e.into_inner())
    }
}

/// The sink of a pass another thread helps ([`NavWriter::run_helped`]): the writer's
/// pass side.
pub struct HelpedSink<'h, 'a> {
    rows: &'h mut Rows,
    batches: &'h Batches<'a>,
    out: &'h Mutex<Out>,
    handoff: &'h Handoff,
}

impl HelpedSink<'_, '_> {
    /// The rows gathered so far go to the helper, once it has come; until then they are
    /// encoded here, as an unhelped writer does.
    fn flush(&mut self) {
        if self.rows.batch.is_empty() {
            return;
        }
        let mut state = self.handoff.lock();
        if !state.helping {
            drop(state);
            let mut out = self.out.lock().unwrap_or_else(|e| e.into_inner());
            self.batches.write_filled(&mut out, self.rows);
            return;
        }
        while state.handed.len() >= HANDED_MAX && !state.helper_gone {
            state = self.handoff.wait(state);
        }
        let spare = state.spares.pop().unwrap_or_default();
        let handed = self.rows.take_batch(spare);
        // A helper gone before the pass panicked (which the join passes on): the file is
        // not written, and the rows are dropped.
        if !state.helper_gone {
            state.handed.push_back(handed);
            drop(state);
            self.handoff.changed.notify_all();
        }
    }
}

/// A side of [`NavWriter::run_helped`].
#[derive(Clone, Copy)]
enum Side {
    Pass,
    Helper,
}

/// Tells the other side, when dropped, that this side has ended (returned or panicked):
/// neither then waits for the other for ever.
struct Ended<'h>(&'h Handoff, Side);

impl Drop for Ended<'_> {
    fn drop(&mut self) {
        let mut state = self.0.lock();
        match self.1 {
            Side::Pass => state.pass_done = true,
            Side::Helper => state.helper_gone = true,
        }
        drop(state);
        self.0.changed.notify_all();
    }
}

impl PassSink for HelpedSink<'_, '_> {
    fn sample(&mut self, k: usize, lat: f64, lon: f64, h: f64, q: &[f64; 4], distance_m: f64) {
        if self.rows.push(k, lat, lon, h, q, distance_m) {
            self.flush();
        }
    }
}

/// The route's 1σ columns of a navigation table (`sigma_north_m`, `sigma_east_m`,
/// `sigma_heading_deg`).
#[derive(Debug, Clone, Copy)]
pub enum SigmaColumns<'a> {
    /// None (`nav.parquet`).
    Without,
    /// Written with the other columns, from this σ.
    With(&'a RouteSigma),
    /// Encoded apart from the pass ([`NavWriter::take_sigma_apart`], then
    /// [`NavWriter::finish_with_sigma`]): the pass need not wait for the σ (the other
    /// columns are encoded as it runs, and their row groups wait for the σ's).
    Later,
}

/// The route's σ columns of a navigation table, encoded apart from its pass (on another
/// thread, while it runs) for [`NavWriter::finish_with_sigma`].
pub struct SigmaApart {
    columns: TrailingColumns,
    schema: SchemaRef,
}

impl SigmaApart {
    /// Encodes `sigma` at samples `0..samples` (every sample the pass writes), in the
    /// batches the pass's rows go in (the file is then the one written with the σ known
    /// from the start, byte for byte).
    pub fn write(&mut self, sigma: &RouteSigma, samples: usize) -> Result<(), FileError> {
        for lo in (0..samples).step_by(ROWS) {
            let columns = sigma_columns(sigma, lo..(lo + ROWS).min(samples));
            let batch = RecordBatch::try_new(self.schema.clone(), columns.to_vec())
                .map_err(|e| FormatError::from(e).in_file(self.columns.dest()))?;
            self.columns.write(&batch)?;
        }
        Ok(())
    }
}

/// A sample's pose (with its height and distance), kept for the stage's report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KeptSample {
    /// Sample index.
    pub sample: usize,
    /// Position, attitude and distance travelled.
    pub pose: FixPose,
}

/// What a [`NavWriter`] saw of its pass.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NavWritten {
    /// Samples written.
    pub samples: usize,
    /// Travelled distance at the last sample, m (0 without one).
    pub distance_m: f64,
    /// The samples asked for at creation that the pass reached, in sample order.
    pub kept: Vec<KeptSample>,
}

impl NavWritten {
    /// The kept sample `sample`.
    pub fn at(&self, sample: usize) -> Option<&KeptSample> {
        self.kept
            .binary_search_by_key(&sample, |s| s.sample)
            .ok()
            .map(|i| &self.kept[i])
    }
}

impl<'a> NavWriter<'a> {
    /// Starts `path` (`nav.parquet`, or `corrected_nav.parquet` with the route's 1σ north,
    /// east and heading per sample, see [`SigmaColumns`]) for a pass over `derived`'s
    /// samples from `start`, keeping the position and distance at the samples `keep`.
    pub fn create(
        path: &Path,
        derived: &'a Derived,
        start: Geodetic,
        sigma: SigmaColumns<'a>,
        keep: &[usize],
    ) -> Result<Self, FileError> {
        let with_sigma = !matches!(sigma, SigmaColumns::Without);
        let all = schema::nav(with_sigma);
        let mut file = ParquetSink::create(path, all.clone())?;
        let schema = schema::nav(matches!(sigma, SigmaColumns::With(_)));
        let mut sigma_apart = None;
        if matches!(sigma, SigmaColumns::Later) {
            let first = schema.fields().len();
            let (sink, columns) = file.deferring_from(first)?;
            let trailing: Vec<usize> = (first..all.fields().len()).collect();
            let schema = Arc::new(
                all.project(&trailing)
                    .map_err(|e| FormatError::from(e).in_file(path))?,
            );
            file = sink;
            sigma_apart = Some(SigmaApart { columns, schema });
        }
        let mut wanted = keep.to_vec();
        wanted.sort_unstable();
        wanted.dedup();
        wanted.reverse();
        Ok(Self {
            batches: Batches {
                path: path.to_path_buf(),
                schema,
                derived,
                start,
                sigma,
            },
            out: Out {
                file: Some(file),
                error: None,
            },
            sigma_apart,
            rows: Rows {
                batch: NavTrack::default(),
                lo: 0,
                first_bad: [None; 4],
                wanted,
                kept: Vec::new(),
                samples: 0,
                last_distance_m: 0.0,
            },
        })
    }

    /// Writes the rows gathered so far as one batch.
    fn flush(&mut self) {
        self.batches.write_filled(&mut self.out, &mut self.rows);
    }

    /// Runs `pass` into this writer with a helper: once another of rayon's threads comes
    /// free, it builds and encodes the batches the pass hands it while the pass runs on.
    /// Until then (and when none comes before the pass ends) the pass's thread encodes
    /// each batch as it fills, as [`PassSink::sample`] does. The same batches in the
    /// same order: the same file. For a pass whose other core ends its own work first
    /// (the corrected navigation's, beside the route's σ and the tables) or has none (the
    /// navigate stage's): a batch's columns and their encoding take about as long as its
    /// samples' pass.
    pub fn run_helped(&mut self, pass: impl FnOnce(&mut HelpedSink<'_, 'a>) + Send) {
        let out = Mutex::new(std::mem::take(&mut self.out));
        let handoff = Handoff {
            state: Mutex::new(HandoffState::default()),
            changed: Condvar::new(),
        };
        let (rows, batches) = (&mut self.rows, &self.batches);
        rayon::join(
            || {
                let _ended = Ended(&handoff, Side::Pass);
                let mut sink = HelpedSink {
                    rows,
                    batches,
                    out: &out,
                    handoff: &handoff,
                };
                pass(&mut sink);
                sink.flush();
            },
            || {
                let _ended = Ended(&handoff, Side::Helper);
                batches.help(&out, &handoff);
            },
        );
        self.out = out.into_inner().unwrap_or_else(|e| e.into_inner());
    }

    /// Writes the last rows and puts the file in place. `what` names the pass in the
    /// error when a sample was not finite (the file is then not written).
    pub fn finish(self, what: &str) -> anyhow::Result<NavWritten> {
        if matches!(self.batches.sigma, SigmaColumns::Later) {
            anyhow::bail!("{what}: the route's σ was not given to the navigation's writer");
        }
        self.close(what, None)
    }

    /// The σ columns' encoder of a writer created with [`SigmaColumns::Later`] (once).
    pub fn take_sigma_apart(&mut self) -> Option<SigmaApart> {
        self.sigma_apart.take()
    }

    /// [`NavWriter::finish`] of a writer created with [`SigmaColumns::Later`]: its rows
    /// with the route's σ columns `sigma` encoded, then the file put in place.
    pub fn finish_with_sigma(self, what: &str, sigma: SigmaApart) -> anyhow::Result<NavWritten> {
        if !matches!(self.batches.sigma, SigmaColumns::Later) {
            anyhow::bail!("{what}: the navigation's writer takes no σ at its end");
        }
        self.close(what, Some(sigma))
    }

    /// Writes the last rows (with the σ columns, when given) and puts the file in place.
    fn close(mut self, what: &str, sigma: Option<SigmaApart>) -> anyhow::Result<NavWritten> {
        self.flush();
        let names = ["latitude", "longitude", "height", "attitude"];
        for (name, bad) in names.iter().zip(self.rows.first_bad) {
            if let Some((k, v)) = bad {
                anyhow::bail!(
                    "{what} {name} is {v} at sample {k}: the input's scales or values are not \
                     physical"
                );
            }
        }
        if let Some(e) = self.out.error {
            return Err(e.into());
        }
        if let Some(file) = self.out.file {
            match sigma {
                Some(sigma) => file.finish_with(sigma.columns)?,
                None => file.finish()?,
            }
        }
        Ok(NavWritten {
            samples: self.rows.samples,
            distance_m: self.rows.last_distance_m,
            kept: self.rows.kept,
        })
    }
}

impl Batches<'_> {
    /// Builds the batch of rows `t` (from sample `lo`) and encodes it into `out`; the
    /// first error ends the file.
    fn write(&self, out: &mut Out, lo: usize, t: &NavTrack) {
        let Some(file) = out.file.as_mut() else {
            return;
        };
        let written = nav_batch(
            &self.schema,
            self.derived,
            lo,
            t,
            self.start,
            match self.sigma {
                SigmaColumns::With(s) => Some(s),
                SigmaColumns::Without | SigmaColumns::Later => None,
            },
        )
        .map_err(|e| FormatError::from(e).in_file(&self.path))
        .and_then(|b| file.write(&b));
        if let Err(e) = written {
            out.error = Some(e);
            out.file = None;
        }
    }

    /// Writes the batch `rows` filled so far (if any) into `out`, and begins the next.
    fn write_filled(&self, out: &mut Out, rows: &mut Rows) {
        if rows.batch.is_empty() {
            return;
        }
        self.write(out, rows.lo, &rows.batch);
        rows.lo += rows.batch.len();
        rows.batch.clear();
    }

    /// The helper's side of [`NavWriter::run_helped`]: encodes the batches handed over
    /// until the pass has ended and none is left (nothing when the pass ended first).
    fn help(&self, out: &Mutex<Out>, handoff: &Handoff) {
        let mut state = handoff.lock();
        if state.pass_done {
            return;
        }
        state.helping = true;
        loop {
            if let Some((lo, mut rows)) = state.handed.pop_front() {
                drop(state);
                handoff.changed.notify_all();
                {
                    let mut out = out.lock().unwrap_or_else(|e| e.into_inner());
                    self.write(&mut out, lo, &rows);
                }
                rows.clear();
                state = handoff.lock();
                state.spares.push(rows);
            } else if state.pass_done {
                return;
            } else {
                state = handoff.wait(state);
            }
        }
    }
}

impl Rows {
    /// The batch filled so far, with its first sample; the next one begins in `spare`.
    fn take_batch(&mut self, spare: NavTrack) -> (usize, NavTrack) {
        let lo = self.lo;
        self.lo += self.batch.len();
        (lo, std::mem::replace(&mut self.batch, spare))
    }

    /// Takes one sample; whether the batch is full.
    fn push(
        &mut self,
        k: usize,
        lat: f64,
        lon: f64,
        h: f64,
        q: &[f64; 4],
        distance_m: f64,
    ) -> bool {
        for (slot, v) in self.first_bad.iter_mut().zip([lat, lon, h, q[0]]) {
            if slot.is_none() && !v.is_finite() {
                *slot = Some((k, v));
            }
        }
        while self.wanted.last().is_some_and(|&w| w < k) {
            self.wanted.pop();
        }
        if self.wanted.last() == Some(&k) {
            self.wanted.pop();
            self.kept.push(KeptSample {
                sample: k,
                pose: FixPose {
                    lat_rad: lat,
                    lon_rad: lon,
                    h_m: h,
                    distance_m,
                    q_b_to_n: *q,
                },
            });
        }
        self.samples = k + 1;
        self.last_distance_m = distance_m;
        let r = &mut self.batch;
        r.lat_rad.push(lat);
        r.lon_rad.push(lon);
        r.h_m.push(h);
        r.q_b_to_n.push(*q);
        r.distance_m.push(distance_m);
        r.len() == ROWS
    }
}

impl PassSink for NavWriter<'_> {
    fn sample(&mut self, k: usize, lat: f64, lon: f64, h: f64, q: &[f64; 4], distance_m: f64) {
        if self.rows.push(k, lat, lon, h, q, distance_m) {
            self.flush();
        }
    }
}

/// Rows of a batch whose angles one task computes.
const EULER_CHUNK_ROWS: usize = 4096;

/// The rows `t` of samples `lo..` as a batch of `schema` (from [`schema::nav`]).
fn nav_batch(
    schema: &SchemaRef,
    d: &Derived,
    lo: usize,
    t: &NavTrack,
    start: Geodetic,
    sigma: Option<&RouteSigma>,
) -> Result<RecordBatch, arrow::error::ArrowError> {
    let r = lo..lo + t.len();
    // The angles and the local offsets side by side.
    let (euler, ne): (Vec<[f32; 3]>, Vec<(f64, f64)>) = rayon::join(
        || {
            let mut euler = vec![[0.0f32; 3]; t.q_b_to_n.len()];
            euler
                .par_chunks_mut(EULER_CHUNK_ROWS)
                .zip(t.q_b_to_n.par_chunks(EULER_CHUNK_ROWS))
                .for_each(|(out, q)| euler_deg_f32_into(q, HeadingDeg::AsIs, out));
            euler
        },
        || {
            let frame = start.local_frame();
            (0..t.len())
                .into_par_iter()
                .map(|j| frame.offset_m(t.lat_rad[j], t.lon_rad[j]))
                .collect()
        },
    );
    let angle = |i: usize| -> ArrayRef {
        Arc::new(Float32Array::from_iter_values(euler.iter().map(|e| e[i])))
    };
    let deg = |v: &[f64]| {
        Arc::new(Float64Array::from_iter_values(
            v.iter().map(|x| x.to_degrees()),
        ))
    };
    let mut columns: Vec<ArrayRef> = vec![
        Arc::new(Int64Array::from_iter_values(d.t_ns(r.clone()))),
        deg(&t.lat_rad),
        deg(&t.lon_rad),
        f32_array(t.h_m.iter().copied()),
        f32_array(ne.iter().map(|p| p.0)),
        f32_array(ne.iter().map(|p| p.1)),
        angle(0),
        angle(1),
        angle(2),
        f32_array(t.distance_m.iter().copied()),
    ];
    if let Some(s) = sigma {
        columns.extend(sigma_columns(s, r));
    }
    RecordBatch::try_new(schema.clone(), columns)
}

/// The route's σ columns of samples `r` (north and east, m; heading, deg).
fn sigma_columns(sigma: &RouteSigma, r: std::ops::Range<usize>) -> [ArrayRef; 3] {
    let [n, e, h] = sigma.at_samples(r);
    [
        f32_array(n),
        f32_array(e),
        f32_array(h.iter().map(|x| x.to_degrees())),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use unz_formats::parquet_io::read_table;
    use unz_formats::tables::{f64_column, i64_column};

    /// A derive of `n` samples 10 ms apart (all the writer reads of it: the times).
    fn derive_of(n: usize) -> Derived {
        Derived {
            t0_ns: 1_000_000_000,
            nominal_dt_s: 0.01,
            t_s: (0..n).map(|k| k as f64 * 0.01).collect::<Vec<_>>().into(),
            dt_s: vec![0.01; n].into(),
            ..Derived::default()
        }
    }

    /// The tests' start.
    const START: Geodetic = Geodetic {
        lat_rad: 0.8,
        lon_rad: 0.5,
        h_m: 100.0,
    };

    /// A route's σ over `n` samples, at every 100th.
    fn sigma_of(n: usize) -> RouteSigma {
        RouteSigma {
            sample: (0..n).step_by(100).collect(),
            north_m: (0..n).step_by(100).map(|k| 1.0 + k as f64 * 1e-3).collect(),
            east_m: (0..n).step_by(100).map(|k| 2.0 + k as f64 * 2e-3).collect(),
            heading_rad: (0..n)
                .step_by(100)
                .map(|k| 1e-3 + k as f64 * 1e-8)
                .collect(),
        }
    }

    /// A pool of `threads` of rayon's threads.
    fn pool_of(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    }

    fn feed(w: &mut impl PassSink, n: usize, bad: Option<usize>) {
        feed_pausing(w, n, bad, None);
    }

    /// [`feed`], pausing for `pause` after each batch's first sample.
    fn feed_pausing(
        w: &mut impl PassSink,
        n: usize,
        bad: Option<usize>,
        pause: Option<std::time::Duration>,
    ) {
        for k in 0..n {
            let lat = if Some(k) == bad {
                f64::NAN
            } else {
                0.8 + k as f64 * 1e-9
            };
            // A turning attitude, so that every angle column varies.
            let a = k as f64 * 1e-4;
            let q = [
                a.cos(),
                0.1 * a.sin(),
                0.2 * a.sin(),
                (1.0 - 0.05f64).sqrt() * a.sin(),
            ];
            w.sample(k, lat, 0.5 + k as f64 * 2e-9, 100.0 + a, &q, k as f64 * 0.1);
            if k % ROWS == 0
                && let Some(p) = pause
            {
                std::thread::sleep(p);
            }
        }
    }

    /// A pass helped by another thread ([`NavWriter::run_helped`]) writes the file the
    /// unhelped pass writes, byte for byte, however the helper comes: from the start (a
    /// pool of two threads with nothing else to do), midway (the other thread busy for
    /// a while first), or never (a pool of one thread: it comes once the pass has ended,
    /// to find nothing left); with the route's σ given or encoded apart.
    #[test]
    fn a_helped_pass_writes_the_unhelped_file() {
        let n = 9 * ROWS + 123;
        let d = derive_of(n);
        let tmp = tempfile::tempdir().unwrap();
        let (start, sigma) = (START, sigma_of(n));
        let keep = [5, ROWS, n - 1];
        for columns in [SigmaColumns::Without, SigmaColumns::With(&sigma)] {
            let plain_path = tmp.path().join("plain.parquet");
            let mut w = NavWriter::create(&plain_path, &d, start, columns, &keep).unwrap();
            feed(&mut w, n, None);
            let plain = w.finish("corrected").unwrap();
            let plain_bytes = std::fs::read(&plain_path).unwrap();
            let pause = std::time::Duration::from_millis(1);
            for (threads, busy_ms) in [(2, 0), (2, 4), (1, 0)] {
                let pool = pool_of(threads);
                let path = tmp
                    .path()
                    .join(format!("helped-{threads}-{busy_ms}.parquet"));
                let mut w = NavWriter::create(&path, &d, start, columns, &keep).unwrap();
                pool.install(|| {
                    rayon::join(
                        || std::thread::sleep(std::time::Duration::from_millis(busy_ms)),
                        || w.run_helped(|sink| feed_pausing(sink, n, None, Some(pause))),
                    )
                });
                let helped = w.finish("corrected").unwrap();
                assert_eq!(helped, plain, "{threads} threads, busy {busy_ms} ms");
                assert!(
                    std::fs::read(&path).unwrap() == plain_bytes,
                    "{threads} threads, busy {busy_ms} ms: the files differ"
                );
            }
        }
        // The σ encoded apart, beside a helped pass.
        let known = tmp.path().join("known.parquet");
        let mut w =
            NavWriter::create(&known, &d, start, SigmaColumns::With(&sigma), &keep).unwrap();
        feed(&mut w, n, None);
        w.finish("corrected").unwrap();
        let apart_path = tmp.path().join("apart.parquet");
        let mut w = NavWriter::create(&apart_path, &d, start, SigmaColumns::Later, &keep).unwrap();
        let mut apart = w.take_sigma_apart().unwrap();
        rayon::join(
            || w.run_helped(|sink| feed(sink, n, None)),
            || apart.write(&sigma, n).unwrap(),
        );
        w.finish_with_sigma("corrected", apart).unwrap();
        assert!(std::fs::read(&apart_path).unwrap() == std::fs::read(&known).unwrap());
    }

    /// Two helped passes at once on a pool of two threads (two runs of a campaign
    /// sharing the cores): a thread free of its own pass may help the other's, and both
    /// files are the unhelped ones.
    #[test]
    fn two_helped_passes_at_once_write_their_files() {
        let n = 7 * ROWS + 11;
        let d = derive_of(n);
        let tmp = tempfile::tempdir().unwrap();
        let plain_path = tmp.path().join("plain.parquet");
        let mut w = NavWriter::create(&plain_path, &d, START, SigmaColumns::Without, &[3]).unwrap();
        feed(&mut w, n, None);
        w.finish("navigated").unwrap();
        let plain = std::fs::read(&plain_path).unwrap();
        let pool = pool_of(2);
        for (first, second) in [(0, 2), (2, 0), (1, 1)] {
            let paths = [0, 1].map(|i| tmp.path().join(format!("run{i}-{first}-{second}.parquet")));
            let mut writers = paths
                .each_ref()
                .map(|p| NavWriter::create(p, &d, START, SigmaColumns::Without, &[3]).unwrap());
            let [a, b] = &mut writers;
            let pause = |ms: u64| Some(std::time::Duration::from_millis(ms));
            pool.install(|| {
                rayon::join(
                    || a.run_helped(|sink| feed_pausing(sink, n, None, pause(first))),
                    || b.run_helped(|sink| feed_pausing(sink, n, None, pause(second))),
                )
            });
            for (w, path) in writers.into_iter().zip(&paths) {
                w.finish("navigated").unwrap();
                assert!(
                    std::fs::read(path).unwrap() == plain,
                    "{}: the file differs",
                    path.display()
                );
            }
        }
    }

    /// A helped pass that panics ends its helper (the panic goes on, nothing waits for
    /// ever), and a non-finite sample of a helped pass is named as an unhelped one's is.
    #[test]
    fn a_helped_pass_ends_its_helper_and_names_a_bad_sample() {
        let n = 6 * ROWS;
        let d = derive_of(n);
        let tmp = tempfile::tempdir().unwrap();
        let pool = pool_of(2);
        let path = tmp.path().join("panicked.parquet");
        let mut w =
            NavWriter::create(&path, &d, Geodetic::default(), SigmaColumns::Without, &[]).unwrap();
        let panicked = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pool.install(|| {
                w.run_helped(|sink| {
                    feed(sink, 3 * ROWS + 7, None);
                    panic!("the pass broke");
                })
            })
        }));
        assert!(panicked.is_err());
        drop(w);
        assert!(!path.exists());

        let path = tmp.path().join("bad.parquet");
        let mut w =
            NavWriter::create(&path, &d, Geodetic::default(), SigmaColumns::Without, &[]).unwrap();
        pool.install(|| w.run_helped(|sink| feed(sink, n, Some(2 * ROWS + 3))));
        let e = w.finish("corrected").unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                "corrected latitude is NaN at sample {}",
                2 * ROWS + 3
            )),
            "{e}"
        );
        assert!(!path.exists());
    }

    #[test]
    fn rows_go_out_in_batches_and_kept_samples_come_back() {
        let n = ROWS + 5;
        let d = derive_of(n);
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("nav.parquet");
        let mut w = NavWriter::create(&path, &d, START, SigmaColumns::Without, &[n - 1, 3, n + 10])
            .unwrap();
        feed(&mut w, n, None);
        let written = w.finish("navigated").unwrap();
        assert_eq!(written.samples, n);
        assert_eq!(written.distance_m, (n - 1) as f64 * 0.1);
        // Kept in sample order; a sample the pass never reached is not there.
        let kept: Vec<usize> = written.kept.iter().map(|s| s.sample).collect();
        assert_eq!(kept, vec![3, n - 1]);
        assert_eq!(written.at(3).unwrap().pose.distance_m, 3.0 * 0.1);
        let (_, t) = read_table(&path).unwrap();
        assert_eq!(t.num_rows(), n);
        let t_ns = i64_column(&t, schema::T_NS).unwrap();
        assert_eq!(
            t_ns[ROWS + 1],
            1_000_000_000 + (ROWS as i64 + 1) * 10_000_000
        );
        let lat = f64_column(&t, schema::nav_cols::LAT_DEG).unwrap();
        assert_eq!(lat[ROWS + 2], (0.8 + (ROWS + 2) as f64 * 1e-9).to_degrees());
    }

    /// The route's σ columns encoded apart, on another thread while the pass runs
    /// ([`SigmaColumns::Later`]), make the file the σ known from the start makes, byte
    /// for byte (rows over several batches); the σ is given to a writer that asked for
    /// it only, and one that asked for it cannot be finished without it.
    #[test]
    fn the_sigma_encoded_apart_makes_the_same_file() {
        let n = 2 * ROWS + 77;
        let d = derive_of(n);
        let tmp = tempfile::tempdir().unwrap();
        let (start, sigma) = (START, sigma_of(n));
        let known = tmp.path().join("known.parquet");
        let mut w = NavWriter::create(&known, &d, start, SigmaColumns::With(&sigma), &[5]).unwrap();
        feed(&mut w, n, None);
        let from_start = w.finish("corrected").unwrap();

        let apart_path = tmp.path().join("apart.parquet");
        let mut w = NavWriter::create(&apart_path, &d, start, SigmaColumns::Later, &[5]).unwrap();
        let mut apart = w.take_sigma_apart().expect("asked for");
        assert!(w.take_sigma_apart().is_none(), "taken once");
        let (written, ()) = rayon::join(
            || {
                feed(&mut w, n, None);
                w
            },
            || apart.write(&sigma, n).unwrap(),
        );
        let later = written.finish_with_sigma("corrected", apart).unwrap();
        assert_eq!(later, from_start);
        assert!(std::fs::read(&apart_path).unwrap() == std::fs::read(&known).unwrap());

        // Misuse.
        let mut w = NavWriter::create(
            &tmp.path().join("a.parquet"),
            &d,
            start,
            SigmaColumns::Later,
            &[],
        )
        .unwrap();
        let apart = w.take_sigma_apart().unwrap();
        feed(&mut w, n, None);
        let e = w.finish("corrected").unwrap_err().to_string();
        assert!(e.contains("σ was not given"), "{e}");
        let mut w = NavWriter::create(
            &tmp.path().join("b.parquet"),
            &d,
            start,
            SigmaColumns::Without,
            &[],
        )
        .unwrap();
        assert!(w.take_sigma_apart().is_none());
        feed(&mut w, n, None);
        let e = w
            .finish_with_sigma("corrected", apart)
            .unwrap_err()
            .to_string();
        assert!(e.contains("takes no σ"), "{e}");
    }

    #[test]
    fn a_non_finite_sample_is_named_and_leaves_no_file() {
        let d = derive_of(100);
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("corrected_nav.parquet");
        let mut w =
            NavWriter::create(&path, &d, Geodetic::default(), SigmaColumns::Without, &[]).unwrap();
        feed(&mut w, 100, Some(7));
        let e = w.finish("corrected").unwrap_err().to_string();
        assert!(e.contains("corrected latitude is NaN at sample 7"), "{e}");
        assert!(!path.exists());
        assert_eq!(
            std::fs::read_dir(tmp.path()).unwrap().count(),
            0,
            "a temporary file left"
        );
    }
}
