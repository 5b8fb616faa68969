//! Writing one run's review as a Rerun recording (`.rrd`).
//!
//! Series go out with `send_columns` (one chunk per series, never one log call per
//! sample). Raw-rate series are decimated to [`SERIES_RATE_HZ`] block means and the
//! vehicle pose to [`POSE_RATE_HZ`]; trajectories arrive already decimated by the
//! disupt stage. The recording is encoded into a temporary file as it is logged
//! (the crate's `rrd_sink`) and renamed when complete.

use std::path::{Path, PathBuf};

use rerun::external::re_log_encoding::EncodeError;
use rerun::{RecordingStream, TimeColumn};

use crate::blueprint::send_review_blueprint;
use crate::frames::enu_flu_xyzw;
use crate::paths::*;
use crate::review::{Review, Track, color_of, display_name};
use unz_stages::attitude::Euler;

/// Rate of the raw-rate series in the recording, Hz.
pub const SERIES_RATE_HZ: f64 = 10.0;
/// Rate of the vehicle's pose and map position, Hz.
pub const POSE_RATE_HZ: f64 = 2.0;

/// A recording that could not be written. The cause is the error's source, not repeated in
/// its message.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordingError {
    /// The Rerun SDK refused the data or the file.
    #[error("the Rerun SDK refused the recording {path}")]
    Rerun {
        /// What the SDK said.
        source: rerun::RecordingStreamError,
        /// The recording.
        path: PathBuf,
    },
    /// The recording could not be encoded.
    #[error("cannot encode the recording: {message} (writing {path})")]
    Flush {
        /// What the SDK said.
        message: String,
        /// The recording.
        path: PathBuf,
    },
    /// A file operation failed.
    #[error("cannot write {path}")]
    Io {
        /// The I/O error.
        source: std::io::Error,
        /// The file.
        path: PathBuf,
    },
}

/// What was written.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RrdStats {
    /// Rows sent over all entities (one per time point and entity).
    pub rows: usize,
    /// Entities with data.
    pub entities: usize,
    /// Size of the file, bytes.
    pub bytes: u64,
}

/// Writes `review` to `path` atomically and returns what it wrote.
///
/// The recording is encoded into a temporary file as it is logged (no copy is held in
/// memory) by our own sink, not by the SDK's file-writer thread: a full disk or a
/// read-only folder then reports the operating system's own error ("No space left on
/// device") with the path, where the SDK's writer says only that its thread shut down.
/// The file takes its name when complete.
pub fn write_rrd(review: &Review, path: &Path) -> Result<RrdStats, RecordingError> {
    let tmp = tmp_name(path);
    let written = write_rrd_to(review, path, &tmp);
    match written {
        Ok(mut stats) => {
            let io = |source| RecordingError::Io {
                source,
                path: path.to_path_buf(),
            };
            stats.bytes = std::fs::metadata(&tmp).map_err(io)?.len();
            std::fs::rename(&tmp, path).map_err(io)?;
            Ok(stats)
        }
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// [`write_rrd`] into `tmp`.
fn write_rrd_to(review: &Review, path: &Path, tmp: &Path) -> Result<RrdStats, RecordingError> {
    let rerun_err = |source| RecordingError::Rerun {
        source,
        path: path.to_path_buf(),
    };
    let encode_err = |e: EncodeError| match e {
        EncodeError::Write(source) => RecordingError::Io {
            source,
            path: path.to_path_buf(),
        },
        e => RecordingError::Flush {
            message: e.to_string(),
            path: path.to_path_buf(),
        },
    };
    let (sink, file) = crate::rrd_sink::create(tmp, review.name.as_str()).map_err(encode_err)?;
    let rec = rerun::RecordingStreamBuilder::new("unz-review")
        .recording_id(review.name.as_str())
        .recording_name(review.name.as_str())
        .batcher_config(crate::rrd_sink::IN_LOGGED_ORDER)
        .buffered()
        .map_err(rerun_err)?;
    rec.set_sink(Box::new(sink));
    crate::rrd_sink::without_wall_clock(&rec);
    // A set recording id turns the SDK's own recording-info chunk off (and with it the
    // name, which the viewer's sources panel then shows as `<unknown>`): send the name.
    rec.send_recording_name(review.name.as_str())
        .map_err(rerun_err)?;
    let mut w = Writer {
        rec: &rec,
        stats: RrdStats::default(),
        unflushed_rows: 0,
    };
    w.write(review).map_err(rerun_err)?;
    send_review_blueprint(&rec, review).map_err(rerun_err)?;
    let stats = w.stats;
    // Every message through the batcher into the sink, then the stream let go of it.
    let _ = rec.flush_blocking();
    drop(rec);
    file.finish().map_err(encode_err)?;
    Ok(stats)
}

/// `.<name>.<pid>.tmp` beside `path`: the pattern the stage records clear when a killed
/// run left one.
fn tmp_name(path: &Path) -> PathBuf {
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(format!(".{}.tmp", std::process::id()));
    path.with_file_name(name)
}

type SdkResult<T> = Result<T, rerun::RecordingStreamError>;

struct Writer<'a> {
    rec: &'a RecordingStream,
    stats: RrdStats,
    /// Rows sent since the stream was last flushed.
    unflushed_rows: usize,
}

/// Rows sent before the stream is flushed: the SDK queues what is sent until its sink has
/// encoded it, and the series are built faster than they are encoded, so without a bound a
/// 12-hour run's queue held some 180 MB of them.
const FLUSH_EVERY_ROWS: usize = 1 << 18;

impl Writer<'_> {
    /// Counts `rows` sent ([`Self::queued`]).
    fn sent(&mut self, rows: usize) {
        self.stats.rows += rows;
        self.queued(rows);
    }

    /// Counts `rows` (or points) queued, and waits for the queue to drain once
    /// [`FLUSH_EVERY_ROWS`] have been (a failed flush shows as the sink's error when the
    /// file is finished).
    fn queued(&mut self, rows: usize) {
        self.unflushed_rows += rows;
        if self.unflushed_rows >= FLUSH_EVERY_ROWS {
            let _ = self.rec.flush_blocking();
            self.unflushed_rows = 0;
        }
    }

    fn write(&mut self, r: &Review) -> SdkResult<()> {
        self.rec
            .log_static(README, &rerun::TextDocument::from_markdown(readme(r)))?;
        self.rec.log_static(
            DISUPT_TABLES,
            &rerun::TextDocument::from_markdown(r.tables_markdown.as_str()),
        )?;
        self.stats.entities += 2;
        self.trajectories(r)?;
        self.control_points(r)?;
        self.vehicle(r)?;
        self.criteria(r)?;
        self.sensors(r)?;
        self.sweep(r)?;
        Ok(())
    }

    /// The odometer's speed over its failures, as points on the speed's plot: the blocks
    /// that hold a failed sample, bridged (`plots/speed/bridged`) or held
    /// (`plots/speed/held`).
    fn odometer_failures(&mut self, r: &Review) -> SdkResult<()> {
        let b = &r.sensors;
        for (bridged, leaf, name, color) in [
            (
                true,
                "bridged",
                "odometer failed, bridged [m/s]",
                [214, 39, 40, 255],
            ),
            (
                false,
                "held",
                "odometer failed, held [m/s]",
                [127, 127, 127, 255],
            ),
        ] {
            let blocks = b.blocks_of(&r.odometer_failures, bridged);
            if blocks.is_empty() {
                continue;
            }
            let t_s: Vec<f64> = blocks.iter().map(|&k| b.t_s[k]).collect();
            let sample: Vec<i64> = blocks.iter().map(|&k| b.sample[k]).collect();
            let u: Vec<f64> = blocks.iter().map(|&k| b.u_mps[k]).collect();
            let path = format!("{PLOT_SPEED}/{leaf}");
            self.rec.log_static(
                path.as_str(),
                &rerun::SeriesPoints::new()
                    .with_names([name])
                    .with_colors([color])
                    .with_marker_sizes([2.5]),
            )?;
            let index = vec![
                TimeColumn::new_duration_secs(TIME, t_s.iter().copied()),
                TimeColumn::new_sequence(SAMPLE, sample.iter().copied()),
            ];
            self.rec.send_columns(
                path.as_str(),
                index,
                rerun::Scalars::new(u.iter().copied()).columns_of_unit_batches()?,
            )?;
            self.sent(t_s.len());
            self.stats.entities += 1;
        }
        Ok(())
    }

    /// One scalar series on `path` with its display name and colour.
    fn series(
        &mut self,
        path: &str,
        name: &str,
        color: [u8; 4],
        t_s: &[f64],
        sample: Option<&[i64]>,
        values: &[f64],
    ) -> SdkResult<()> {
        let n = t_s.len().min(values.len());
        if n == 0 {
            return Ok(());
        }
        self.rec.log_static(
            path,
            &rerun::SeriesLines::new()
                .with_names([name])
                .with_colors([color])
                .with_widths([1.5]),
        )?;
        let mut index = vec![TimeColumn::new_duration_secs(
            TIME,
            t_s[..n].iter().copied(),
        )];
        if let Some(s) = sample {
            index.push(TimeColumn::new_sequence(SAMPLE, s[..n].iter().copied()));
        }
        self.rec.send_columns(
            path,
            index,
            rerun::Scalars::new(values[..n].iter().copied()).columns_of_unit_batches()?,
        )?;
        self.sent(n);
        self.stats.entities += 1;
        Ok(())
    }

    fn trajectories(&mut self, r: &Review) -> SdkResult<()> {
        for t in &r.tracks {
            let color = color_of(&t.label);
            let label = display_name(&t.label);
            let geo: Vec<[f64; 2]> = t
                .lat_deg
                .iter()
                .zip(&t.lon_deg)
                .map(|(&a, &o)| [a, o])
                .collect();
            self.rec.log_static(
                format!("{MAP_TRAJECTORY}/{}", t.label),
                &rerun::GeoLineStrings::from_lat_lon([geo])
                    .with_colors([color])
                    .with_radii([rerun::Radius::new_ui_points(if t.label == "truth" {
                        1.5
                    } else {
                        2.0
                    })]),
            )?;
            let local: Vec<[f32; 3]> = (0..t.north_m.len())
                .map(|k| [t.east_m[k] as f32, t.north_m[k] as f32, t.up_m[k] as f32])
                .collect();
            self.rec.log_static(
                format!("{WORLD_TRAJECTORY}/{}", t.label),
                &rerun::LineStrips3D::new([local])
                    .with_colors([color])
                    .with_radii([rerun::Radius::new_ui_points(1.5)])
                    .with_labels([label])
                    // The routes overlap: their labels would pile up on the control
                    // points' (hovering a route names it; the colours are the plots').
                    .with_show_labels(false),
            )?;
            self.stats.rows += 2;
            self.stats.entities += 2;
            // Every point twice: on the map and in 3-D.
            self.queued(2 * t.north_m.len());
        }
        Ok(())
    }

    fn control_points(&mut self, r: &Review) -> SdkResult<()> {
        if r.control_points.is_empty() {
            return Ok(());
        }
        let cps = &r.control_points;
        self.rec.log_static(
            MAP_CONTROL_POINTS,
            &rerun::GeoPoints::from_lat_lon(cps.iter().map(|c| [c.lat_deg, c.lon_deg]))
                .with_colors([[31, 119, 180, 255]])
                .with_radii([rerun::Radius::new_ui_points(6.0)]),
        )?;
        // Just "CP n": close points' longer labels (with each settings' error) piled up
        // into an unreadable block. The errors are in the DISUPT tab's tables.
        let labels: Vec<String> = cps.iter().map(|c| format!("CP {}", c.id)).collect();
        self.rec.log_static(
            WORLD_CONTROL_POINTS,
            &rerun::Points3D::new(
                cps.iter()
                    .map(|c| [c.east_m as f32, c.north_m as f32, c.up_m as f32]),
            )
            .with_colors([[31, 119, 180, 255]])
            .with_radii([rerun::Radius::new_ui_points(6.0)])
            .with_labels(labels),
        )?;
        self.stats.rows += 2;
        self.stats.entities += 2;
        Ok(())
    }

    fn vehicle(&mut self, r: &Review) -> SdkResult<()> {
        self.rec
            .log_static(WORLD, &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())?;
        let Some(t) = vehicle_track(r) else {
            return Ok(());
        };
        let idx = pose_indices(t);
        let times = TimeColumn::new_duration_secs(TIME, idx.iter().map(|&k| t.t_s[k]));
        let translations = idx
            .iter()
            .map(|&k| [t.east_m[k] as f32, t.north_m[k] as f32, t.up_m[k] as f32]);
        let quats = idx.iter().map(|&k| {
            rerun::Quaternion::from_xyzw(enu_flu_xyzw(Euler {
                roll_rad: t.roll_deg[k].to_radians(),
                pitch_rad: t.pitch_deg[k].to_radians(),
                heading_rad: t.heading_deg[k].to_radians(),
            }))
        });
        self.rec.send_columns(
            WORLD_VEHICLE,
            [times.clone()],
            rerun::Transform3D::update_fields()
                .with_many_translation(translations)
                .with_many_quaternion(quats)
                .columns_of_unit_batches()?,
        )?;
        // The body in its own forward-left-up frame: a car-sized box and a forward arrow.
        self.rec.log_static(
            WORLD_VEHICLE_BODY,
            &rerun::Boxes3D::from_centers_and_half_sizes([[0.0, 0.0, 0.8]], [[2.3, 0.9, 0.8]])
                .with_colors([color_of(&t.label)]),
        )?;
        if let Some([f, r, d]) = r.mark_lever_arm_m {
            // Forward-right-down to the body's forward-left-up.
            self.rec.log_static(
                WORLD_VEHICLE_MARK,
                &rerun::Points3D::new([[f as f32, -r as f32, -d as f32]])
                    .with_colors([[31, 119, 180, 255]])
                    .with_radii([rerun::Radius::new_ui_points(6.0)])
                    .with_labels(["mark"]),
            )?;
            self.stats.rows += 1;
            self.stats.entities += 1;
        }
        self.rec.send_columns(
            MAP_VEHICLE,
            [times],
            rerun::GeoPoints::update_fields()
                .with_positions(idx.iter().map(|&k| [t.lat_deg[k], t.lon_deg[k]]))
                .columns_of_unit_batches()?,
        )?;
        self.rec.log_static(
            MAP_VEHICLE,
            &rerun::GeoPoints::update_fields()
                .with_colors([color_of(&t.label)])
                .with_radii([rerun::Radius::new_ui_points(8.0)]),
        )?;
        self.sent(2 * idx.len() + 1);
        self.stats.entities += 3;
        Ok(())
    }

    fn criteria(&mut self, r: &Review) -> SdkResult<()> {
        let e = &r.epochs;
        let (gyro, acc) = ([44, 160, 44, 255], [31, 119, 180, 255]);
        // (entity, display name, colour, series in rad): shown in degrees.
        let angles: [(String, &str, [u8; 4], &[f64]); 8] = [
            (
                format!("{PLOT_PITCH}/gyro"),
                "pitch Θn (gyro) [°]",
                gyro,
                &e.theta_gyro_rad,
            ),
            (
                format!("{PLOT_PITCH}/accel"),
                "pitch Θp (accelerometer) [°]",
                acc,
                &e.theta_acc_rad,
            ),
            (
                format!("{PLOT_ROLL}/gyro"),
                "roll Φn (gyro) [°]",
                gyro,
                &e.phi_gyro_rad,
            ),
            (
                format!("{PLOT_ROLL}/accel"),
                "roll Φp (accelerometer) [°]",
                acc,
                &e.phi_acc_rad,
            ),
            (
                format!("{PLOT_RESIDUALS}/d_theta"),
                "ΔΘ [°]",
                [174, 199, 232, 255],
                &e.d_theta_rad,
            ),
            (
                format!("{PLOT_RESIDUALS}/d_phi"),
                "ΔΦ [°]",
                [255, 187, 120, 255],
                &e.d_phi_rad,
            ),
            (
                format!("{PLOT_RESIDUALS}/kf_d_theta"),
                "ΔΘ Kalman [°]",
                [31, 119, 180, 255],
                &e.kf_d_theta_rad,
            ),
            (
                format!("{PLOT_RESIDUALS}/kf_d_phi"),
                "ΔΦ Kalman [°]",
                [255, 127, 14, 255],
                &e.kf_d_phi_rad,
            ),
        ];
        for (path, name, color, rad) in angles {
            let deg: Vec<f64> = rad.iter().map(|x| x.to_degrees()).collect();
            self.series(&path, name, color, &e.t_s, None, &deg)?;
        }
        if let Some(s) = &r.route_sigma {
            for (child, name, color, v) in [
                ("north", "σ north [m]", [31, 119, 180, 255], &s.north_m),
                ("east", "σ east [m]", [255, 127, 14, 255], &s.east_m),
                (
                    "heading",
                    "σ heading [°]",
                    [44, 160, 44, 255],
                    &s.heading_deg,
                ),
            ] {
                self.series(
                    &format!("{PLOT_ROUTE_SIGMA}/{child}"),
                    name,
                    color,
                    &s.t_s,
                    None,
                    v,
                )?;
            }
        }
        for k in &r.kryt1 {
            self.series(
                &format!("{PLOT_KRYT1}/{}", k.label),
                &format!("Kryt1, {} [rad]", display_name(&k.label)),
                color_of(&k.label),
                &k.t_s,
                None,
                &k.kryt1_cum_rad,
            )?;
        }
        Ok(())
    }

    fn sensors(&mut self, r: &Review) -> SdkResult<()> {
        let b = &r.sensors;
        let raw: [(String, &str, [u8; 4], &[f64]); 3] = [
            (
                format!("{PLOT_SPEED}/u"),
                "odometer speed u [m/s]",
                [31, 119, 180, 255],
                &b.u_mps,
            ),
            (
                format!("{PLOT_ACCEL_TERMS}/u_dot"),
                "u̇ [m/s²]",
                [174, 199, 232, 255],
                &b.u_dot_mps2,
            ),
            (
                format!("{PLOT_ACCEL_TERMS}/ru"),
                "ru [m/s²]",
                [255, 187, 120, 255],
                &b.ru_mps2,
            ),
        ];
        for (path, name, color, v) in raw {
            self.series(&path, name, color, &b.t_s, Some(&b.sample), v)?;
        }
        self.odometer_failures(r)?;
        let e = &r.epochs;
        let filtered: [(&str, &str, [u8; 4], &[f64]); 4] = [
            (
                "u_dot_f",
                "u̇ filtered [m/s²]",
                [31, 119, 180, 255],
                &e.u_dot_f_mps2,
            ),
            (
                "ru_f",
                "ru filtered [m/s²]",
                [255, 127, 14, 255],
                &e.ru_f_mps2,
            ),
            (
                "ax_f",
                "aₓ filtered [m/s²]",
                [44, 160, 44, 255],
                &e.ax_f_mps2,
            ),
            (
                "ay_f",
                "a_y filtered [m/s²]",
                [214, 39, 40, 255],
                &e.ay_f_mps2,
            ),
        ];
        for (leaf, name, color, v) in filtered {
            self.series(
                &format!("{PLOT_ACCEL_TERMS}/{leaf}"),
                name,
                color,
                &e.t_s,
                None,
                v,
            )?;
        }
        let axes = ["x", "y", "z"];
        let colors = [[214, 39, 40, 255], [44, 160, 44, 255], [31, 119, 180, 255]];
        for a in 0..3 {
            self.series(
                &format!("{PLOT_IMU_GYRO}/{}", axes[a]),
                &format!("ω{} body [°/s]", axes[a]),
                colors[a],
                &b.t_s,
                Some(&b.sample),
                &b.gyro_deg_s[a],
            )?;
            self.series(
                &format!("{PLOT_IMU_ACCEL}/{}", axes[a]),
                &format!("f{} body [m/s²]", axes[a]),
                colors[a],
                &b.t_s,
                Some(&b.sample),
                &b.accel_mps2[a],
            )?;
        }
        Ok(())
    }

    fn sweep(&mut self, r: &Review) -> SdkResult<()> {
        let Some(s) = &r.sweep else { return Ok(()) };
        match s.axes.as_slice() {
            [(name, values)] => {
                for (crit, v, color) in [
                    ("kryt1", &s.kryt1_rad, [31, 119, 180, 255]),
                    ("kryt2", &s.kryt2_m, [214, 39, 40, 255]),
                ] {
                    let strip: Vec<[f32; 2]> = values
                        .iter()
                        .zip(v)
                        .map(|(&x, &y)| [x as f32, y as f32])
                        .collect();
                    self.rec.log_static(
                        format!("{SENSITIVITY}/{crit}"),
                        &rerun::LineStrips2D::new([strip])
                            .with_colors([color])
                            .with_labels([format!("{crit} over {name}")]),
                    )?;
                    self.stats.rows += 1;
                    self.stats.entities += 1;
                }
            }
            [(a, va), (b, vb)] => {
                for (crit, v) in [("kryt1", &s.kryt1_rad), ("kryt2", &s.kryt2_m)] {
                    if v.len() != va.len() * vb.len() {
                        continue;
                    }
                    let data = rerun::datatypes::TensorData::new(
                        vec![va.len() as u64, vb.len() as u64],
                        rerun::datatypes::TensorBuffer::F64(v.clone().into()),
                    );
                    self.rec.log_static(
                        format!("{SENSITIVITY}/{crit}"),
                        &rerun::Tensor::new(data).with_dim_names([a.as_str(), b.as_str()]),
                    )?;
                    self.stats.rows += 1;
                    self.stats.entities += 1;
                }
            }
            _ => {}
        }
        Ok(())
    }
}

/// The track that drives the vehicle: the corrected one, else the initial one.
fn vehicle_track(r: &Review) -> Option<&Track> {
    let want = r.vehicle_track.as_deref().unwrap_or("initial");
    r.tracks
        .iter()
        .find(|t| t.label == want)
        .or_else(|| r.tracks.iter().find(|t| t.label == "initial"))
        .filter(|t| !t.t_s.is_empty())
}

/// Indices of a track kept at [`POSE_RATE_HZ`] (always the first and the last).
fn pose_indices(t: &Track) -> Vec<usize> {
    let mut idx = Vec::new();
    let mut next = f64::NEG_INFINITY;
    for (k, &ts) in t.t_s.iter().enumerate() {
        if ts >= next {
            idx.push(k);
            next = ts + 1.0 / POSE_RATE_HZ - 1e-9;
        }
    }
    if let Some(last) = t.t_s.len().checked_sub(1)
        && idx.last() != Some(&last)
    {
        idx.push(last);
    }
    idx
}

fn readme(r: &Review) -> String {
    format!(
        "# {name}\n\n{summary}\n\n\
## What is shown\n\
- **Map** and **Local ENU** (3D, metres east, north, up of the start): the trajectory with the \
initial settings (red), after OEPI (orange), OWPI (purple), joint (green) and the truth when \
it is known (dark grey); control points in blue, labelled with ΔX/ΔY (north/east, navigated \
minus surveyed) of each settings. The vehicle follows the corrected navigation ({vehicle}); \
its box is forward-left-up.\n\
- **Pitch / roll**: gyro (navigated, green) against accelerometer (blue) values at the ΔTg \
epochs with the initial settings; **residuals** ΔΘ, ΔΦ and their Kalman estimates; \
**Kryt1** cumulative for every settings (the paper's Fig. 1).\n\
- **Sensors**: odometer speed u (red points where the odometer failed and its distance was \
bridged by the inertial speed, grey where it held), the acceleration terms u̇ and ru with \
the filtered aₓ, a_y that Kryt1 compares, and the IMU's rates from its raw increments \
({rate} Hz block means).\n\
- **DISUPT**: the tables of each method, and the sensitivity maps when `unz sweep` ran.\n\n\
Timelines: `time` (s since the first IMU sample) and `sample` (raw IMU sample index, on \
raw-rate series).\n",
        name = r.name,
        summary = r.summary_markdown,
        vehicle = r.vehicle_track.as_deref().unwrap_or("initial"),
        rate = SERIES_RATE_HZ,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_indices_keep_the_rate_and_both_ends() {
        let t = Track {
            t_s: (0..25).map(|k| f64::from(k) * 0.1).collect(),
            ..Track::default()
        };
        assert_eq!(pose_indices(&t), vec![0, 5, 10, 15, 20, 24]);
    }
}
