//! The disupt stage's per-method tables, written for review: each method's trajectory
//! (`tracks.parquet`, decimated to [`TRACK_RATE_HZ`]) and its Kryt1 series
//! (`kryt1_series.parquet`, at the ΔTg epochs), in long form with a `method` column
//! (`initial` for the settings before DISUPT). Reading them back never navigates.

use std::path::Path;
use std::sync::Arc;

use arrow::array::{Float32Array, Float64Array, Int64Array, RecordBatch, StringArray};
use unz_formats::parquet_io::{ParquetSink, read_table, write_batch};
use unz_formats::schema::{self, criteria_cols};
use unz_formats::tables::{f32_column, f64_column, i64_column};
use unz_stages::criteria::Kryt1Series;
use unz_stages::derive::Derived;
use unz_stages::earth::Geodetic;
use unz_stages::strapdown::{KeepRows, TrackRow, euler_of, samples_every};

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

/// One method's trajectory built as its pass reaches the kept samples (see
/// [`decimation_indices`]; a [`KeepRows`]), with local offsets from `start`: no state of
/// the pass is stored beside it.
pub struct TrackBuilder<'d> {
    d: &'d Derived,
    start: Geodetic,
    track: MethodTrack,
}

impl<'d> TrackBuilder<'d> {
    /// For `method`'s pass over `d`, keeping `rows` samples.
    pub fn new(method: &str, d: &'d Derived, rows: usize, start: Geodetic) -> Self {
        Self {
            d,
            start,
            track: MethodTrack {
                method: method.to_owned(),
                t_ns: Vec::with_capacity(rows),
                lat_deg: Vec::with_capacity(rows),
                lon_deg: Vec::with_capacity(rows),
                h_m: Vec::with_capacity(rows),
                north_m: Vec::with_capacity(rows),
                east_m: Vec::with_capacity(rows),
                roll_deg: Vec::with_capacity(rows),
                pitch_deg: Vec::with_capacity(rows),
                heading_deg: Vec::with_capacity(rows),
            },
        }
    }

    /// The trajectory.
    pub fn finish(self) -> MethodTrack {
        self.track
    }
}

impl KeepRows for TrackBuilder<'_> {
    fn keep(&mut self, k: usize, (lat, lon, h, q): TrackRow) {
        let (d, m) = (self.d, &mut self.track);
        let (n, e) = self.start.offset_m(lat, lon);
        let att = euler_of(&q);
        m.t_ns.push(d.ns_of(d.t_s.get(k)));
        m.lat_deg.push(lat.to_degrees());
        m.lon_deg.push(lon.to_degrees());
        m.h_m.push(h as f32);
        m.north_m.push(n as f32);
        m.east_m.push(e as f32);
        m.roll_deg.push(att.roll_rad.to_degrees() as f32);
        m.pitch_deg.push(att.pitch_rad.to_degrees() as f32);
        m.heading_deg
            .push(att.heading_rad.to_degrees().rem_euclid(360.0) as f32);
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

fn method_column<'a>(names: impl Iterator<Item = (&'a str, usize)>) -> Arc<StringArray> {
    let values: Vec<&str> = names
        .flat_map(|(n, len)| std::iter::repeat_n(n, len))
        .collect();
    Arc::new(StringArray::from(values))
}

fn cat<T: Copy>(parts: impl Iterator<Item = Vec<T>>) -> Vec<T> {
    parts.flatten().collect()
}

/// Writes `tracks.parquet`, one method's rows at a time (the methods' columns are not
/// concatenated in memory first), each track let go once written.
pub fn write_tracks(path: &Path, tracks: Vec<MethodTrack>) -> anyhow::Result<()> {
    let schema = schema::tracks();
    // Row groups of 65 536 rows: the writer holds that many encoded rows, not a
    // method's whole track.
    let mut sink = ParquetSink::create_in_row_groups(path, schema.clone(), 1 << 16)?;
    // Each track's columns become the batch's (no copy) and go once written.
    for t in tracks {
        let batch = RecordBatch::try_new(
            schema.clone(),
            vec![
                method_column(std::iter::once((t.method.as_str(), t.t_ns.len()))),
                Arc::new(Int64Array::from(t.t_ns)),
                Arc::new(Float64Array::from(t.lat_deg)),
                Arc::new(Float64Array::from(t.lon_deg)),
                Arc::new(Float32Array::from(t.h_m)),
                Arc::new(Float32Array::from(t.north_m)),
                Arc::new(Float32Array::from(t.east_m)),
                Arc::new(Float32Array::from(t.roll_deg)),
                Arc::new(Float32Array::from(t.pitch_deg)),
                Arc::new(Float32Array::from(t.heading_deg)),
            ],
        )?;
        sink.write(&batch)?;
    }
    sink.finish()?;
    Ok(())
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

/// Row ranges of each method, in file order.
fn method_ranges(
    b: &RecordBatch,
    path: &Path,
) -> anyhow::Result<Vec<(String, std::ops::Range<usize>)>> {
    let methods = b
        .column_by_name(schema::METHOD)
        .and_then(|c| c.as_any().downcast_ref::<StringArray>())
        .ok_or_else(|| anyhow::anyhow!("{}: no string column \"method\"", path.display()))?;
    let mut ranges: Vec<(String, std::ops::Range<usize>)> = Vec::new();
    for (k, m) in methods.iter().enumerate() {
        let m = m.unwrap_or_default();
        match ranges.last_mut() {
            Some((name, r)) if name == m => r.end = k + 1,
            _ => ranges.push((m.to_owned(), k..k + 1)),
        }
    }
    Ok(ranges)
}

/// Reads `tracks.parquet`.
pub fn read_tracks(path: &Path) -> anyhow::Result<Vec<MethodTrack>> {
    let (_, b) = read_table(path)?;
    let t = i64_column(&b, schema::T_NS)?;
    let [lat, lon, rest @ ..] = schema::NAV_STATE;
    let (lat, lon) = (f64_column(&b, lat)?, f64_column(&b, lon)?);
    let cols: Vec<Vec<f32>> = rest
        .iter()
        .map(|n| f32_column(&b, n))
        .collect::<Result<_, _>>()?;
    Ok(method_ranges(&b, path)?
        .into_iter()
        .map(|(method, r)| MethodTrack {
            method,
            t_ns: t[r.clone()].to_vec(),
            lat_deg: lat[r.clone()].to_vec(),
            lon_deg: lon[r.clone()].to_vec(),
            h_m: cols[0][r.clone()].to_vec(),
            north_m: cols[1][r.clone()].to_vec(),
            east_m: cols[2][r.clone()].to_vec(),
            roll_deg: cols[3][r.clone()].to_vec(),
            pitch_deg: cols[4][r.clone()].to_vec(),
            heading_deg: cols[5][r].to_vec(),
        })
        .collect())
}

/// Reads `kryt1_series.parquet`.
pub fn read_kryt1_series(path: &Path) -> anyhow::Result<Vec<MethodKryt1>> {
    let (_, b) = read_table(path)?;
    let t = i64_column(&b, schema::T_NS)?;
    let (k, th, ph) = (
        f64_column(&b, criteria_cols::KRYT1_CUM)?,
        f64_column(&b, criteria_cols::KF_D_THETA_RAD)?,
        f64_column(&b, criteria_cols::KF_D_PHI_RAD)?,
    );
    Ok(method_ranges(&b, path)?
        .into_iter()
        .map(|(method, r)| MethodKryt1 {
            method,
            t_ns: t[r.clone()].to_vec(),
            kryt1_cum: k[r.clone()].to_vec(),
            kf_d_theta_rad: th[r.clone()].to_vec(),
            kf_d_phi_rad: ph[r].to_vec(),
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let mk = |m: &str, n: usize, off: f64| MethodTrack {
            method: m.to_owned(),
            t_ns: (0..n as i64).collect(),
            lat_deg: vec![off; n],
            lon_deg: vec![off + 1.0; n],
            h_m: vec![2.0; n],
            north_m: vec![3.0; n],
            east_m: vec![4.0; n],
            roll_deg: vec![5.0; n],
            pitch_deg: vec![6.0; n],
            heading_deg: vec![7.0; n],
        };
        let tracks = vec![mk("initial", 3, 0.5), mk("joint", 2, 1.5)];
        let p = dir.path().join(TRACKS);
        write_tracks(&p, tracks.clone()).unwrap();
        assert_eq!(read_tracks(&p).unwrap(), tracks);
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
}
