//! Gaps in a text log's odometer speed file (an OBD-II logger's dropouts), bridged by the
//! IMU.
//!
//! A speed file's distance is the trapezoid of its speeds: across a gap that is the mean
//! of the speeds at its ends times its length, whatever the vehicle did meanwhile.
//! Measured on Kingston's drive with a minute of its 1-Hz speeds removed (stop-and-go
//! traffic): the joint fit's control points went from 1.0 and 0.4 m to 95 and 30 m off,
//! and nothing said why. A gap here is an interval between two readings longer than
//! [`MIN_GAP_S`] and [`GAP_PERIODS`] times the file's recent intervals. Each is bridged
//! as a binary log's failure is ([`unz_stages::odo_bridge::bridge`]: the inertial
//! along-track speed, fitted to the readings up to [`WINDOW_S`] each side, interpolated to
//! the IMU's samples), and the bridge's distances are written as odometer rows at the
//! IMU's samples across it (`distance_source` bridged); the readings after it are moved
//! by what the bridge gives across it less the trapezoid.
//!
//! A logger that writes zero, not nothing, when it loses the speed leaves no gap but a
//! stand: the file's distance stands while the car drives. Every stand of
//! [`STAND_MIN_S`] or more is judged by the IMU (`stand_failed`; one longer than
//! the longest bridged, over its last such stretch: a long stop whose drive-off the file
//! missed), and one the car moved over is bridged as a gap is, from when it failed to
//! when the car came to rest in it, if it did (and again from a drive-off it missed).
//!
//! Three passes: the file once to find its gaps ([`find_gaps`], through a [`GapFinder`]),
//! the IMU's samples as the ingest streams them ([`GapBridger`]), and the file again as
//! it is written ([`BridgedGaps::give`]). Memory: the readings around the gaps (at most
//! 2 000 000), the IMU's samples over the windows open at a time, and the bridged rows
//! (one per IMU sample inside a gap). A text log's 8th column, whose readings come with
//! the IMU's samples, is judged the same way in one pass ([`crate::odometer_column`]).

use std::collections::VecDeque;
use std::io::BufRead;

use nalgebra::{Rotation3, Vector3};

use unz_formats::OdometerFailures;
use unz_formats::error::FormatError;
use unz_formats::kfgins::OdometerFileReader;
use unz_formats::schema::DistanceSource;
use unz_stages::odo_bridge::{BridgeSample, Reading, WINDOW_S, bridge};

use crate::standing_motion::{Motion, REFERENCE_S, StandingMotion, WATCH_S};

use crate::odometer_bridge::{Given, MAX_BRIDGED_S};

/// Shortest gap between two readings bridged, s: over a few seconds the trapezoid of the
/// speeds at its ends is within centimetres to decimetres of the route.
pub const MIN_GAP_S: f64 = 3.0;
/// A gap is also this many times the median of the file's last nine intervals: a
/// file written at its own slow rate has no gaps.
pub const GAP_PERIODS: f64 = 3.0;
/// Intervals the file's recent rate is taken over.
const RECENT: usize = 9;
/// Readings kept before a gap at most, whatever their time tags (a file at a kilohertz
/// would hold 10 000 over [`WINDOW_S`]).
const MAX_WINDOW_READINGS: usize = 100_000;
/// Gaps bridged at most; beyond, a file with more is counted, its other gaps left to the
/// trapezoid.
const MAX_GAPS: usize = 10_000;
/// Shortest stand judged, s: the file's distance standing over at least this long (its
/// speeds zero) while the IMU may say the vehicle moved (a logger that writes zero, not
/// nothing, when it loses the speed).
pub const STAND_MIN_S: f64 = unz_formats::speed_spikes::STAND_MIN_S;
/// The IMU takes the vehicle at rest from this long after a stand's first reading, s: a
/// file read at a hertz, whose clock may run ahead of the IMU's, says zero before the
/// vehicle stands (a binary count stands within a pulse of it:
/// [`crate::odometer_stuck::SETTLE_S`], 0.5 s). Measured on Kingston with its file's
/// clock shifted (beyond a configured odometer time offset, which the judgement takes
/// out): from 1 s ahead to 2.5 s behind, no stop judged moving (0.5 s: 0.7 s ahead to 3 s
/// behind; 2 s: 2 s ahead to 1.5 s behind).
pub const STAND_SETTLE_S: f64 = 1.0;
/// The IMU's backward watch of a stand begins this long before its last reading, s: a
/// file whose clock lags the vehicle by up to 2.5 s still says zero as it drives off.
const END_SETTLE_S: f64 = 3.0;
/// A vehicle that moved into a stand (its distance stepped into it) is at rest within
/// this long of the stand's first reading, s: slower than [`BRAKED_FROM_MPS`] before it,
/// at 0.35 m/s² or more.
const MOVED_IN_REST_BY_S: f64 = 6.0;
/// Least speed before a stand, by the file, whose braking into it the IMU judges, m/s:
/// slower, a stop and a speed that stood look alike over a second.
pub const BRAKED_FROM_MPS: f64 = 2.0;
/// Readings kept around all the gaps at most (32 MB): a file far denser than its gaps'
/// windows need leaves its later gaps to the trapezoid, counted.
const MAX_KEPT_READINGS: usize = 2_000_000;

/// A gap in the file, with the readings around it.
#[derive(Debug, Clone, PartialEq)]
pub struct Gap {
    /// The last reading before it, s.
    pub from_s: f64,
    /// The first reading after it, s.
    pub to_s: f64,
    /// The readings within [`WINDOW_S`] before it (up to `from_s`) and after it (from
    /// `to_s`, not past the next gap): time, s, and distance as the file gives it, m.
    readings: Vec<(f64, f64)>,
    /// A stand, not a gap: the file's readings say the vehicle stood from its first
    /// reading to its last (s; [`STAND_MIN_S`] at least, its readings among `readings`),
    /// between `from_s` and `to_s`. The IMU judges it ([`stand_failed`]); it is a
    /// failure, bridged, only when the vehicle moved.
    stand: Option<(f64, f64)>,
}

impl Gap {
    /// A stand of the file's distance, judged by the IMU, not a gap between readings.
    pub(crate) fn is_stand(&self) -> bool {
        self.stand.is_some()
    }

    /// The window's first and last times, s.
    pub(crate) fn span_s(&self) -> (f64, f64) {
        let first = self.readings.first().map_or(self.from_s, |r| r.0);
        let last = self.readings.last().map_or(self.to_s, |r| r.0);
        (first, last)
    }

    /// The file's distance at `t_s` by linear interpolation between its readings on the
    /// same side of the gap.
    fn reading_at(&self, t_s: f64) -> Reading {
        if t_s > self.from_s && t_s < self.to_s {
            return Reading::Failed;
        }
        let side: &[(f64, f64)] = {
            let split = self.readings.partition_point(|r| r.0 <= self.from_s);
            if t_s <= self.from_s {
                &self.readings[..split]
            } else {
                &self.readings[split..]
            }
        };
        let k = side
            .partition_point(|r| r.0 < t_s)
            .clamp(1, side.len().max(1));
        let d = match side {
            [] => f64::NAN,
            [only] => only.1,
            _ => {
                let ((t0, d0), (t1, d1)) = (side[k - 1], side[k.min(side.len() - 1)]);
                if t1 > t0 {
                    d0 + (d1 - d0) * (t_s - t0) / (t1 - t0)
                } else {
                    d0
                }
            }
        };
        if t_s <= self.from_s {
            Reading::Before(d)
        } else {
            Reading::After(d)
        }
    }

    /// The stand's failure `f`: a gap from the stand's last reading at or before its
    /// start (the readings before are the vehicle's rest) to its first reading at or
    /// after its end (the readings from there are right again, the vehicle at rest), or
    /// to `to_s`; the readings after it kept over [`WINDOW_S`].
    fn failed_between(self, f: StandFailure) -> Gap {
        let from_s = self
            .readings
            .iter()
            .filter(|r| r.0 <= f.from_s && r.0 < self.to_s)
            .map(|r| r.0)
            .fold(self.from_s, f64::max);
        let to_s = f.until_s.map_or(self.to_s, |until_s| {
            (self.readings.iter())
                .map(|r| r.0)
                .filter(|&t| t >= until_s && t > from_s)
                .fold(self.to_s, f64::min)
        });
        let readings = self
            .readings
            .into_iter()
            .filter(|r| {
                (r.0 <= from_s && r.0 >= f.after_s) || (r.0 >= to_s && r.0 - to_s <= WINDOW_S)
            })
            .collect();
        Gap {
            from_s,
            to_s,
            readings,
            stand: None,
        }
    }
}

/// A stand's readings that failed, s: from the last at or before `from_s`, to the first
/// at or after `until_s` (the vehicle at rest again), or to the stand's end. The readings
/// before it are taken from `after_s` (a failure before it ended there).
#[derive(Debug, Clone, Copy, PartialEq)]
struct StandFailure {
    from_s: f64,
    until_s: Option<f64>,
    after_s: f64,
}

/// The stretches of the stand `g` over which the IMU's `samples` say the vehicle moved
/// while the speed file stood (a logger that writes zero when it loses the speed), in
/// order; none for a stop. The file's readings are taken `lag_prior_s` late (the
/// configured odometer time offset, negated). Judged:
/// - *Into the stand*: from at least [`BRAKED_FROM_MPS`] (the file's speed at the reading
///   before it), a vehicle that stops brakes to rest. Taking the specific force along x
///   over [`REFERENCE_S`] after [`STAND_SETTLE_S`] into the stand as at rest, the IMU's
///   speed at the reading before it must be the file's, within half of it and 2 m/s (or
///   at the reading before that: a file that lags the car); else the speed stood as the
///   vehicle drove on, and the readings failed from the stand's start.
/// - *In the stand*: the IMU's watch of a standing count ([`StandingMotion`]) from
///   [`STAND_SETTLE_S`] into the stand to its last reading: a vehicle that drives off while
///   the file still says zero fails it from the watch's start. In a stand the vehicle
///   moved into (its distance stepped from the reading before), a watch whose reference
///   began within [`MOVED_IN_REST_BY_S`] of the stand's first reading fails it from the
///   stand's start: that reference, taken as rest, may have been the vehicle still
///   moving as the speed stood, and a bridge from the watch would start it at rest.
/// - *Out of a failure from the stand's start*: a vehicle that came to rest later in the
///   stand ([`rest_in`]: it braked there from the speed before the stand, and drove off
///   from the stand's end to the speed after it) has its readings right again from
///   there; from that rest, the watch looks for a drive-off the file missed, a second
///   stretch. Else the failure runs to the stand's end.
fn stand_failed(
    g: &Gap,
    samples: &[ImuSample],
    g_mps2: f64,
    lag_prior_s: f64,
) -> Vec<StandFailure> {
    let Some((first_s, last_s)) = g.stand else {
        return Vec::new();
    };
    // The IMU's time in the file's: its readings lag the vehicle by `lag_prior_s`.
    let t_of = |s: &ImuSample| s.0 as f64 * 1e-9 + lag_prior_s;
    let period_s = match samples {
        [a, .., b] => (t_of(b) - t_of(a)) / (samples.len() - 1) as f64,
        _ => return Vec::new(),
    };
    // The x specific force over REFERENCE_S from `from_s`, m/s².
    let force_over = |from_s: f64| rest_force(samples, period_s, &t_of, from_s).map(|f| f.x);
    // The IMU's change of speed along x over (`from_s`, `to_s`], the x specific force at
    // rest being `f_rest_mps2`, m/s.
    let speed_change = |from_s: f64, to_s: f64, f_rest_mps2: f64| -> f64 {
        (samples.iter())
            .filter(|s| t_of(s) > from_s && t_of(s) <= to_s)
            .map(|s| s.2[0] - f_rest_mps2 * period_s)
            .sum()
    };
    // Whether the IMU's change of speed is the file's `dv_mps`: within half of it and
    // 2 m/s.
    let agrees =
        |imu_mps: f64, dv_mps: f64| (imu_mps - dv_mps).abs() <= (0.5 * dv_mps.abs()).max(2.0);
    // The first stretch the watch finds the vehicle moving over, from `from_s` (the
    // vehicle at rest then) to the stand's last reading: the watch's start.
    let watch_from = |from_s: f64| {
        let watched = (samples.iter()).filter(|s| t_of(s) > from_s && t_of(s) <= last_s);
        first_motion(watched, false, g_mps2, period_s, &t_of)
    };
    let settle_s = first_s + STAND_SETTLE_S;
    // The file's speed at the reading before the stand (zero at its first), and at the
    // reading before that.
    let before: Vec<(f64, f64)> = (g.readings.iter().copied())
        .filter(|r| r.0 <= g.from_s)
        .collect();
    let reading = |t_s: f64| g.readings.iter().find(|r| r.0 == t_s).map(|r| r.1);
    let into = match (before.last(), reading(first_s)) {
        (Some(&(t_from, d_from)), Some(d_first)) if first_s > t_from => {
            let v_from = 2.0 * (d_first - d_from) / (first_s - t_from);
            // A file that lags the car may say it moved a reading after it stood.
            let v_before = match before.len().checked_sub(2).map(|k| before[k]) {
                Some((t, d)) if t_from > t => Some((t, 2.0 * (d_from - d) / (t_from - t) - v_from)),
                _ => None,
            };
            Some((t_from, v_from, v_before, d_first > d_from))
        }
        _ => None,
    };
    let f_settle = force_over(settle_s);
    let braked = |t_s: f64, v_mps: f64| {
        f_settle.is_none_or(|f| agrees(speed_change(t_s, settle_s, f), -v_mps))
    };
    let drove_on = into.is_some_and(|(t_from, v_from, v_before, _)| {
        v_from >= BRAKED_FROM_MPS
            && !braked(t_from, v_from)
            && v_before.is_none_or(|(t, v)| !braked(t, v))
    });
    let watched = if drove_on { None } else { watch_from(settle_s) };
    let stepped_in = into.is_some_and(|i| i.3);
    let moved_in = drove_on
        || (stepped_in && watched.is_some_and(|w| w - REFERENCE_S < first_s + MOVED_IN_REST_BY_S));
    let Some((t_from, v_from, ..)) = into.filter(|_| moved_in) else {
        return (watched.into_iter())
            .map(|from_s| StandFailure {
                from_s,
                until_s: None,
                after_s: f64::NEG_INFINITY,
            })
            .collect();
    };
    // The speed stood as the vehicle moved into the stand. Where it came to rest later,
    // its readings are right again: it braked there from the speed before the stand,
    // and drove off from the rest at the stand's end to the speed after it.
    let end_rest_s = last_s - END_SETTLE_S - REFERENCE_S;
    // The IMU's speed at `t_s` from a rest at `rest_s`, within a quarter of the file's
    // `v_mps` and 1 m/s (on Kingston's stops they were 0.1–0.8 m/s apart, the file's
    // 1-Hz speed lagging the car).
    let from_rest = |rest_s: f64, t_s: f64, v_mps: f64| {
        speed_from_rest(samples, g_mps2, period_s, &t_of, rest_s, t_s)
            .is_some_and(|v| (v - v_mps).abs() <= (0.25 * v_mps.abs()).max(1.0))
    };
    let drove_off = match (reading(last_s), reading(g.to_s)) {
        (Some(d_last), Some(d_to)) if g.to_s > last_s => {
            let v_to = 2.0 * (d_to - d_last) / (g.to_s - last_s);
            from_rest(end_rest_s, g.to_s, v_to)
        }
        _ => false,
    };
    let rest_s = rest_in(samples, first_s, last_s, g_mps2, period_s, &t_of).filter(|&rest_s| {
        drove_off && rest_s + WATCH_S <= end_rest_s && from_rest(rest_s, t_from, v_from)
    });
    let mut failures = vec![StandFailure {
        from_s: g.from_s,
        until_s: rest_s,
        after_s: f64::NEG_INFINITY,
    }];
    // From that rest, a drive-off the file missed.
    if let Some((rest_s, from_s)) = rest_s.and_then(|r| Some((r, watch_from(r)?))) {
        failures.push(StandFailure {
            from_s,
            until_s: None,
            after_s: rest_s,
        });
    }
    failures
}

/// The mean specific force over [`REFERENCE_S`] from `from_s` (body FRD, m/s²): gravity
/// and the accelerometers' biases, the vehicle at rest then. `None` without samples there.
fn rest_force(
    samples: &[ImuSample],
    period_s: f64,
    t_of: &impl Fn(&ImuSample) -> f64,
    from_s: f64,
) -> Option<Vector3<f64>> {
    let (mut force, mut time_s) = (Vector3::zeros(), 0.0);
    for s in samples {
        if t_of(s) > from_s && t_of(s) <= from_s + REFERENCE_S {
            force += Vector3::from(s.2);
            time_s += period_s;
        }
    }
    (time_s > 0.0).then(|| force / time_s)
}

/// The IMU's speed along x at `t_s`, m/s, of a vehicle at rest over [`REFERENCE_S`] from
/// `rest_s` (before or after `t_s`): its acceleration integrated from the rest, the x
/// specific force plus gravity's part along x, gravity's direction carried from the rest
/// by the gyros, less the x accelerometer's bias (the rest's force less gravity's).
/// `None` without samples over the rest.
fn speed_from_rest(
    samples: &[ImuSample],
    g_mps2: f64,
    period_s: f64,
    t_of: &impl Fn(&ImuSample) -> f64,
    rest_s: f64,
    t_s: f64,
) -> Option<f64> {
    let force_mps2 = rest_force(samples, period_s, t_of, rest_s)?;
    // Gravity's direction in the body's axes at rest; the x accelerometer's bias.
    let down = -force_mps2.try_normalize(f64::MIN_POSITIVE)?;
    let bias_x = force_mps2.x + g_mps2 * down.x;
    // The acceleration's step over a sample whose body is turned by `c` from the rest's
    // (`c` takes its axes into the rest's, at the interval's middle).
    let step = |s: &ImuSample, c: &Rotation3<f64>| {
        s.2[0] + (g_mps2 * (c.transpose() * down).x - bias_x) * period_s
    };
    let (mut c, mut v_mps) = (Rotation3::identity(), 0.0);
    let turn = |s: &ImuSample, k: f64| Rotation3::from_scaled_axis(k * Vector3::from(s.1));
    if t_s >= rest_s {
        for s in samples
            .iter()
            .filter(|s| t_of(s) > rest_s && t_of(s) <= t_s)
        {
            v_mps += step(s, &(c * turn(s, 0.5)));
            c *= turn(s, 1.0);
        }
    } else {
        for s in samples
            .iter()
            .rev()
            .filter(|s| t_of(s) > t_s && t_of(s) <= rest_s)
        {
            v_mps -= step(s, &(c * turn(s, -0.5)));
            c *= turn(s, -1.0);
        }
    }
    Some(v_mps)
}

/// Where the vehicle came to rest in a stand whose readings lie from `first_s` to
/// `last_s` (the file's times; `t_of` gives a sample's): the IMU's watch of a standing
/// count run backwards in time, from [`END_SETTLE_S`] before the stand's last reading
/// (the vehicle at rest there, before it drove off) toward its first. It finds the
/// vehicle moving where it had not yet stopped; the watch's start there, at rest, is
/// returned. `None` when it finds no motion, or the vehicle at rest from before the
/// stand's first reading. Whether the stand's end was rest at all is the caller's to
/// judge (a vehicle at a constant speed there looks at rest to the watch).
fn rest_in(
    samples: &[ImuSample],
    first_s: f64,
    last_s: f64,
    g_mps2: f64,
    period_s: f64,
    t_of: &impl Fn(&ImuSample) -> f64,
) -> Option<f64> {
    let watched = (samples.iter().rev()).filter(|s| t_of(s) <= last_s - END_SETTLE_S);
    first_motion(watched, true, g_mps2, period_s, t_of).filter(|&t| t > first_s)
}

/// Where the IMU's watch of a standing count ([`StandingMotion`]) over `watched` (in the
/// order given) finds the vehicle moving: the watch's start then, s. `backwards` in time,
/// the times and the increments are negated, and the watch sees the vehicle's speed,
/// negated, from the rest at the end.
fn first_motion<'a>(
    watched: impl Iterator<Item = &'a ImuSample>,
    backwards: bool,
    g_mps2: f64,
    period_s: f64,
    t_of: &impl Fn(&ImuSample) -> f64,
) -> Option<f64> {
    let sign = if backwards { -1.0 } else { 1.0 };
    let watched: Vec<&ImuSample> = watched.collect();
    let mut watch = StandingMotion::new(g_mps2, period_s);
    for (k, s) in watched.iter().enumerate() {
        let (dvel, dtheta) = (s.2.map(|x| sign * x), s.1.map(|x| sign * x));
        if let Motion::Moving { watched: n } = watch.push(sign * t_of(s), dvel, dtheta) {
            return Some(t_of(watched[k.saturating_sub(n)]));
        }
    }
    None
}

/// A stand of the file's distance going on, as [`find_gaps`] reads it.
struct OpenStand {
    /// The reading before its first, s.
    from_s: f64,
    /// Its first and last readings, s.
    first_s: f64,
    last_s: f64,
    /// The readings before it (up to `from_s`).
    before: Vec<(f64, f64)>,
    /// Its readings over its last [`MAX_BRIDGED_S`] and [`WINDOW_S`] (a long stand's
    /// earlier ones are the car's rest, not judged).
    zeros: VecDeque<(f64, f64)>,
}

impl OpenStand {
    /// Takes the stand's next reading.
    fn push(&mut self, r: (f64, f64)) {
        self.last_s = r.0;
        self.zeros.push_back(r);
        while self.zeros.len() > 2 * MAX_WINDOW_READINGS
            || self
                .zeros
                .front()
                .is_some_and(|z| r.0 - z.0 > MAX_BRIDGED_S + WINDOW_S)
        {
            self.zeros.pop_front();
        }
    }

    /// The stand ended by the reading at `to_s`, as a gap to judge: whole when it is
    /// bridgeable, else its last [`MAX_BRIDGED_S`] from a reading at rest (a long stop
    /// whose drive-off the file missed). `None` when shorter than [`STAND_MIN_S`].
    fn judged(self, to_s: f64) -> Option<Gap> {
        if to_s - self.from_s <= MAX_BRIDGED_S {
            let readings = self.before.into_iter().chain(self.zeros).collect();
            return (self.last_s - self.first_s >= STAND_MIN_S).then_some(Gap {
                from_s: self.from_s,
                to_s,
                readings,
                stand: Some((self.first_s, self.last_s)),
            });
        }
        let from_s = self.zeros.iter().find(|z| to_s - z.0 <= MAX_BRIDGED_S)?.0;
        (self.last_s - from_s >= STAND_MIN_S).then(|| Gap {
            from_s,
            to_s,
            readings: self
                .zeros
                .into_iter()
                .filter(|z| z.0 >= from_s - WINDOW_S)
                .collect(),
            stand: Some((from_s, self.last_s)),
        })
    }
}

/// The gaps of an odometer's speed readings, each its time, s, and the trapezoid's
/// distance, m (`next` gives them in order, then `None`: a speed file's lines), in order,
/// with the readings around each. At most 10 000; the count of the others is returned
/// too.
pub fn find_gaps<E>(
    mut next: impl FnMut() -> Result<Option<(f64, f64)>, E>,
) -> Result<(Vec<Gap>, u64), E> {
    let mut finder = GapFinder::default();
    while let Some(r) = next()? {
        finder.push(r);
    }
    Ok(finder.finish())
}

/// The gaps and stands of an odometer's speed readings, found as the readings are
/// pushed ([`find_gaps`] for a whole file; the ingest's 8th column as it streams).
#[derive(Default)]
pub struct GapFinder {
    /// The gaps found, the last one still collecting its readings after it when
    /// `collecting`.
    gaps: Vec<Gap>,
    /// Gaps beyond [`MAX_GAPS`] or [`MAX_KEPT_READINGS`], counted only.
    more: u64,
    /// Readings kept in `gaps`.
    kept: usize,
    /// The readings over the last [`WINDOW_S`].
    before: VecDeque<(f64, f64)>,
    /// The file's last intervals between readings, s.
    intervals: VecDeque<f64>,
    /// The last gap's readings after it are being collected.
    collecting: bool,
    stand: Option<OpenStand>,
}

impl GapFinder {
    /// Takes the next reading: its time, s, and distance, m. True when it ends a gap
    /// kept (not a stand).
    pub fn push(&mut self, r: (f64, f64)) -> bool {
        let mut gap_here = false;
        let mut kept_here = false;
        if let Some(&(t0, d0)) = self.before.back() {
            let dt = r.0 - t0;
            // The median of the recent intervals, sorted on the stack (the 8th column
            // pushes a reading per IMU sample).
            let mut recent = [0.0; RECENT];
            let n = self.intervals.len();
            recent[..n].copy_from_slice(self.intervals.make_contiguous());
            recent[..n].sort_by(f64::total_cmp);
            // The file's first interval, with no rate to judge it by, is not a gap.
            let typical = if n > 0 { recent[n / 2] } else { f64::INFINITY };
            if dt > MIN_GAP_S && dt > GAP_PERIODS * typical {
                if self.gaps.len() < MAX_GAPS && self.kept + self.before.len() < MAX_KEPT_READINGS {
                    self.kept += self.before.len();
                    self.gaps.push(Gap {
                        from_s: t0,
                        to_s: r.0,
                        readings: self.before.iter().copied().collect(),
                        stand: None,
                    });
                    self.collecting = true;
                    kept_here = true;
                } else {
                    self.more += 1;
                    self.collecting = false;
                }
                self.before.clear();
                self.stand = None;
                gap_here = true;
            } else {
                if self.intervals.len() == RECENT {
                    self.intervals.pop_front();
                }
                self.intervals.push_back(dt);
            }
            // A distance that stands (zero speeds at both readings) starts or goes on
            // with a stand; one that moves ends it, judged by the IMU when long enough.
            if !gap_here && r.1 == d0 {
                match &mut self.stand {
                    Some(open) => open.push(r),
                    None => {
                        let before = &self.before;
                        let from_s = before.len().checked_sub(2).map_or(t0, |k| before[k].0);
                        let mut open = OpenStand {
                            from_s,
                            first_s: t0,
                            last_s: t0,
                            before: before.iter().copied().filter(|b| b.0 <= from_s).collect(),
                            zeros: VecDeque::from([(t0, d0)]),
                        };
                        open.push(r);
                        self.stand = Some(open);
                    }
                }
            } else if let Some(g) = self.stand.take().and_then(|open| open.judged(r.0))
                && self.gaps.len() < MAX_GAPS
                && self.kept + g.readings.len() < MAX_KEPT_READINGS
            {
                self.kept += g.readings.len();
                self.gaps.push(g);
                self.collecting = true;
            }
        }
        if self.collecting
            && let Some(g) = self.gaps.last_mut()
        {
            if r.0 - g.to_s <= WINDOW_S
                && g.readings.len() < 2 * MAX_WINDOW_READINGS
                && self.kept < MAX_KEPT_READINGS
            {
                self.kept += 1;
                g.readings.push(r);
            } else {
                self.collecting = false;
            }
        }
        self.before.push_back(r);
        while self.before.len() > MAX_WINDOW_READINGS
            || self.before.front().is_some_and(|f| r.0 - f.0 > WINDOW_S)
        {
            self.before.pop_front();
        }
        kept_here
    }

    /// The gaps found, in order, and the count of those beyond the caps.
    pub fn finish(self) -> (Vec<Gap>, u64) {
        (self.gaps, self.more)
    }

    /// No reading before `t_s` is to come (a stream whose readings may be missing): a
    /// gap whose window after it ends before then has all its readings.
    pub fn read_to(&mut self, t_s: f64) {
        if self.collecting && self.gaps.last().is_some_and(|g| t_s - g.to_s > WINDOW_S) {
            self.collecting = false;
        }
    }

    /// The gaps whose readings after them are all read, in order, taken out.
    pub fn take_complete(&mut self) -> Vec<Gap> {
        let n = self.gaps.len() - usize::from(self.collecting && !self.gaps.is_empty());
        let done: Vec<Gap> = self.gaps.drain(..n).collect();
        self.kept = (self.kept).saturating_sub(done.iter().map(|g| g.readings.len()).sum());
        done
    }

    /// The gap the last reading ended ([`GapFinder::push`] true), taken out when it is
    /// too long to bridge (it needs no readings after it): its first and last times, s.
    pub fn take_long_gap(&mut self) -> Option<(f64, f64)> {
        let g = self.gaps.last()?;
        if !self.collecting || g.is_stand() || g.to_s - g.from_s <= MAX_BRIDGED_S {
            return None;
        }
        let g = self.gaps.pop()?;
        self.kept = self.kept.saturating_sub(g.readings.len());
        self.collecting = false;
        Some((g.from_s, g.to_s))
    }

    /// Forgets the gaps and the stand not complete yet (a stream whose time tags stand
    /// would hold its readings whole); returns the gaps among them (not stands).
    pub fn forget_unsettled(&mut self) -> u64 {
        self.stand = None;
        self.collecting = false;
        self.kept = 0;
        self.gaps.drain(..).filter(|g| !g.is_stand()).count() as u64
    }

    /// The earliest time, s, from which a reading read so far may still be replaced: by
    /// a gap collecting its readings after it, a stand going on (a long stand's failure
    /// begins within [`MAX_BRIDGED_S`] of its end), or a stand the next reading may
    /// begin (from the reading before the last). `None` before the first reading.
    pub fn unsettled_from_s(&self) -> Option<f64> {
        let n = self.before.len();
        let next_stand = self.before.get(n.saturating_sub(2)).map(|r| r.0);
        let gap = self.gaps.first().map(|g| g.from_s);
        let stand = self.stand.as_ref().map(|open| {
            let latest_s = self.before.back().map_or(open.last_s, |r| r.0);
            open.from_s.max(latest_s - MAX_BRIDGED_S)
        });
        [next_stand, gap, stand]
            .into_iter()
            .flatten()
            .reduce(f64::min)
    }
}

/// A speed file's next reading, for [`find_gaps`]: its time, s, and distance, m.
pub fn file_readings<R: BufRead>(
    reader: &mut OdometerFileReader<R>,
) -> Result<Option<(f64, f64)>, FormatError> {
    Ok(reader.next_sample()?.map(|s| (s.t_s, s.distance_m)))
}

/// A time of the file, s, as the ingest tags it, ns.
pub fn tag_ns(t_s: f64) -> i64 {
    (t_s * 1e9).round() as i64
}

/// A gap as bridged.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BridgedGap {
    /// The last reading before it, ns ([`tag_ns`]): the file's readings after it and
    /// before `to_ns` (a stand's) are the bridge's rows' to replace.
    from_ns: i64,
    /// The first reading after it, ns, tagged as the ingest tags the file's readings
    /// ([`tag_ns`]): it is met by the reading itself, whatever the float rounding.
    to_ns: i64,
    /// The rows across it: each IMU sample's time tag, ns, and the route's distance in the
    /// file's distance (before the earlier gaps' offsets), m.
    rows: Vec<(i64, f64)>,
    /// Added to the file's distances from `to_ns` on, m.
    after_offset_m: f64,
}

/// An IMU sample: its time tag, ns, its angle and velocity increments (body FRD; rad,
/// m/s).
pub(crate) type ImuSample = (i64, [f64; 3], [f64; 3]);

/// The IMU's samples in the gaps' windows, collected as the ingest streams them, each
/// gap bridged once its window is whole.
pub struct GapBridger {
    gaps: VecDeque<Gap>,
    /// Gaps longer than [`MAX_BRIDGED_S`] (from, to; s): their samples are counted only.
    long: VecDeque<(f64, f64)>,
    /// Windows being filled: the gap, and the IMU samples in its window so far.
    open: VecDeque<(Gap, Vec<ImuSample>)>,
    /// The gaps bridged, in order.
    done: VecDeque<BridgedGap>,
    failures: OdometerFailures,
    g_mps2: f64,
    lag_prior_s: f64,
    more_gaps: u64,
}

impl GapBridger {
    /// Bridges `gaps` (of [`find_gaps`], `more_gaps` beyond them) where gravity is
    /// `g_mps2`, the odometer's lag searched about `lag_prior_s`.
    pub fn new(gaps: Vec<Gap>, more_gaps: u64, g_mps2: f64, lag_prior_s: f64) -> Self {
        let (gaps, long): (Vec<Gap>, Vec<Gap>) = gaps
            .into_iter()
            .partition(|g| g.to_s - g.from_s <= MAX_BRIDGED_S);
        let stands = gaps.iter().filter(|g| g.stand.is_some()).count();
        let failures = OdometerFailures {
            file_gaps: (gaps.len() + long.len() - stands) as u64 + more_gaps,
            not_bridged: long.len() as u64,
            ..OdometerFailures::default()
        };
        Self {
            gaps: gaps.into(),
            long: long.iter().map(|g| (g.from_s, g.to_s)).collect(),
            open: VecDeque::new(),
            done: VecDeque::new(),
            failures,
            g_mps2,
            lag_prior_s,
            more_gaps,
        }
    }

    /// Takes the next IMU sample (time tags increasing).
    pub fn sample(&mut self, t_ns: i64, dtheta_rad: [f64; 3], dvel_mps: [f64; 3]) {
        let t_s = t_ns as f64 * 1e-9;
        while self.long.front().is_some_and(|g| g.1 <= t_s) {
            self.long.pop_front();
        }
        if self.long.front().is_some_and(|g| g.0 < t_s) {
            self.failures.not_bridged_samples += 1;
        }
        while self.gaps.front().is_some_and(|g| g.span_s().0 <= t_s) {
            let g = self.gaps.pop_front().expect("a gap in front");
            self.open.push_back((g, Vec::new()));
        }
        for (g, samples) in &mut self.open {
            if t_s <= g.span_s().1 {
                samples.push((t_ns, dtheta_rad, dvel_mps));
            }
        }
        while self.open.front().is_some_and(|(g, _)| g.span_s().1 < t_s) {
            let (g, samples) = self.open.pop_front().expect("a window in front");
            self.close(g, samples);
        }
    }

    /// Bridges the gap `g` with the IMU's `samples` over its window ([`close`]).
    fn close(&mut self, g: Gap, samples: Vec<ImuSample>) {
        let bridged = close(
            g,
            samples,
            self.g_mps2,
            self.lag_prior_s,
            &mut self.failures,
        );
        self.done.extend(bridged);
    }

    /// Bridges the gaps whose windows the IMU's samples ended in (with the samples
    /// there); a gap after the last sample is left to the trapezoid, counted.
    pub fn finish(mut self) -> BridgedGaps {
        while let Some((g, samples)) = self.open.pop_front() {
            self.close(g, samples);
        }
        self.failures.not_bridged += self.gaps.len() as u64 + self.more_gaps;
        BridgedGaps {
            gaps: self.done,
            offset_m: 0.0,
            failures: self.failures,
        }
    }
}

/// Bridges the gap `g` with the IMU's `samples` over its window (at a site where gravity
/// is `g_mps2`, the odometer's lag searched about `lag_prior_s`), counted in `failures`;
/// a stand, only when the vehicle moved ([`stand_failed`]), from then on. `None`
/// when there is nothing to write across it: a stop, or a gap left to the trapezoid.
pub(crate) fn close(
    g: Gap,
    samples: Vec<ImuSample>,
    g_mps2: f64,
    lag_prior_s: f64,
    failures: &mut OdometerFailures,
) -> Vec<BridgedGap> {
    match g.stand {
        None => bridge_gap(g, &samples, false, g_mps2, lag_prior_s, failures)
            .into_iter()
            .collect(),
        Some(_) => stand_failed(&g, &samples, g_mps2, lag_prior_s)
            .into_iter()
            .filter_map(|f| {
                let failed = g.clone().failed_between(f);
                bridge_gap(failed, &samples, true, g_mps2, lag_prior_s, failures)
            })
            .collect(),
    }
}

/// Bridges the gap `g` (a stand's failure when `stuck`) with the IMU's samples over its
/// window (among `samples`), counted in `failures`.
fn bridge_gap(
    g: Gap,
    samples: &[ImuSample],
    stuck: bool,
    g_mps2: f64,
    lag_prior_s: f64,
    failures: &mut OdometerFailures,
) -> Option<BridgedGap> {
    let (first_s, last_s) = g.span_s();
    let samples: Vec<&ImuSample> = samples
        .iter()
        .filter(|s| (first_s..=last_s).contains(&(s.0 as f64 * 1e-9)))
        .collect();
    let length_s = g.to_s - g.from_s;
    let window: Vec<BridgeSample> = samples
        .iter()
        .map(|&&(t_ns, dtheta_rad, dvel_mps)| {
            let t_s = t_ns as f64 * 1e-9;
            BridgeSample {
                t_s,
                dtheta_rad,
                dvel_mps,
                reading: g.reading_at(t_s),
            }
        })
        .collect();
    let failed = window
        .iter()
        .filter(|s| matches!(s.reading, Reading::Failed))
        .count() as u64;
    let f = failures;
    if stuck {
        f.stuck += 1;
        f.stuck_samples += failed;
    }
    let Some(b) = bridge(&window, g_mps2, lag_prior_s) else {
        // Left to the trapezoid: nothing to write across it.
        f.not_bridged += 1;
        f.not_bridged_samples += failed;
        return None;
    };
    f.bridged += 1;
    f.bridged_samples += failed;
    f.longest_bridged_s = f.longest_bridged_s.max(length_s);
    f.bridged_distance_m += b.across_m;
    f.worst_residual_m = f.worst_residual_m.max(b.rms_residual_m);
    let at = window
        .iter()
        .zip(&samples)
        .filter(|(s, _)| matches!(s.reading, Reading::Failed))
        .map(|(_, s)| s.0);
    Some(BridgedGap {
        from_ns: tag_ns(g.from_s),
        to_ns: tag_ns(g.to_s),
        rows: at.zip(b.failed_distance_m).collect(),
        after_offset_m: b.after_offset_m,
    })
}

/// The bridged gaps, to write with the file's readings (a gap not bridged keeps the
/// file's trapezoid: nothing to write).
#[derive(Default)]
pub struct BridgedGaps {
    gaps: VecDeque<BridgedGap>,
    /// The earlier gaps' offsets, m.
    offset_m: f64,
    failures: OdometerFailures,
}

impl BridgedGaps {
    /// How the gaps were bridged.
    pub fn failures(&self) -> &OdometerFailures {
        &self.failures
    }

    /// How the gaps were bridged, to count more in.
    pub(crate) fn failures_mut(&mut self) -> &mut OdometerFailures {
        &mut self.failures
    }

    /// Bridges the gap `g`, found after the gaps bridged so far, with the IMU's
    /// `samples` over its window ([`close`]).
    pub(crate) fn close(&mut self, g: Gap, samples: Vec<ImuSample>, g_mps2: f64, lag_prior_s: f64) {
        let bridged = close(g, samples, g_mps2, lag_prior_s, &mut self.failures);
        self.gaps.extend(bridged);
    }

    /// Gives the file's reading at `t_ns` (its distance `distance_m`, as the file gives
    /// it) to `out` with the route's distance, after the rows of the gaps that end at it.
    pub fn give(&mut self, t_ns: i64, distance_m: f64, mut out: impl FnMut(i64, Given)) {
        // A stand's readings are replaced by its bridge.
        if self
            .gaps
            .front()
            .is_some_and(|g| g.from_ns < t_ns && t_ns < g.to_ns)
        {
            return;
        }
        while self.gaps.front().is_some_and(|g| g.to_ns <= t_ns) {
            let g = self.gaps.pop_front().expect("a gap in front");
            for (t, d) in g.rows {
                out(t, (d + self.offset_m, DistanceSource::Bridged));
            }
            self.offset_m += g.after_offset_m;
        }
        out(t_ns, (distance_m + self.offset_m, DistanceSource::Reading));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use unz_formats::manifest::OdometerKind;

    fn gaps_of(text: &str) -> (Vec<Gap>, u64) {
        let mut r = OdometerFileReader::new(text.as_bytes(), OdometerKind::SpeedMps);
        find_gaps(|| file_readings(&mut r)).unwrap()
    }

    #[test]
    fn stands_of_three_seconds_or_more_are_judged() {
        // 1 Hz: driving at 10 m/s, zero speed over 40–50 s (eleven readings), driving,
        // zero over 80–81 s (too short), driving, zero over 100–300 s (too long to
        // bridge whole), driving to 310 s.
        let stood =
            |t: u32| (40..=50).contains(&t) || (80..=81).contains(&t) || (100..=300).contains(&t);
        let text: String = (0..=310)
            .map(|t| format!("{t} {}\n", if stood(t) { 0.0 } else { 10.0 }))
            .collect();
        let (gaps, more) = gaps_of(&text);
        assert_eq!((gaps.len(), more), (2, 0), "{gaps:?}");
        // The long stand's last two minutes, from a reading at rest.
        let long = &gaps[1];
        assert_eq!(
            (long.from_s, long.to_s, long.stand),
            (181.0, 301.0, Some((181.0, 300.0)))
        );
        let times: Vec<f64> = long.readings.iter().map(|r| r.0).collect();
        assert_eq!((times[0], times[times.len() - 1]), (171.0, 310.0));
        let g = &gaps[0];
        // From the reading before its first zero to the first reading after its last.
        assert_eq!(
            (g.from_s, g.to_s, g.stand),
            (39.0, 51.0, Some((40.0, 50.0)))
        );
        // Its readings: the window before it, its own, and the window after it.
        let times: Vec<f64> = g.readings.iter().map(|r| r.0).collect();
        assert_eq!(times.first(), Some(&30.0));
        assert_eq!(times.last(), Some(&61.0));
        assert!((40..=50).all(|t| times.contains(&f64::from(t))));
        // The file's own distance across it: the half-trapezoids at its ends.
        let d = |t: f64| g.readings.iter().find(|r| r.0 == t).unwrap().1;
        assert!((d(51.0) - d(39.0) - 10.0).abs() < 1e-9);
        // Judged without samples: not a failure.
        assert_eq!(stand_failed(g, &[], 9.81, 0.0), []);
        // A failure from 45 s: the gap from the last reading at rest before it.
        let f = g.clone().failed_between(StandFailure {
            from_s: 45.2,
            until_s: None,
            after_s: f64::NEG_INFINITY,
        });
        assert_eq!((f.from_s, f.to_s, f.stand), (45.0, 51.0, None));
        assert!(f.readings.iter().all(|r| r.0 <= 45.0 || r.0 >= 51.0));
        // A failure from its start until 47.5 s: to the first reading at rest after
        // then, the readings from there kept over a window.
        let f = g.clone().failed_between(StandFailure {
            from_s: 39.0,
            until_s: Some(47.5),
            after_s: f64::NEG_INFINITY,
        });
        assert_eq!((f.from_s, f.to_s, f.stand), (39.0, 48.0, None));
        let times: Vec<f64> = f.readings.iter().map(|r| r.0).collect();
        assert_eq!((times[0], times[times.len() - 1]), (30.0, 58.0));
        assert!(!times.iter().any(|&t| t > 39.0 && t < 48.0));
    }

    /// A car that brakes from 10 m/s at 1 m/s² to rest at 40 s, stands to 70 s and
    /// pulls away at 2 m/s² (level ground, a 10-Hz IMU), its 1-Hz speed file zero from
    /// 32 s to 72 s: two stretches, into the stop (from the last reading before the
    /// zeros to the rest the backward watch finds) and out of it (from the watch's start
    /// before the drive-off); the stop's readings between are kept. Bridged, they give the
    /// route's distance.
    #[test]
    fn a_speed_that_stood_into_a_stop_and_out_of_it_fails_twice() {
        let speed = |t: f64| match t {
            t if t < 30.0 => 10.0,
            t if t < 40.0 => 10.0 - (t - 30.0),
            t if t < 70.0 => 0.0,
            t if t < 75.0 => 2.0 * (t - 70.0),
            _ => 10.0,
        };
        let text: String = (0..=100)
            .map(|t| {
                let v = if (32..=72).contains(&t) {
                    0.0
                } else {
                    speed(f64::from(t))
                };
                format!("{t} {v}\n")
            })
            .collect();
        let (gaps, _) = gaps_of(&text);
        let g = gaps.iter().find(|g| g.is_stand()).expect("the stand");
        assert_eq!((g.from_s, g.to_s), (31.0, 73.0));
        let samples: Vec<ImuSample> = (1..=1000)
            .map(|k| {
                let t = f64::from(k) * 0.1;
                let dv = speed(t) - speed(t - 0.1);
                ((k as i64) * 100_000_000, [0.0; 3], [dv, 0.0, -0.981])
            })
            .collect();
        let f = stand_failed(g, &samples, 9.81, 0.0);
        assert_eq!(f.len(), 2, "{f:?}");
        assert_eq!(f[0].from_s, 31.0);
        let rest_s = f[0].until_s.expect("the rest");
        assert!((40.0..47.0).contains(&rest_s), "{f:?}");
        assert!((63.0..70.0).contains(&f[1].from_s), "{f:?}");
        assert_eq!(f[1].until_s, None);
        // Bridged: the route's distance across both, as the file's intact trapezoid.
        let mut failures = OdometerFailures::default();
        let bridged = close(g.clone(), samples, 9.81, 0.0, &mut failures);
        assert_eq!((failures.stuck, failures.bridged, bridged.len()), (2, 2, 2));
        // From 9 m/s at 31 s to rest at 1 m/s²: 40.5 m; from rest at 70 s to 73 s at
        // 2 m/s²: 9 m.
        let truth_m = 40.5 + 9.0;
        assert!(
            (failures.bridged_distance_m - truth_m).abs() < 1.0,
            "{failures:?} against {truth_m} m"
        );
    }

    /// A vehicle standing on a 5° slope, its body turned about its own z axis by 90°
    /// over 10 s (the slope's fall moves from its nose to its side): at rest throughout.
    /// Gravity carried by the gyros, its speed stays zero; taken to first order (as
    /// the standing watch does over seconds), it would be metres per second off.
    #[test]
    fn a_body_turning_on_a_slope_at_rest_has_no_speed() {
        let pitch = 5f64.to_radians();
        let down = Vector3::new(-pitch.sin(), 0.0, pitch.cos());
        let (dt, rate) = (0.01, std::f64::consts::FRAC_PI_2 / 10.0);
        let samples: Vec<ImuSample> = (1..=1400)
            .map(|k| {
                let t = f64::from(k) * dt;
                let yaw = |t: f64| {
                    if t < 2.0 {
                        0.0
                    } else {
                        rate * (t - 2.0).min(10.0)
                    }
                };
                let dyaw = yaw(t) - yaw(t - dt);
                let c = Rotation3::from_scaled_axis(Vector3::z() * yaw(t - 0.5 * dt));
                let f = -9.81 * (c.transpose() * down);
                ((k as i64) * 10_000_000, [0.0, 0.0, dyaw], (f * dt).into())
            })
            .collect();
        let t_of = |s: &ImuSample| s.0 as f64 * 1e-9;
        let v = speed_from_rest(&samples, 9.81, dt, &t_of, 0.0, 13.0).unwrap();
        assert!(v.abs() < 0.01, "{v} m/s");
        // Backwards from a rest at the end, the same.
        let v = speed_from_rest(&samples, 9.81, dt, &t_of, 12.0, 1.0).unwrap();
        assert!(v.abs() < 0.01, "{v} m/s");
    }

    #[test]
    fn a_gap_is_long_against_the_files_own_rate() {
        // 1 Hz at 2 m/s, a 20-s gap from 30 s, then on.
        let mut text = String::new();
        for t in (0..=30).chain(50..=70) {
            text += &format!("{t} 2.0\n");
        }
        let (gaps, more) = gaps_of(&text);
        assert_eq!((gaps.len(), more), (1, 0));
        let g = &gaps[0];
        assert_eq!((g.from_s, g.to_s), (30.0, 50.0));
        // Ten seconds each side, the reading at each end included.
        assert_eq!(g.readings.first().unwrap().0, 20.0);
        assert_eq!(g.readings.last().unwrap().0, 60.0);
        assert_eq!(g.readings.len(), 22);
        assert_eq!(g.reading_at(25.5), Reading::Before(51.0));
        assert_eq!(g.reading_at(40.0), Reading::Failed);
        // The file's trapezoid across the gap: 2 m/s over 20 s.
        assert_eq!(g.reading_at(55.0), Reading::After(110.0));
        // A file at 0.2 Hz has no gaps; two missed seconds at 1 Hz are not one.
        let slow: String = (0..20).map(|k| format!("{} 1.0\n", 5 * k)).collect();
        assert!(gaps_of(&slow).0.is_empty());
        let missed: String = (0..30)
            .filter(|t| *t != 11 && *t != 12)
            .map(|t| format!("{t} 1.0\n"))
            .collect();
        assert!(gaps_of(&missed).0.is_empty());
    }

    #[test]
    fn many_gaps_and_a_long_one_are_counted_in_bounded_memory() {
        // 30 000 gaps of 4 s between pairs of readings 1 s apart: 10 000 kept, the rest
        // counted.
        let text: String = (0..30_000)
            .flat_map(|k| [5 * k, 5 * k + 1])
            .map(|t| format!("{t} 1.0\n"))
            .collect();
        let (gaps, more) = gaps_of(&text);
        assert_eq!((gaps.len(), more), (MAX_GAPS, 30_000 - 1 - MAX_GAPS as u64));
        // An hour without readings, and IMU samples through it at 10 Hz: counted, never
        // held (a window is not opened for it), nothing bridged, nothing moved.
        let long = "0 1.0\n1 1.0\n2 1.0\n3602 1.0\n3603 1.0\n";
        let (gaps, more) = gaps_of(long);
        let mut bridger = GapBridger::new(gaps, more, 9.81, 0.0);
        for k in 0..36_100_i64 {
            bridger.sample(k * 100_000_000, [0.0; 3], [0.0, 0.0, -0.981]);
            assert!(bridger.open.is_empty());
        }
        let mut bridged = bridger.finish();
        let f = bridged.failures().clone();
        assert_eq!((f.file_gaps, f.bridged, f.not_bridged), (1, 0, 1), "{f:?}");
        assert_eq!(f.not_bridged_samples, 35_999);
        let mut out = Vec::new();
        bridged.give(3_602_000_000_000, 3602.0, |t, g| out.push((t, g)));
        assert_eq!(
            out,
            [(3_602_000_000_000, (3602.0, DistanceSource::Reading))]
        );
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]

        /// Any speed file (its intervals mostly a second, some of them gaps of up to
        /// 200 s) over a 10-Hz IMU of any increments: the rows come out in time order,
        /// finite, the file's readings and one per IMU sample bridged, inside the gaps;
        /// every gap is bridged or not, and every IMU sample inside one counted once.
        #[test]
        fn any_file_gives_rows_in_order_and_counts_that_add_up(
            steps in proptest::collection::vec(
                proptest::prop_oneof![4 => 1.0f64..1.0001, 1 => 3.5f64..200.0],
                2..80,
            ),
            speeds in proptest::collection::vec(-1.0f64..30.0, 80),
            imu in proptest::collection::vec(
                (proptest::array::uniform3(-0.05f64..0.05), proptest::array::uniform3(-1.5f64..1.5)),
                64,
            ),
        ) {
            let mut t = 10.0;
            let mut text = format!("{t} {}\n", speeds[0]);
            for (k, dt) in steps.iter().enumerate() {
                t += dt;
                text += &format!("{t} {}\n", speeds[(k + 1) % speeds.len()]);
            }
            let end_s = t + 5.0;
            let (gaps, more) = gaps_of(&text);
            let spans: Vec<(f64, f64)> = gaps.iter().map(|g| (g.from_s, g.to_s)).collect();
            let mut bridger = GapBridger::new(gaps, more, 9.81, 0.0);
            let samples = (end_s * 10.0) as i64;
            for k in 1..=samples {
                let (dtheta, dvel) = imu[k as usize % imu.len()];
                let dvel = [dvel[0] * 0.1, dvel[1] * 0.1, -0.981 + dvel[2] * 0.01];
                bridger.sample(k * 100_000_000, dtheta.map(|w| w * 0.1), dvel);
            }
            let mut bridged = bridger.finish();
            let f = bridged.failures().clone();
            proptest::prop_assert_eq!(f.bridged + f.not_bridged, f.file_gaps);
            proptest::prop_assert_eq!(f.file_gaps, spans.len() as u64 + more);
            let inside = (1..=samples)
                .filter(|k| {
                    let t_s = (k * 100_000_000) as f64 * 1e-9;
                    spans.iter().any(|&(a, b)| a < t_s && t_s < b)
                })
                .count() as u64;
            proptest::prop_assert_eq!(f.bridged_samples + f.not_bridged_samples, inside);
            let mut reader = OdometerFileReader::new(text.as_bytes(), OdometerKind::SpeedMps);
            let mut rows: Vec<(i64, Given)> = Vec::new();
            let mut readings = 0;
            while let Some(o) = reader.next_sample().unwrap() {
                readings += 1;
                bridged.give(tag_ns(o.t_s), o.distance_m, |t, g| rows.push((t, g)));
            }
            proptest::prop_assert_eq!(rows.len() as u64, readings + f.bridged_samples);
            proptest::prop_assert!(rows.windows(2).all(|w| w[0].0 < w[1].0));
            proptest::prop_assert!(rows.iter().all(|r| r.1.0.is_finite()));
            for (t_ns, (_, source)) in &rows {
                if *source == DistanceSource::Bridged {
                    let t_s = *t_ns as f64 * 1e-9;
                    proptest::prop_assert!(spans.iter().any(|&(a, b)| a < t_s && t_s < b));
                }
            }
        }
    }

    /// Found by the property test: a gap's end whose time in ns, back in seconds, is below
    /// the time it came from was never met by its own reading, so its rows and offset
    /// were lost. The gap's end is now compared in the readings' own ns.
    #[test]
    fn a_gap_ends_at_its_reading_whatever_the_float_rounding() {
        let to_s = (0..100_000)
            .map(|k| 70.0 + f64::from(k) * 0.001_234_567_890_1)
            .find(|&t| (tag_ns(t) as f64) * 1e-9 < t)
            .expect("a time that does not round-trip");
        let text: String = (10..=15)
            .map(|t| format!("{t} 2.0\n"))
            .chain([format!("{to_s:?} 2.0\n")])
            .collect();
        let (gaps, more) = gaps_of(&text);
        let mut bridger = GapBridger::new(gaps, more, 9.81, 0.0);
        for k in 1..=((to_s + 5.0) * 10.0) as i64 {
            bridger.sample(k * 100_000_000, [0.0; 3], [0.2, 0.0, -0.981]);
        }
        let mut bridged = bridger.finish();
        let f = bridged.failures().clone();
        assert_eq!(f.bridged, 1, "{f:?}");
        let mut reader = OdometerFileReader::new(text.as_bytes(), OdometerKind::SpeedMps);
        let mut rows = 0;
        while let Some(o) = reader.next_sample().unwrap() {
            bridged.give(tag_ns(o.t_s), o.distance_m, |_, _| rows += 1);
        }
        assert_eq!(rows, 7 + f.bridged_samples);
    }

    #[test]
    fn bridged_rows_come_before_the_reading_that_ends_their_gap() {
        let mut gaps = BridgedGaps {
            gaps: VecDeque::from([BridgedGap {
                from_ns: 1_000_000_000,
                to_ns: 2_000_000_000,
                rows: vec![(1_500_000_000, 15.0)],
                after_offset_m: -3.0,
            }]),
            offset_m: 0.0,
            failures: OdometerFailures::default(),
        };
        let mut out = Vec::new();
        // A stand's reading inside the bridge (1.2 s) is the bridge's to replace.
        for (t_ns, d) in [
            (1_000_000_000, 10.0),
            (1_200_000_000, 10.0),
            (2_000_000_000, 23.0),
        ] {
            gaps.give(t_ns, d, |t, given| out.push((t, given)));
        }
        assert_eq!(
            out,
            [
                (1_000_000_000, (10.0, DistanceSource::Reading)),
                (1_500_000_000, (15.0, DistanceSource::Bridged)),
                (2_000_000_000, (20.0, DistanceSource::Reading)),
            ]
        );
    }
}
