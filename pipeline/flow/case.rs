//! A navigation case: the derive, the control points matched to its samples, and the
//! initial settings of the pass (overrides, the manifest, else the alignment).

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, bail};
use serde::{Deserialize, Serialize};
use unz_formats::IngestReport;
use unz_formats::kfgins::GPS_WEEK_S;
use unz_formats::manifest::{LogFormat, OdometerKind, RunManifest};
use unz_formats::parquet_io::read_schema;
use unz_formats::schema::META_ODO_M_PER_PULSE;
use unz_formats::tables::MarksTable;
use unz_stages::criteria::ControlPointFix;
use unz_stages::derive::Derived;
use unz_stages::disupt::{GyroWalk, ProblemSpec};
use unz_stages::earth::Geodetic;
use unz_stages::imu_axes::ImuAxes;
use unz_stages::in_motion_level::{Free, IN_MOTION_LEVEL_WINDOW_S, level_in_motion};
use unz_stages::initial::{
    InMotionLevelReport, InitialReport, InitialRequest, Source, initial_settings_with_velocity,
    static_samples,
};
use unz_stages::strapdown::{self, NavInputs, NavSettings, NavTrack, PassSink, navigate};

use super::coordinates_misread::misreading_that_reaches;
use super::ingest_derive::read_ingest_report;
use super::ingested::load_table;
use super::marks::{RepeatedMark, UnknownMarks, choose_marks};
use super::moving_marks::{MovingMark, moving_marks};
use super::odometer_checks::{WHOLE_HOURS_REACH_S, shift_named, whole_weeks};
use super::unix_clock::UnixAgainstGps;
use super::{Overrides, Params, RunCtx, ensure_derive};
use crate::artifacts::{StageName, files};
use crate::derive_io::{StoredDerive, read_velocity_prefix};

/// Everything a navigation pass needs, loaded once.
pub struct NavCase {
    /// Derived series (shared with the run's other stages in this process).
    pub derived: Arc<Derived>,
    /// Control points matched to samples.
    pub fixes: Vec<ControlPointFix>,
    /// Control points whose id was marked more than once, and the mark used.
    pub repeated_marks: Vec<RepeatedMark>,
    /// Control points passed at speed, not stood at.
    pub moving_marks: Vec<MovingMark>,
    /// Marks whose id no control point of the manifest has.
    pub unknown_marks: Option<UnknownMarks>,
    /// Settings of the pass.
    pub settings: NavSettings,
    /// How they were found.
    pub initial: InitialReport,
    /// The gyros' angle random walk the joint fit's covariance takes (`[align]
    /// arw_rad_sqrt_s`).
    pub gyro_walk: GyroWalk,
}

impl NavCase {
    /// The navigation inputs.
    pub fn inputs(&self) -> NavInputs<'_> {
        NavInputs {
            dt_s: &self.derived.dt_s,
            dtheta_rad: self.derived.dtheta_rad.view(),
            odo_dist_m: &self.derived.odo_dist_m,
        }
    }

    /// Runs the navigation into `track`.
    pub fn navigate(&self, track: &mut NavTrack) {
        navigate(&self.inputs(), &self.settings, track);
    }
}

/// The vehicle's installation (`[vehicle]`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleParams {
    /// Where the vehicle's control-point mark (the point the crew holds over a surveyed
    /// point at a stop) lies from the navigated point, in the IMU's body axes (x forward,
    /// y right, z down), m. The navigated point is the odometer's: dead reckoning carries
    /// the wheels' distance along the body's x, so it follows the point that does not
    /// slip sideways (a rigid axle's middle). Every control point's error is the mark's.
    pub mark_lever_arm_m: [f64; 3],
    /// Where the log's IMU axes point on the vehicle (`"FRD"`, the default: x forward,
    /// y right, z down; `"FLU"`, `"RFU"`…): the ingest turns the increments into the
    /// body's FRD, and the derive fails a log whose gravity or odometer says its axes are
    /// other than the ones named.
    pub imu_axes: ImuAxes,
    /// The IMU's mounting beyond those right angles, `[roll, pitch, yaw]` in degrees
    /// (roll and yaw within ±180°, pitch within ±90°; the right angles are best named by
    /// `imu_axes`): its axes are the body's turned by the yaw, then the pitch,
    /// then the roll; the ingest turns the increments back. The derive's check of the
    /// axes measures it (`navigate.json`'s `imu_axes.check.mounting_deg`) and fails a
    /// yaw beyond 10°, which the joint fit cannot take, naming the setting.
    pub imu_mounting_deg: [f64; 3],
    /// The odometer's pitch boresight, deg: how far the vehicle's path climbs above the
    /// IMU's x while driving (positive: up). Dead reckoning climbs by its tangent per
    /// metre of distance, in height alone. The disupt stage fits it to the control
    /// points' heights where a run has a point 200 m or more along its route, starting
    /// from this value; `campaign.md` pools the runs' fits into the value to set here, so
    /// that a run without such a point gets its heights right too.
    pub odo_pitch_deg: f64,
}

impl VehicleParams {
    /// The mark's lever arm, unless the mark is the navigated point (reports say it only
    /// then).
    pub fn mark_arm(&self) -> Option<[f64; 3]> {
        Some(self.mark_lever_arm_m).filter(|a| *a != [0.0; 3])
    }
}

/// Largest lever arm of the mark, m: a vehicle's length.
pub const MARK_LEVER_ARM_MAX_M: f64 = 30.0;

/// The manifest's control points matched to the log.
#[derive(Debug, Clone, Default)]
pub struct MatchedPoints {
    /// Control points matched to samples, in the manifest's order; a point visited more
    /// than once has a fix per visit, in time order.
    pub fixes: Vec<ControlPointFix>,
    /// Points whose id was marked more than once, and the mark used.
    pub repeated_marks: Vec<RepeatedMark>,
    /// Points passed at speed, not stood at ([`moving_marks`]).
    pub moving_marks: Vec<MovingMark>,
    /// Marks whose id no control point of the manifest has.
    pub unknown_marks: Option<UnknownMarks>,
}

/// Matches the manifest's control points: by their mark records ([`choose_marks`],
/// reading the ingested `odometer`: of an id marked more than once, the last made at
/// rest, and the earlier stops that `navigated` puts at the same place, each a visit),
/// else by `t_s`. Each point is compared with the `vehicle`'s mark. `navigated` gives the
/// navigated north and east (m, from any origin) at samples; it is called only when
/// some id was marked at rest at more than one stop.
pub fn match_control_points(
    m: &RunManifest,
    marks: &MarksTable,
    d: &Derived,
    rolled: &IngestReport,
    odometer: &Path,
    vehicle: &VehicleParams,
    navigated: impl FnOnce(&[usize]) -> anyhow::Result<Vec<[f64; 2]>>,
) -> anyhow::Result<MatchedPoints> {
    let log_t_s = |t_ns: i64| t_ns as f64 * 1e-9;
    let Some(last) = d.t_s.last() else {
        bail!("no samples")
    };
    let in_log = |t_s: f64| {
        let rel = t_s - log_t_s(d.t0_ns);
        (0.0..=last + d.nominal_dt_s).contains(&rel)
    };
    let sample_at = |t_s: f64| {
        let rel = t_s - log_t_s(d.t0_ns);
        d.t_s.partition_point(|t| t < rel).min(d.t_s.len() - 1)
    };
    let ids: Vec<u32> = m.control_points.iter().map(|cp| cp.id).collect();
    let chosen = choose_marks(marks, &ids, odometer, |t_ns| in_log(log_t_s(t_ns)))?;
    let to_place = chosen.to_place();
    let places: BTreeMap<usize, [f64; 2]> = if to_place.is_empty() {
        BTreeMap::new()
    } else {
        let samples: Vec<usize> = to_place
            .iter()
            .map(|&i| sample_at(log_t_s(marks.t_ns[i])))
            .collect();
        to_place.into_iter().zip(navigated(&samples)?).collect()
    };
    let (marks_of, repeated_marks) = chosen.settle(marks, |i| places.get(&i).copied());
    let unknown_marks = UnknownMarks::of(marks, &ids);
    // A point without its mark beside a mark without its point: an id keyed or typed
    // wrong, which the error names.
    let unknown_said = unknown_marks
        .as_ref()
        .map(|u| {
            format!(
                "; the log has marks of ids no control point has: {}",
                u.listed()
            )
        })
        .unwrap_or_default();
    let mut fixes = Vec::with_capacity(m.control_points.len());
    for cp in &m.control_points {
        let times: Vec<f64> = match marks_of.get(&cp.id) {
            Some(visits) => visits.iter().map(|&i| log_t_s(marks.t_ns[i])).collect(),
            None => vec![past_rollovers(
                cp.t_s.with_context(|| {
                    format!(
                        "control point {} matches no mark record and has no t_s{unknown_said}",
                        cp.id
                    )
                })?,
                rolled,
                log_t_s(d.t0_ns),
                in_log,
            )],
        };
        for t_s in times {
            if !in_log(t_s) {
                let first_s = log_t_s(d.t0_ns);
                let log_s = [first_s, first_s + last];
                let other_clock = whole_hours_into(t_s, log_s).map_or_else(
                    || on_unix_clock(t_s, log_s).unwrap_or_default(),
                    |shift_s| {
                        let (on, in_weeks) = shift_named(shift_s);
                        let why = if in_weeks {
                            "GPS seconds of week against the log's GPS seconds since the \
                             weeks' start (6 January 1980), or the other way round?"
                        } else {
                            "UTC seconds of day against the log's GPS seconds of week, or a \
                             time zone's? GPS time runs 18 s ahead of UTC"
                        };
                        format!(
                            ": {shift_s} s later ({on} on) it would lie within it, at t_s = \
                             {:.2} (a time on another clock: {why}); write the point's t_s on \
                             the log's clock",
                            t_s + shift_s
                        )
                    },
                );
                bail!(
                    "control point {} at t_s = {} is outside the log, which runs from \
                     t_s = {first_s:.2} to {:.2}{other_clock}",
                    cp.id,
                    crate::config::shown(t_s),
                    first_s + last
                );
            }
            fixes.push(ControlPointFix {
                id: cp.id,
                sample: sample_at(t_s),
                t_s,
                lat_rad: cp.position.latitude_deg.to_radians(),
                lon_rad: cp.position.longitude_deg.to_radians(),
                h_m: cp.position.height_m,
                mark_lever_arm_m: vehicle.mark_lever_arm_m,
            });
        }
    }
    // A repeated id none of whose marks was at rest is said so with its marks.
    let moving_marks = moving_marks(&fixes, d, |id| {
        (repeated_marks.iter()).any(|r| r.id == id && !r.at_rest)
    });
    Ok(MatchedPoints {
        fixes,
        repeated_marks,
        moving_marks,
        unknown_marks,
    })
}

/// A text log's time `t_s` as written in the manifest (as its time column reads: seconds
/// of GPS week, or of day), in the log's time base when the log ran over rollovers and
/// the time is after one: the first of a week on, two weeks, …, then a day on, two days,
/// … (as many as the log's tags rolled over, `rolled`'s counts) that lies within the log
/// (`in_log`; it begins at `first_s`). The ingest adds the week or the day to the log's
/// own tags from each rollover on (`unz_formats::kfgins::{GPS_WEEK_S, DAY_S}`); a log
/// that did not roll over takes `t_s` as written. The first period on that reaches the
/// log's start is computed, not walked to: a hostile log's rollovers by turns count
/// millions.
fn past_rollovers(
    t_s: f64,
    rolled: &IngestReport,
    first_s: f64,
    in_log: impl Fn(f64) -> bool,
) -> f64 {
    use unz_formats::kfgins::DAY_S;
    if in_log(t_s) {
        return t_s;
    }
    [
        (GPS_WEEK_S, rolled.week_rollovers),
        (DAY_S, rolled.day_rollovers),
    ]
    .into_iter()
    .flat_map(|(period_s, count)| {
        // The fewest periods that reach the log's start, and one more for rounding.
        let k = periods_into(t_s, first_s, period_s).max(1.0);
        [k, k + 1.0]
            .into_iter()
            .filter(move |&k| k <= count as f64)
            .map(move |k| t_s + k * period_s)
    })
    .find(|&t| in_log(t))
    .unwrap_or(t_s)
}

/// The fewest whole `period_s` that bring the time `t_s` to `to_s` or past it (negative
/// to go back).
fn periods_into(t_s: f64, to_s: f64, period_s: f64) -> f64 {
    ((to_s - t_s) / period_s).ceil()
}

/// The one whole number of hours, s, that brings the time `t_s` within the log's span
/// `log_s` (s), up to a week either way: `None` when none does, or more than one (a log
/// longer than an hour may take several, and the point's own clock is then unknown).
/// Beyond a week, the one whole number of GPS weeks ([`whole_weeks`]) that does, for a
/// log shorter than a week.
fn whole_hours_into(t_s: f64, log_s: [f64; 2]) -> Option<f64> {
    let k = periods_into(t_s, log_s[0], 3600.0);
    // One hour more would pass the log's end.
    let only = t_s + (k + 1.0) * 3600.0 > log_s[1] && t_s + k * 3600.0 <= log_s[1];
    let shift_s = k * 3600.0;
    if only && k != 0.0 && shift_s.abs() <= WHOLE_HOURS_REACH_S {
        return Some(shift_s);
    }
    let weeks_s = periods_into(t_s, log_s[0], GPS_WEEK_S) * GPS_WEEK_S;
    (log_s[1] - log_s[0] < GPS_WEEK_S && t_s + weeks_s <= log_s[1])
        .then_some(weeks_s)
        .filter(|&s| whole_weeks(s).is_some())
}

/// Why a control point's time `t_s` lies outside the log's span `log_s` (s) when one
/// of them is Unix time and the other GPS time ([`UnixAgainstGps`]), with the time it
/// would have on the log's clock; `None` for other clocks.
fn on_unix_clock(t_s: f64, log_s: [f64; 2]) -> Option<String> {
    let u = UnixAgainstGps::between([t_s; 2], log_s)?;
    let (unix, gps) = (u.unix_clock(), u.gps_clock());
    let clocks = if u.other_is_unix {
        format!("its t_s is {unix} and the log's {gps}")
    } else {
        format!("the log's time tags are {unix} and its t_s {gps}")
    };
    Some(format!(
        ": {clocks}; moved by {} s ({}) it would lie within it, at t_s = {:.2}; write the \
         point's t_s on the log's clock",
        u.shift_s,
        u.parts(),
        t_s + u.shift_s
    ))
}

/// How many times over the odometer's path to a mark a control point may lie from the
/// start: a scale wrong by half still reaches it.
const CP_REACH_PATH_FACTOR: f64 = 2.0;
/// What a control point may lie beyond that, m: the site's own uncertainty (a start read
/// off a map or a GNSS fix) and a mark pressed a little late.
const CP_REACH_MARGIN_M: f64 = 100.0;

/// Fails when a control point lies farther from the run's start than the vehicle can have
/// gone by its mark (the odometer's path there, `odo_scale` times, twice over, plus
/// 100 m). No setting DISUPT moves reaches such a point: the
/// azimuth turns the route about the start, the odometer scale stretches it by per cent,
/// the drifts bend it. Fitted anyway, the joint fit follows it to any value (an odometer
/// scale of thousands) and the route is the fit's artefact; its coordinates, its mark's
/// point id or the site are wrong, and the manifest says which point.
pub fn check_reach(
    m: &RunManifest,
    fixes: &[ControlPointFix],
    d: &Derived,
    odo_scale: f64,
) -> anyhow::Result<()> {
    let start = start_position(m);
    let mut by_sample: Vec<&ControlPointFix> = fixes.iter().collect();
    by_sample.sort_by_key(|f| f.sample);
    let (mut path_m, mut k) = (0.0, 0);
    // Each point's distance from the start, the odometer's travel by its mark, and the
    // farthest it may lie.
    let mut reaches = Vec::with_capacity(by_sample.len());
    for f in by_sample {
        let end = (f.sample + 1).min(d.odo_dist_m.len());
        path_m += d.odo_dist_m[k.min(end)..end]
            .iter()
            .map(|s| s.abs())
            .sum::<f64>();
        k = k.max(end);
        let travelled_m = path_m * odo_scale.abs();
        let (north_m, east_m) = start.offset_m(f.lat_rad, f.lon_rad);
        let away_m = north_m.hypot(east_m);
        let reach_m = CP_REACH_PATH_FACTOR * travelled_m + CP_REACH_MARGIN_M;
        reaches.push((f, away_m, travelled_m, reach_m));
    }
    let out_of_reach =
        |&&(_, away_m, _, reach_m): &&(_, f64, _, f64)| away_m.is_nan() || away_m > reach_m;
    // Every point out of reach, two or more: the site is the likelier misread.
    let site_first = reaches.len() > 1 && reaches.iter().all(|r| out_of_reach(&r));
    if let Some(&(f, away_m, travelled_m, reach_m)) = reaches.iter().find(out_of_reach) {
        let misread = misreading_that_reaches(m, f, reach_m, site_first)
            .map_or_else(String::new, |misread| format!(": {misread}"));
        bail!(
            "control point {} is {away_m:.0} m from the run's start (the site) but the \
             odometer measured {travelled_m:.0} m of travel by its mark at t_s = {:.2}: no \
             azimuth or odometer scale reaches it; its coordinates, its mark's point id or \
             the site are wrong{misread}",
            f.id,
            f.t_s
        );
    }
    Ok(())
}

/// Where the run starts: the manifest's site.
pub fn start_position(m: &RunManifest) -> Geodetic {
    Geodetic::from_deg(m.site.latitude_deg, m.site.longitude_deg, m.site.height_m)
}

/// Loads a navigation case of the run with `overrides` (derive must be up to date).
pub fn load_case(ctx: &RunCtx, params: &Params, overrides: &Overrides) -> anyhow::Result<NavCase> {
    ensure_derive(ctx, params)?;
    let m = &ctx.manifest;
    let ingest_dir = ctx.layout().dir(StageName::Ingest);
    let derived = ctx.derived()?;
    let (marks, _) = load_table::<MarksTable>(
        &ingest_dir.join(files::MARKS),
        MarksTable::extend_from_batch,
    )?;
    let odo_schema = read_schema(&ingest_dir.join(files::ODOMETER))?;
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
        body_from_unit: unz_stages::imu_mounting::rotation(params.vehicle.imu_mounting_deg),
    };
    // The alignment reads the velocity increments of the static start only: read apart
    // when the derive was loaded without them.
    let prefix;
    let dvel_mps: &[[f64; 3]] = if derived.dvel_mps.len() == derived.t_s.len() {
        &derived.dvel_mps
    } else {
        prefix = read_velocity_prefix(
            &StoredDerive::of(&ctx.layout()),
            static_samples(&derived, &req),
        )?;
        &prefix
    };
    let (mut settings, mut initial) =
        initial_settings_with_velocity(&derived, dvel_mps, &req, &params.align, start_position(m));
    level_in_motion_over_window(&derived, params, &mut settings, &mut initial);
    // Only an odometer that gives speeds takes a speed floor.
    let gives_speeds =
        m.format == LogFormat::KfGins && m.odometer.kind.is_none_or(OdometerKind::is_speed);
    if let Some(travel) = initial.stand_travel.as_mut().filter(|_| !gives_speeds) {
        travel.floor_mps = None;
    }
    settings.odo_pitch_rad = params.vehicle.odo_pitch_deg.to_radians();
    let inputs = NavInputs {
        dt_s: &derived.dt_s,
        dtheta_rad: derived.dtheta_rad.view(),
        odo_dist_m: &derived.odo_dist_m,
    };
    let MatchedPoints {
        fixes,
        repeated_marks,
        moving_marks,
        unknown_marks,
    } = match_control_points(
        m,
        &marks,
        &derived,
        &read_ingest_report(&ingest_dir)?,
        &ingest_dir.join(files::ODOMETER),
        &params.vehicle,
        |samples| Ok(navigated_places(&inputs, &settings, samples)),
    )
    .with_context(|| format!("in {}", m.path.display()))?;
    check_reach(m, &fixes, &derived, odo_scale)
        .with_context(|| format!("in {}", m.path.display()))?;
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
        repeated_marks,
        moving_marks,
        unknown_marks,
        settings,
        initial,
        gyro_walk: GyroWalk::new(params.align.arw_rad_sqrt_s),
    })
}

/// The navigated north and east (m, from the start) at each of `samples`, of a pass with
/// `settings`: where a control point's marks at several stops were made.
fn navigated_places(
    inputs: &NavInputs<'_>,
    settings: &NavSettings,
    samples: &[usize],
) -> Vec<[f64; 2]> {
    /// Keeps the positions at the samples asked for (`wanted`: sample and where it goes,
    /// by sample).
    struct At {
        wanted: Vec<(usize, usize)>,
        next: usize,
        start: Geodetic,
        places: Vec<[f64; 2]>,
    }
    impl PassSink for At {
        fn sample(&mut self, k: usize, lat: f64, lon: f64, _: f64, _: &[f64; 4], _: f64) {
            while let Some(&(at, i)) = self.wanted.get(self.next).filter(|w| w.0 <= k) {
                if at == k {
                    let (north_m, east_m) = self.start.offset_m(lat, lon);
                    self.places[i] = [north_m, east_m];
                }
                self.next += 1;
            }
        }
    }
    let mut wanted: Vec<(usize, usize)> = samples.iter().copied().zip(0..).collect();
    wanted.sort_unstable();
    let mut at = At {
        wanted,
        next: 0,
        start: settings.start(),
        places: vec![[f64::NAN; 2]; samples.len()],
    };
    strapdown::run(inputs, settings, &mut at);
    at.places
}

/// A start levelled in motion (no static start) refitted over the log's first
/// [`IN_MOTION_LEVEL_WINDOW_S`] ([`level_in_motion`]): the first epoch's accelerometer
/// references alone carry the odometer acceleration's noise into the initial tilt.
fn level_in_motion_over_window(
    derived: &Derived,
    params: &Params,
    settings: &mut NavSettings,
    initial: &mut InitialReport,
) {
    let free = Free {
        pitch: initial.pitch_source == Source::InMotion,
        roll: initial.roll_source == Source::InMotion,
    };
    if !(free.pitch || free.roll) {
        return;
    }
    let spec = ProblemSpec {
        settings: *settings,
        filter: params.derive.filter,
        kalman: params.kalman,
        fixes: &[],
        excluded_cps: &[],
        drift_z_prior_deg_h: None,
        gyro_walk: None,
    };
    let Some(fit) = level_in_motion(&spec.on(derived), free) else {
        return;
    };
    *settings = fit.settings;
    initial.pitch_deg = settings.initial.pitch_rad.to_degrees();
    initial.roll_deg = settings.initial.roll_rad.to_degrees();
    initial.in_motion_level = Some(InMotionLevelReport {
        window_s: IN_MOTION_LEVEL_WINDOW_S,
        epochs: fit.epochs,
        residual_rms_deg: fit.residual_rms_rad.to_degrees(),
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use unz_formats::kfgins::DAY_S;

    /// A point's time the log takes after one whole number of hours only is named; none
    /// when it takes none, several (a log longer than an hour), or beyond a week.
    #[test]
    fn a_time_whole_hours_off_the_log_is_named() {
        let log = [152_143.09, 153_018.99];
        assert_eq!(whole_hours_into(66_407.0, log), Some(86_400.0));
        assert_eq!(
            whole_hours_into(152_825.0 + 5.0 * 3600.0, log),
            Some(-18_000.0)
        );
        assert_eq!(whole_hours_into(152_825.0 + 1_800.0, log), None);
        assert_eq!(whole_hours_into(152_825.0, log), None);
        assert_eq!(whole_hours_into(152_825.0 - 8.0 * 86_400.0, log), None);
        // A point in seconds of week, the log in seconds since GPS time's start.
        let weeks = 1480.0 * GPS_WEEK_S;
        let since_1980 = log.map(|t| t + weeks);
        assert_eq!(whole_hours_into(152_825.0, since_1980), Some(weeks));
        assert_eq!(whole_hours_into(152_825.0 + weeks, log), Some(-weeks));
        let long = [0.0, 3.0 * 3600.0];
        assert_eq!(whole_hours_into(-86_400.0 + 100.0, long), None);
    }

    /// A time outside the log is taken past as many rollovers as the log's tags made, the
    /// weeks first, and never past one they did not make: a log in seconds of week
    /// running Monday to Tuesday has no day's rollover, so a point timed a day before it
    /// (a typo, or another run's) stays outside, and the run says so.
    #[test]
    fn a_time_is_taken_past_the_rollovers_the_log_made_only() {
        let rolled = |weeks: u64, days: u64| IngestReport {
            week_rollovers: weeks,
            day_rollovers: days,
            ..IngestReport::default()
        };
        // Monday and Tuesday in seconds of week, or two days after two midnights.
        let log = |t: f64| (100_000.0..180_000.0).contains(&t);
        let past = |t: f64, weeks, days| past_rollovers(t, &rolled(weeks, days), 100_000.0, log);
        assert_eq!(past(120_000.0, 0, 0), 120_000.0);
        assert_eq!(past(20_000.0, 0, 0), 20_000.0);
        assert_eq!(past(20_000.0, 0, 1), 20_000.0 + DAY_S);
        assert_eq!(past(1_000.0, 0, 2), 1_000.0 + 2.0 * DAY_S);
        assert_eq!(past(1_000.0, 0, 1), 1_000.0);
        // A hostile log's rollovers by turns, without end: at once.
        assert_eq!(past(1_000.0, u64::MAX, u64::MAX), 1_000.0 + 2.0 * DAY_S);
        let week = GPS_WEEK_S - 100.0;
        let after_week = |t: f64| (week..GPS_WEEK_S + 500.0).contains(&t);
        let past_week = |t: f64, weeks| past_rollovers(t, &rolled(weeks, 0), week, after_week);
        assert_eq!(past_week(300.0, 1), 300.0 + GPS_WEEK_S);
        assert_eq!(past_week(300.0, 0), 300.0);
    }
}
