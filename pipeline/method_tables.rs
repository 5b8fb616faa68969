//! The disupt stage's per-method tables, written for review: each method's trajectory
//! (`tracks.parquet`, decimated to [`TRACK_RATE_HZ`]) and its Kryt1 series
//! (`kryt1_series.parquet`, at the ΔTg epochs), in long form with a `method` column
//! (`initial` for the settings before DISUPT). Reading them back never navigates.

use std::path::Path;
use std::sync::Arc;

use arrow::array::{
    Array, Float32Array, Float64Array, Int64Array, RecordBatch, StringArray, StringBuilder,
};
use arrow::datatypes::{Float32Type, Float64Type, Int64Type, SchemaRef};
use unz_formats::FormatError;
use unz_formats::parquet_io::{ParquetSink, for_each_batch_of, write_batch};
use unz_formats::schema::{self, criteria_cols};
use unz_formats::split_doubles::{SplitFloat, for_each_split_page};
use unz_formats::tables::values_of;
use unz_stages::criteria::Kryt1Series;
use unz_stages::derive::Derived;
use unz_stages::earth::{Geodetic, LocalFrame};
use unz_stages::euler_f32::{HeadingDeg, SIDE_BY_SIDE, euler_deg_f32_into};
use unz_stages::strapdown::{KeepRows, TrackRow, samples_every};

/// File name of the per-method trajectories.
pub const TRACKS: &str = "tracks.parquet";
/// File name of the per-method Kryt1 series.
pub const KRYT1_SERIES: &str = "kryt1_series.parquet";
/// Rate of the stored trajectories, Hz (a reviewer sees no difference from 100 Hz on a
/// map or in 3D; a 40-minute run keeps 24 000 rows per method).
pub const TRACK_RATE_HZ: f64 = 10.0;

/// One method's trajectory, decimated, in the types `tracks.parquet` stores (latitude
/// and longitude need f64: f32 degrees resolve only about a metre).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MethodTrack {
    /// `initial`, `oepi`, `owpi` or `joint`.
    pub method: String,
    /// Time, ns in the log's time base.
    pub t_ns: Vec<i64>,
    /// Latitude, degrees.
    pub lat_deg: Vec<f64>,
    /// Longitude, degrees.
    pub lon_deg: Vec<f64>,
    /// Height, m.
    pub h_m: Vec<f32>,
    /// North of the start, m.
    pub north_m: Vec<f32>,
    /// East of the start, m.
    pub east_m: Vec<f32>,
    /// Roll, degrees.
    pub roll_deg: Vec<f32>,
    /// Pitch, degrees.
    pub pitch_deg: Vec<f32>,
    /// Heading, degrees.
    pub heading_deg: Vec<f32>,
}

/// One method's Kryt1 series at the ΔTg epochs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MethodKryt1 {
    /// `initial`, `oepi`, `owpi` or `joint`.
    pub method: String,
    /// Epoch time, ns in the log's time base.
    pub t_ns: Vec<i64>,
    /// Cumulative Kryt1, rad.
    pub kryt1_cum: Vec<f64>,
    /// Kalman estimate of ΔΘ, rad.
    pub kf_d_theta_rad: Vec<f64>,
    /// Kalman estimate of ΔΦ, rad.
    pub kf_d_phi_rad: Vec<f64>,
}

/// Samples between two kept at `rate_hz` (at least 1).
pub fn decimation_step(nominal_dt_s: f64, rate_hz: f64) -> usize {
    ((1.0 / (rate_hz * nominal_dt_s)).round() as usize).max(1)
}

/// Samples kept at `rate_hz`: every k-th one and always the last.
pub fn decimation_indices(len: usize, nominal_dt_s: f64, rate_hz: f64) -> Vec<usize> {
    samples_every(len, decimation_step(nominal_dt_s, rate_hz))
}

/// The samples of `d` the methods' trajectories keep (at [`TRACK_RATE_HZ`]).
pub fn track_samples(d: &Derived) -> Vec<usize> {
    decimation_indices(d.nav_inputs().len(), d.nominal_dt_s, TRACK_RATE_HZ)
}

/// The times of the kept samples `keep` of `d` (ns in the log's time base): the rows of
/// each track in `tracks.parquet`.
pub fn track_times(d: &Derived, keep: &[usize]) -> Vec<i64> {
    keep.iter().map(|&k| d.t_ns_at(k)).collect()
}

/// One method's trajectory as its review pass keeps it, at [`track_samples`]: what
/// [`MethodTrack`] holds but its times and local offsets, which [`TracksWriter`] makes
/// from the samples and the positions as it writes (16 of a row's 48 bytes fewer held
/// beside the review lanes: 28 MB for four methods at 12 h).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct KeptTrack {
    /// `initial`, `oepi`, `owpi` or `joint`.
    pub method: String,
    /// Latitude, rad.
    pub lat_rad: Vec<f64>,
    /// Longitude, rad.
    pub lon_rad: Vec<f64>,
    /// Height, m.
    pub h_m: Vec<f32>,
    /// Roll, degrees.
    pub roll_deg: Vec<f32>,
    /// Pitch, degrees.
    pub pitch_deg: Vec<f32>,
    /// Heading, degrees in [0, 360).
    pub heading_deg: Vec<f32>,
}

/// One method's trajectory built as its pass reaches the kept samples (see
/// [`track_samples`]; a [`KeepRows`]): no state of the pass is stored beside it.
pub struct TrackBuilder {
    track: KeptTrack,
    /// Attitudes whose angles are not taken yet: they are taken a block at a time, side
    /// by side ([`euler_deg_f32_into`]).
    pending: [[f64; 4]; SIDE_BY_SIDE],
    pending_rows: usize,
}

impl TrackBuilder {
    /// For `method`'s pass, keeping `rows` samples.
    pub fn new(method: &str, rows: usize) -> Self {
        Self {
            track: KeptTrack {
                method: method.to_owned(),
                lat_rad: Vec::with_capacity(rows),
                lon_rad: Vec::with_capacity(rows),
                h_m: Vec::with_capacity(rows),
                roll_deg: Vec::with_capacity(rows),
                pitch_deg: Vec::with_capacity(rows),
                heading_deg: Vec::with_capacity(rows),
            },
            pending: [[0.0; 4]; SIDE_BY_SIDE],
            pending_rows: 0,
        }
    }

    /// The trajectory.
    pub fn finish(mut self) -> KeptTrack {
        self.take_angles();
        self.track
    }

    /// The pending attitudes' angles, into the track.
    fn take_angles(&mut self) {
        let n = self.pending_rows;
        let mut rows = [[0.0; 3]; SIDE_BY_SIDE];
        euler_deg_f32_into(&self.pending[..n], HeadingDeg::Wrapped, &mut rows[..n]);
        let m = &mut self.track;
        for [roll, pitch, heading] in &rows[..n] {
            m.roll_deg.push(*roll);
            m.pitch_deg.push(*pitch);
            m.heading_deg.push(*heading);
        }
        self.pending_rows = 0;
    }
}

impl KeepRows for TrackBuilder {
    fn keep(&mut self, _k: usize, (lat, lon, h, q): TrackRow) {
        let m = &mut self.track;
        m.lat_rad.push(lat);
        m.lon_rad.push(lon);
        m.h_m.push(h as f32);
        self.pending[self.pending_rows] = q;
        self.pending_rows += 1;
        if self.pending_rows == SIDE_BY_SIDE {
            self.take_angles();
        }
    }
}

/// One method's Kryt1 series from the criteria of its pass.
pub fn method_kryt1(method: &str, d: &Derived, s: &Kryt1Series) -> MethodKryt1 {
    MethodKryt1 {
        method: method.to_owned(),
        t_ns: d.epoch_t_ns(),
        kryt1_cum: s.kryt1_cum.clone(),
        kf_d_theta_rad: s.kf_theta_rad.clone(),
        kf_d_phi_rad: s.kf_phi_rad.clone(),
    }
}

/// The `method` column: each name repeated over its rows (built in place, without a
/// reference to the name per row first).
fn method_column<'a>(names: impl Iterator<Item = (&'a str, usize)>) -> Arc<StringArray> {
    let names: Vec<(&str, usize)> = names.collect();
    let rows = names.iter().map(|&(_, len)| len).sum();
    let bytes = names.iter().map(|&(n, len)| n.len() * len).sum();
    let mut column = StringBuilder::with_capacity(rows, bytes);
    for (n, len) in names {
        (0..len).for_each(|_| column.append_value(n));
    }
    Arc::new(column.finish())
}

fn cat<T: Copy>(parts: impl Iterator<Item = Vec<T>>) -> Vec<T> {
    parts.flatten().collect()
}

/// `tracks.parquet` as it is written, method by method (the methods' columns are not
/// concatenated in memory first, each track let go once written): the rows of the
/// tracks given so far are encoded (those of each full row group in the file), so that
/// the methods known first are written while the others are still worked out.
pub struct TracksWriter<'t> {
    sink: ParquetSink,
    schema: SchemaRef,
    t_ns: &'t [i64],
    /// North and east are taken in it.
    frame: LocalFrame,
    /// The methods written so far.
    methods: usize,
}

impl<'t> TracksWriter<'t> {
    /// The file at `path` (put in place by [`Self::finish`]), of the tracks kept at
    /// times `t_ns`, north and east of `start`.
    pub fn create(path: &Path, t_ns: &'t [i64], start: Geodetic) -> anyhow::Result<Self> {
        let schema = schema::tracks();
        // Row groups of 65 536 rows: the writer holds that many encoded rows, not a
        // method's whole track.
        let sink = ParquetSink::create_in_row_groups(path, schema.clone(), 1 << 16)?;
        Ok(Self {
            sink,
            schema,
            t_ns,
            frame: start.local_frame(),
            methods: 0,
        })
    }

    /// The methods' tracks written so far.
    pub fn methods(&self) -> usize {
        self.methods
    }

    /// Writes the rows of the next method's track `t`: its kept columns become the
    /// batch's (no copy) and go once written.
    pub fn push(&mut self, t: KeptTrack) -> anyhow::Result<()> {
        let t_ns = self.t_ns;
        let rows = t.lat_rad.len();
        anyhow::ensure!(
            rows <= t_ns.len(),
            "{}'s track has {rows} rows for the times of {} kept samples",
            t.method,
            t_ns.len()
        );
        let frame = &self.frame;
        let (north_m, east_m): (Vec<f32>, Vec<f32>) = t
            .lat_rad
            .iter()
            .zip(&t.lon_rad)
            .map(|(&lat, &lon)| {
                let (n, e) = frame.offset_m(lat, lon);
                (n as f32, e as f32)
            })
            .unzip();
        // The track's radians become the file's degrees in place.
        let degrees = |mut v: Vec<f64>| {
            v.iter_mut().for_each(|x| *x = x.to_degrees());
            Arc::new(Float64Array::from(v))
        };
        let batch = RecordBatch::try_new(
            self.schema.clone(),
            vec![
                method_column(std::iter::once((t.method.as_str(), rows))),
                Arc::new(Int64Array::from(t_ns[..rows].to_vec())),
                degrees(t.lat_rad),
                degrees(t.lon_rad),
                Arc::new(Float32Array::from(t.h_m)),
                Arc::new(Float32Array::from(north_m)),
                Arc::new(Float32Array::from(east_m)),
                Arc::new(Float32Array::from(t.roll_deg)),
                Arc::new(Float32Array::from(t.pitch_deg)),
                Arc::new(Float32Array::from(t.heading_deg)),
            ],
        )?;
        self.sink.write(&batch)?;
        self.methods += 1;
        Ok(())
    }

    /// Writes the last rows and the footer, and puts the file in place.
    pub fn finish(self) -> anyhow::Result<()> {
        self.sink.finish()?;
        Ok(())
    }
}

/// Writes `kryt1_series.parquet`.
pub fn write_kryt1_series(path: &Path, series: &[MethodKryt1]) -> anyhow::Result<()> {
    let schema = schema::kryt1_series();
    let col = |get: fn(&MethodKryt1) -> &Vec<f64>| {
        Arc::new(Float64Array::from(cat(series
            .iter()
            .map(|t| get(t).clone()))))
    };
    let batch = RecordBatch::try_new(
        schema,
        vec![
            method_column(series.iter().map(|s| (s.method.as_str(), s.t_ns.len()))),
            Arc::new(Int64Array::from(cat(series.iter().map(|s| s.t_ns.clone())))),
            col(|s| &s.kryt1_cum),
            col(|s| &s.kf_d_theta_rad),
            col(|s| &s.kf_d_phi_rad),
        ],
    )?;
    write_batch(path, &batch)?;
    Ok(())
}

/// The rows of each method in `path` (its `method` column and the columns `names`), read
/// batch by batch: a method's rows are consecutive, and `extend` adds each run of them in
/// a batch to the method's value. Each method's name and value, in file order.
fn read_per_method<T: Default>(
    path: &Path,
    names: &[&str],
    mut extend: impl FnMut(&mut T, &RecordBatch, std::ops::Range<usize>) -> Result<(), FormatError>,
) -> anyhow::Result<Vec<(String, T)>> {
    let mut columns = vec![schema::METHOD];
    columns.extend_from_slice(names);
    let mut out: Vec<(String, T)> = Vec::new();
    for_each_batch_of(path, &columns, |b| {
        let methods = b
            .column_by_name(schema::METHOD)
            .and_then(|c| c.as_any().downcast_ref::<StringArray>())
            .ok_or_else(|| FormatError::Invalid("no string column \"method\"".into()))?;
        let n = methods.len();
        let mut from = 0;
        while from < n {
            let m = methods.value(from);
            let to = (from..n).find(|&k| methods.value(k) != m).unwrap_or(n);
            if out.last().is_none_or(|(last, _)| last != m) {
                out.push((m.to_owned(), T::default()));
            }
            let (_, value) = out.last_mut().expect("a method was started");
            extend(value, b, from..to)?;
            from = to;
        }
        Ok(())
    })?;
    Ok(out)
}

/// Reads `tracks.parquet` into each method's columns: the methods and times through
/// Arrow, the float columns page by page with their byte streams joined
/// ([`for_each_split_page`]) where their layout is the tables', else batch by batch
/// through Arrow.
pub fn read_tracks(path: &Path) -> anyhow::Result<Vec<MethodTrack>> {
    match read_tracks_split(path)? {
        Some(tracks) => Ok(tracks),
        None => read_tracks_arrow(path),
    }
}

/// A float column of [`MethodTrack`]: its name and where a method's values go.
type TrackColumn<F> = (&'static str, fn(&mut MethodTrack) -> &mut Vec<F>);

/// [`MethodTrack`]'s f64 columns, then its f32 ones, in the table's order.
fn track_columns() -> ([TrackColumn<f64>; 2], [TrackColumn<f32>; 6]) {
    let [lat, lon, h, north, east, roll, pitch, heading] = schema::NAV_STATE;
    (
        [(lat, |t| &mut t.lat_deg), (lon, |t| &mut t.lon_deg)],
        [
            (h, |t| &mut t.h_m),
            (north, |t| &mut t.north_m),
            (east, |t| &mut t.east_m),
            (roll, |t| &mut t.roll_deg),
            (pitch, |t| &mut t.pitch_deg),
            (heading, |t| &mut t.heading_deg),
        ],
    )
}

/// Each of `columns` of the tracks (their methods' rows ending at `ends`) filled page by
/// page, each method's column sized for its rows first; `false` when a column is not of
/// the tables' layout (its type among them: the pages' reader checks it).
fn split_track_columns<F: SplitFloat>(
    path: &Path,
    columns: &[TrackColumn<F>],
    ends: &[usize],
    tracks: &mut [MethodTrack],
) -> anyhow::Result<bool> {
    for &(name, field) in columns {
        for t in tracks.iter_mut() {
            let rows = t.t_ns.len();
            field(t).reserve_exact(rows);
        }
        let mut method = 0;
        let whole = for_each_split_page::<F>(path, name, |first, v| {
            per_method_rows(ends, &mut method, first, v, |m, part| {
                field(&mut tracks[m]).extend_from_slice(part);
            });
        })?;
        if !whole {
            return Ok(false);
        }
        for t in tracks.iter_mut() {
            let (rows, len) = (t.t_ns.len(), field(t).len());
            anyhow::ensure!(
                len == rows,
                "{}: {name} has {len} rows of {} for {rows}",
                path.display(),
                t.method
            );
        }
    }
    Ok(true)
}

/// Hands each method's part of a page's values (rows `first..`) to `put`: the methods'
/// rows end at `ends` (increasing), `method` the one the page's first row is in.
fn per_method_rows<F>(
    ends: &[usize],
    method: &mut usize,
    first: usize,
    values: &[F],
    mut put: impl FnMut(usize, &[F]),
) {
    let mut at = 0;
    while at < values.len() && *method < ends.len() {
        let row = first + at;
        if row >= ends[*method] {
            *method += 1;
            continue;
        }
        let take = (ends[*method] - row).min(values.len() - at);
        put(*method, &values[at..at + take]);
        at += take;
    }
}

/// [`read_tracks`] with the floats' pages joined; `None` when a column is not of the
/// tables' layout.
fn read_tracks_split(path: &Path) -> anyhow::Result<Option<Vec<MethodTrack>>> {
    let mut tracks: Vec<MethodTrack> =
        read_per_method(path, &[schema::T_NS], |t: &mut MethodTrack, b, r| {
            t.t_ns
                .extend_from_slice(&values_of::<Int64Type>(b, schema::T_NS)?[r]);
            Ok(())
        })?
        .into_iter()
        .map(|(method, t)| MethodTrack { method, ..t })
        .collect();
    let ends: Vec<usize> = tracks
        .iter()
        .scan(0, |end, t| {
            *end += t.t_ns.len();
            Some(*end)
        })
        .collect();
    let (f64_columns, f32_columns) = track_columns();
    let whole = split_track_columns(path, &f64_columns, &ends, &mut tracks)?
        && split_track_columns(path, &f32_columns, &ends, &mut tracks)?;
    Ok(whole.then_some(tracks))
}

/// [`read_tracks`] through Arrow, batch by batch into each method's columns.
fn read_tracks_arrow(path: &Path) -> anyhow::Result<Vec<MethodTrack>> {
    let [lat, lon, h, north, east, roll, pitch, heading] = schema::NAV_STATE;
    let names = [schema::T_NS, lat, lon, h, north, east, roll, pitch, heading];
    let tracks = read_per_method(path, &names, |t: &mut MethodTrack, b, r| {
        t.t_ns
            .extend_from_slice(&values_of::<Int64Type>(b, schema::T_NS)?[r.clone()]);
        for (v, name) in [(&mut t.lat_deg, lat), (&mut t.lon_deg, lon)] {
            v.extend_from_slice(&values_of::<Float64Type>(b, name)?[r.clone()]);
        }
        for (v, name) in [
            (&mut t.h_m, h),
            (&mut t.north_m, north),
            (&mut t.east_m, east),
            (&mut t.roll_deg, roll),
            (&mut t.pitch_deg, pitch),
            (&mut t.heading_deg, heading),
        ] {
            v.extend_from_slice(&values_of::<Float32Type>(b, name)?[r.clone()]);
        }
        Ok(())
    })?;
    Ok(tracks
        .into_iter()
        .map(|(method, t)| MethodTrack { method, ..t })
        .collect())
}

/// Reads `kryt1_series.parquet`, batch by batch into each method's series.
pub fn read_kryt1_series(path: &Path) -> anyhow::Result<Vec<MethodKryt1>> {
    let [kryt1, theta, phi] = [
        criteria_cols::KRYT1_CUM,
        criteria_cols::KF_D_THETA_RAD,
        criteria_cols::KF_D_PHI_RAD,
    ];
    let series = read_per_method(
        path,
        &[schema::T_NS, kryt1, theta, phi],
        |s: &mut MethodKryt1, b, r| {
            s.t_ns
                .extend_from_slice(&values_of::<Int64Type>(b, schema::T_NS)?[r.clone()]);
            for (v, name) in [
                (&mut s.kryt1_cum, kryt1),
                (&mut s.kf_d_theta_rad, theta),
                (&mut s.kf_d_phi_rad, phi),
            ] {
                v.extend_from_slice(&values_of::<Float64Type>(b, name)?[r.clone()]);
            }
            Ok(())
        },
    )?;
    Ok(series
        .into_iter()
        .map(|(method, s)| MethodKryt1 { method, ..s })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `tracks` written to `path` by a [`TracksWriter`] in one go.
    fn write_tracks(
        path: &Path,
        t_ns: &[i64],
        start: Geodetic,
        tracks: Vec<KeptTrack>,
    ) -> anyhow::Result<()> {
        let mut file = TracksWriter::create(path, t_ns, start)?;
        for t in tracks {
            file.push(t)?;
        }
        file.finish()
    }

    /// The tracks' start in the tests.
    const START: Geodetic = Geodetic {
        lat_rad: 0.78,
        lon_rad: -1.33,
        h_m: 90.0,
    };

    /// A track built row by row holds each row's angles as `euler_deg_f32` gives them
    /// (taken four at a time, the last ones at its end), and its positions as they came.
    #[test]
    fn a_track_built_row_by_row_holds_each_rows_angles() {
        use unz_stages::euler_f32::euler_deg_f32;
        for rows in [0, 1, 3, 4, 5, 8, 11] {
            let mut b = TrackBuilder::new("joint", rows);
            let row = |i: usize| {
                let e = unz_stages::attitude::Euler {
                    roll_rad: 0.01 * i as f64 - 0.02,
                    pitch_rad: -0.003 * i as f64,
                    // Across north: headings on both sides of the wrap.
                    heading_rad: 0.3 * i as f64 - 1.0,
                };
                let q = e.to_quat_b_to_n();
                (
                    0.8 + 1e-6 * i as f64,
                    0.5,
                    100.0 + i as f64,
                    [q.w, q.i, q.j, q.k],
                )
            };
            for i in 0..rows {
                b.keep(i, row(i));
            }
            let t = b.finish();
            assert_eq!(t.lat_rad.len(), rows);
            assert_eq!(t.roll_deg.len(), rows);
            for i in 0..rows {
                let (lat, _, h, q) = row(i);
                let [roll, pitch, heading] = euler_deg_f32(&q, HeadingDeg::Wrapped);
                assert_eq!(t.lat_rad[i], lat);
                assert_eq!(t.h_m[i], h as f32);
                assert_eq!(
                    [t.roll_deg[i], t.pitch_deg[i], t.heading_deg[i]].map(f32::to_bits),
                    [roll, pitch, heading].map(f32::to_bits),
                    "row {i} of {rows}"
                );
                assert!((0.0..360.0).contains(&t.heading_deg[i]));
            }
        }
    }

    #[test]
    fn decimation_keeps_the_rate_and_the_last_sample() {
        assert_eq!(decimation_indices(25, 0.01, 10.0), vec![0, 10, 20, 24]);
        assert_eq!(decimation_indices(21, 0.01, 10.0), vec![0, 10, 20]);
        assert_eq!(decimation_indices(3, 0.5, 10.0), vec![0, 1, 2]);
        assert!(decimation_indices(0, 0.01, 10.0).is_empty());
    }

    #[test]
    fn tables_round_trip_per_method() {
        let dir = tempfile::tempdir().unwrap();
        let start = START;
        let kept = |m: &str, n: usize, off: f64| KeptTrack {
            method: m.to_owned(),
            lat_rad: (0..n).map(|k| 0.78 + off * 1e-5 * k as f64).collect(),
            lon_rad: (0..n).map(|k| -1.33 - off * 2e-5 * k as f64).collect(),
            h_m: vec![2.0; n],
            roll_deg: vec![5.0; n],
            pitch_deg: vec![6.0; n],
            heading_deg: vec![7.0; n],
        };
        let tracks = vec![kept("initial", 3, 0.5), kept("joint", 2, 1.5)];
        let t_ns = [1_000, 2_000, 3_000];
        let p = dir.path().join(TRACKS);
        write_tracks(&p, &t_ns, start, tracks.clone()).unwrap();
        // Times from the kept samples', degrees and local offsets from the positions.
        let want: Vec<MethodTrack> = tracks
            .iter()
            .map(|t| {
                let n = t.lat_rad.len();
                let ne: Vec<(f64, f64)> = (0..n)
                    .map(|k| start.offset_m(t.lat_rad[k], t.lon_rad[k]))
                    .collect();
                MethodTrack {
                    method: t.method.clone(),
                    t_ns: t_ns[..n].to_vec(),
                    lat_deg: t.lat_rad.iter().map(|x| x.to_degrees()).collect(),
                    lon_deg: t.lon_rad.iter().map(|x| x.to_degrees()).collect(),
                    h_m: t.h_m.clone(),
                    north_m: ne.iter().map(|p| p.0 as f32).collect(),
                    east_m: ne.iter().map(|p| p.1 as f32).collect(),
                    roll_deg: t.roll_deg.clone(),
                    pitch_deg: t.pitch_deg.clone(),
                    heading_deg: t.heading_deg.clone(),
                }
            })
            .collect();
        assert_eq!(read_tracks(&p).unwrap(), want);
        assert!(want[1].north_m[1] > 0.1 && want[1].east_m[1] < -0.1);
        // A track longer than the kept samples' times is refused, naming the method.
        let long = vec![kept("oepi", 4, 0.5)];
        let err = write_tracks(&dir.path().join("long.parquet"), &t_ns, start, long)
            .unwrap_err()
            .to_string();
        assert!(err.contains("oepi"), "{err}");
        let series = vec![MethodKryt1 {
            method: "oepi".into(),
            t_ns: vec![1, 2],
            kryt1_cum: vec![0.0, 1.0],
            kf_d_theta_rad: vec![0.1, 0.2],
            kf_d_phi_rad: vec![0.3, 0.4],
        }];
        let p = dir.path().join(KRYT1_SERIES);
        write_kryt1_series(&p, &series).unwrap();
        assert_eq!(read_kryt1_series(&p).unwrap(), series);
    }

    #[test]
    fn methods_are_read_whole_across_the_readers_batches() {
        // Each method longer than a reader's batch (65536 rows), the second one starting
        // within a batch: every row comes back in its method, in order.
        let dir = tempfile::tempdir().unwrap();
        let start = START;
        let n = 70_001;
        let kept = |m: &str, off: f64| KeptTrack {
            method: m.to_owned(),
            lat_rad: (0..n).map(|k| 0.78 + off * 1e-9 * k as f64).collect(),
            lon_rad: (0..n).map(|k| -1.33 - off * 2e-9 * k as f64).collect(),
            h_m: (0..n).map(|k| k as f32 * 0.5).collect(),
            roll_deg: (0..n).map(|k| (k % 360) as f32).collect(),
            pitch_deg: vec![6.0; n],
            heading_deg: (0..n).map(|k| (k % 7) as f32).collect(),
        };
        let tracks = vec![kept("initial", 0.5), kept("owpi", 1.0), kept("joint", 1.5)];
        let t_ns: Vec<i64> = (0..n as i64).map(|k| 1_000 + 10 * k).collect();
        let p = dir.path().join(TRACKS);
        write_tracks(&p, &t_ns, start, tracks.clone()).unwrap();
        let read = read_tracks(&p).unwrap();
        // Page by page (taken: the tables' layout) and through Arrow, the same tracks.
        assert_eq!(read_tracks_split(&p).unwrap().as_ref(), Some(&read));
        assert_eq!(read_tracks_arrow(&p).unwrap(), read);
        // The same table in Arrow's plain encodings: read through Arrow, the same tracks.
        let plain = dir.path().join("plain.parquet");
        crate::picked_rows::plain_copy(&p, &plain);
        assert_eq!(read_tracks_split(&plain).unwrap(), None);
        assert_eq!(read_tracks(&plain).unwrap(), read);
        let methods: Vec<&str> = read.iter().map(|t| t.method.as_str()).collect();
        assert_eq!(methods, ["initial", "owpi", "joint"]);
        for (t, k) in read.iter().zip(&tracks) {
            assert_eq!(t.t_ns, t_ns);
            assert_eq!(t.h_m, k.h_m);
            assert_eq!(t.roll_deg, k.roll_deg);
            assert_eq!(t.heading_deg, k.heading_deg);
            let lat: Vec<f64> = k.lat_rad.iter().map(|x| x.to_degrees()).collect();
            assert_eq!(t.lat_deg, lat);
        }
        let series: Vec<MethodKryt1> = ["oepi", "joint"]
            .iter()
            .enumerate()
            .map(|(i, m)| MethodKryt1 {
                method: (*m).into(),
                t_ns: (0..n as i64).collect(),
                kryt1_cum: (0..n).map(|k| (k + i) as f64).collect(),
                kf_d_theta_rad: vec![0.1; n],
                kf_d_phi_rad: (0..n).map(|k| -(k as f64)).collect(),
            })
            .collect();
        let p = dir.path().join(KRYT1_SERIES);
        write_kryt1_series(&p, &series).unwrap();
        assert_eq!(read_kryt1_series(&p).unwrap(), series);
    }

    #[test]
    fn a_table_without_methods_is_refused_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(TRACKS);
        let schema = Arc::new(arrow::datatypes::Schema::new(vec![
            arrow::datatypes::Field::new(schema::T_NS, arrow::datatypes::DataType::Int64, false),
        ]));
        let b =
            RecordBatch::try_new(schema, vec![Arc::new(Int64Array::from(vec![1_i64]))]).unwrap();
        write_batch(&p, &b).unwrap();
        let err = format!("{:#}", read_tracks(&p).unwrap_err());
        assert!(err.contains("tracks.parquet"), "{err}");
    }
}
