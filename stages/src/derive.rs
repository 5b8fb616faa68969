//! Stage 2, derive: odometer terms and accelerometer pitch/roll (paper eqs 6–11).
//!
//! Input: the IMU (time, angle and velocity increments) and the odometer's cumulative
//! distance at its own rate. Output, per IMU sample: the repaired interval `dt`, the
//! increments (a lost stretch filled with the mean of the rates either side), the
//! odometer distance over the interval, and from these (computed where read, not stored:
//! [`Derived::odometer_speeds`], [`Derived::r_rad_s`]) `u` (eq 9), `u̇` (eq 10), yaw rate
//! `r`, `ru` (eq 11); per block of F
//! ([`crate::filter`]): the filtered `a_x`, `a_y`, `u̇`, `ru`; per epoch (ΔTg = 1 s):
//! accelerometer pitch Θ_p and roll Φ_p (eqs 7–8) and whether the simplified model (6)
//! holds well enough to use the epoch (hard braking and hard turns are gated out).
//!
//! Not guaranteed: sideslip, lever arms and the Earth-rate part of the yaw rate are not
//! modelled (eq 6's simplifications; each below 0.01° on a land vehicle).

use std::sync::Arc;

use either::Either;

use crate::angle_increments::{AngleIncrements, AngleSlice, Increment3};
use crate::filter::{FilterParams, LowPass};
use crate::lost_samples::{Closed, LostSamples};
use crate::nth_smallest::median;
use crate::time_base::{TagIter, TagTimes, TagsFrom, TimeBase, Times};

/// Parameters of the derive stage.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DeriveParams {
    /// The low-pass filter F.
    pub filter: FilterParams,
    /// Epoch spacing ΔTg, s (100·ΔT = 1 s at 100 Hz).
    pub epoch_s: f64,
    /// Time added to the odometer's time tags to align them with the IMU, s (within
    /// ±[`ODO_TIME_OFFSET_RANGE_S`]).
    pub odo_time_offset_s: f64,
    /// Epochs with |filtered u̇| above this are gated out, m/s².
    pub gate_long_mps2: f64,
    /// Epochs with |filtered ru| above this are gated out, m/s².
    pub gate_lat_mps2: f64,
    /// Longest gap in the IMU's time tags the derive bridges, s (filled from the rates
    /// either side); a longer one fails the run. The turns across a gap are unknown, and
    /// so is the gyros' noise: an LN-200's angle random walk held from one 10-ms sample
    /// turns the heading by 0.12° (1σ) over 10 s. A pause at rest may be worth raising it.
    pub max_gap_s: f64,
}

/// Largest `odo_time_offset_s` either way, s: a logger's clock set by hand is seconds
/// off; a time zone's or a day's difference leaves no overlap, which the ingest refuses.
pub const ODO_TIME_OFFSET_RANGE_S: f64 = 60.0;

impl Default for DeriveParams {
    fn default() -> Self {
        Self {
            filter: FilterParams::default(),
            epoch_s: 1.0,
            odo_time_offset_s: 0.0,
            gate_long_mps2: 1.5,
            gate_lat_mps2: 1.5,
            max_gap_s: 2.0,
        }
    }
}

/// Raw IMU and odometer columns, as ingested.
#[derive(Debug, Clone, Copy)]
pub struct RawSeries<'a> {
    /// IMU time, ns.
    pub imu_t_ns: &'a [i64],
    /// Angle increments, rad, body FRD.
    pub dtheta_rad: &'a [[f64; 3]],
    /// Velocity increments, m/s, body FRD.
    pub dvel_mps: &'a [[f64; 3]],
    /// Odometer time, ns (own rate).
    pub odo_t_ns: OdoTimes<'a>,
    /// Odometer cumulative distance, m.
    pub odo_distance_m: &'a [f64],
}

/// An ingested odometer's time tags, ns in the log's time base: one i64 each, or
/// compact ([`TagTimes`], as the disupt stage holds them for the lag's re-derives). Read
/// in order only.
#[derive(Debug, Clone, Copy)]
pub enum OdoTimes<'a> {
    /// One i64 per tag.
    Slice(&'a [i64]),
    /// Steps in 32 bits.
    Tags(&'a TagTimes),
}

impl<'a> OdoTimes<'a> {
    /// The tags in order, ns.
    fn iter(self) -> OdoTimesIter<'a> {
        match self {
            OdoTimes::Slice(t) => Either::Left(t.iter().copied()),
            OdoTimes::Tags(t) => Either::Right(t.iter()),
        }
    }
}

impl<'a> From<&'a [i64]> for OdoTimes<'a> {
    fn from(t: &'a [i64]) -> Self {
        OdoTimes::Slice(t)
    }
}

impl<'a> From<&'a Vec<i64>> for OdoTimes<'a> {
    fn from(t: &'a Vec<i64>) -> Self {
        OdoTimes::Slice(t)
    }
}

impl<'a> From<&'a TagTimes> for OdoTimes<'a> {
    fn from(t: &'a TagTimes) -> Self {
        OdoTimes::Tags(t)
    }
}

/// [`OdoTimes::iter`].
type OdoTimesIter<'a> = Either<std::iter::Copied<std::slice::Iter<'a, i64>>, TagIter<'a>>;

/// Everything the stage derives.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Derived {
    /// IMU time of the first sample, ns (times below count from it).
    pub t0_ns: i64,
    /// Nominal sample period (median interval), s.
    pub nominal_dt_s: f64,
    /// Per sample: time since `t0_ns`, s (repaired to increase): as computed, or whole
    /// nanoseconds once stored (then compact).
    ///
    /// The IMU's series (this, `dt_s`, `dtheta_rad`, `dvel_mps`) are shared (`Arc`),
    /// not copied, between a derive and its re-derives at other odometer timings: only
    /// the odometer's part differs.
    pub t_s: TimeBase,
    /// Per sample: the interval its increments were integrated over, s (a text log's:
    /// from the time before; a binary log's: its `seq` step times the nominal period,
    /// the IMU's, whatever a recorder's jittering tags say: [`LostSamples`]).
    pub dt_s: Arc<Vec<f64>>,
    /// Per sample: angle increments, rad (lost stretches filled from the rates either
    /// side), in f32 when every value is one exactly ([`AngleIncrements`]).
    pub dtheta_rad: Arc<AngleIncrements>,
    /// Per sample: velocity increments, m/s (likewise).
    pub dvel_mps: Arc<Vec<[f64; 3]>>,
    /// Samples whose increments are not the ingested ones, in order: scaled over a gap
    /// they close, or replaced beyond the instrument's range. Every other sample's are the
    /// ingest's, bit for bit (what lets the stored derive keep only these).
    pub replaced_increments: Vec<usize>,
    /// Per sample: odometer distance over the interval, m.
    pub odo_dist_m: Vec<f64>,
    /// Per block: filtered a_x, m/s² (shared with the re-derives at other odometer
    /// timings, which move the odometer's part only).
    pub ax_f: Arc<Vec<f64>>,
    /// Per block: filtered a_y, m/s² (likewise).
    pub ay_f: Arc<Vec<f64>>,
    /// Per block: filtered u̇, m/s².
    pub u_dot_f: Vec<f64>,
    /// Per block: filtered ru, m/s².
    pub ru_f: Vec<f64>,
    /// Per block: filtered r over the samples in which the odometer moved, rad/s (what an
    /// odometer speed bias adds to ru, per m/s).
    pub r_moving_f: Vec<f64>,
    /// Per block: filtered rate of change of "the odometer moved", 1/s (what an odometer
    /// speed bias adds to u̇, per m/s).
    pub moving_dot_f: Vec<f64>,
    /// Samples per block of F.
    pub block: usize,
    /// The epochs.
    pub epochs: Epochs,
    /// Samples whose time tag was repaired (not after the previous one).
    pub repaired_times: usize,
    /// Samples that closed a gap and were scaled to it.
    pub filled_gaps: usize,
    /// Samples whose status flags an IMU built-in-test failure (bit 0).
    pub imu_failure_samples: usize,
    /// Samples whose status flags an odometer failure (bit 1).
    pub odometer_failure_samples: usize,
    /// Samples whose increments exceed the IMU's measurement range ([`GYRO_RANGE_RAD_S`],
    /// [`ACCEL_RANGE_MPS2`]): saturated or corrupt counts, replaced by the previous
    /// sample's rates.
    pub out_of_range_samples: usize,
    /// The first of those (not stored: what a failing derive names).
    pub first_out_of_range: Option<usize>,
    /// What the increments say of the IMU's axes against the vehicle's (gravity's
    /// direction, the odometer's accelerations): set by the derive stage, which fails a
    /// log whose axes are not the vehicle's.
    pub axes_check: Option<crate::imu_axes::AxesCheck>,
    /// What the drive says of the odometer's clock at the offset configured (the shift
    /// at which its u̇ follows the accelerometers' x): set by the derive stage, which
    /// fails a log whose odometer is seconds off ([`crate::odo_clock`]).
    pub odometer_clock: Option<crate::odo_clock::ClockFit>,
    /// The segments the optimisers' passes read, integrated from these series on first
    /// use and kept (a memo: not part of the derive's value).
    pub segments: crate::strapdown::segments::SegmentMemo,
}

/// Eqs 9–11 at one sample ([`Derived::odometer_speeds`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometerSpeed {
    /// u, m/s (eq 9).
    pub u_mps: f64,
    /// u̇, m/s² (eq 10).
    pub u_dot_mps2: f64,
    /// ru, m/s² (eq 11).
    pub ru_mps2: f64,
}

/// The LN-200's gyro range, ±1000 °/s: an angle increment faster than this is not a
/// measurement.
pub const GYRO_RANGE_RAD_S: f64 = 1000.0 * std::f64::consts::PI / 180.0;
/// The LN-200's accelerometer range, ±40 g (the 70 g option included with margin: 70 g).
pub const ACCEL_RANGE_MPS2: f64 = 70.0 * 9.806_65;

/// Whether an IMU sample's angle and velocity increments over `dt_s` are within the
/// instrument's range ([`GYRO_RANGE_RAD_S`], [`ACCEL_RANGE_MPS2`]); a NaN increment is
/// not.
pub fn increments_in_range(dtheta_rad: [f64; 3], dvel_mps: [f64; 3], dt_s: f64) -> bool {
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    norm(dtheta_rad) <= GYRO_RANGE_RAD_S * dt_s && norm(dvel_mps) <= ACCEL_RANGE_MPS2 * dt_s
}

impl Derived {
    /// This derive without its odometer's part (its increments, block series and epochs
    /// left empty) — what a re-derive at another odometer timing starts from and fills,
    /// without copying the series it replaces. The IMU's series and blocks are shared.
    pub fn without_odometer_series(&self) -> Derived {
        Derived {
            t0_ns: self.t0_ns,
            nominal_dt_s: self.nominal_dt_s,
            t_s: self.t_s.clone(),
            dt_s: self.dt_s.clone(),
            dtheta_rad: self.dtheta_rad.clone(),
            dvel_mps: self.dvel_mps.clone(),
            replaced_increments: self.replaced_increments.clone(),
            odo_dist_m: Vec::new(),
            ax_f: self.ax_f.clone(),
            ay_f: self.ay_f.clone(),
            u_dot_f: Vec::new(),
            ru_f: Vec::new(),
            r_moving_f: Vec::new(),
            moving_dot_f: Vec::new(),
            block: self.block,
            epochs: Epochs::default(),
            repaired_times: self.repaired_times,
            filled_gaps: self.filled_gaps,
            imu_failure_samples: self.imu_failure_samples,
            odometer_failure_samples: self.odometer_failure_samples,
            out_of_range_samples: self.out_of_range_samples,
            first_out_of_range: self.first_out_of_range,
            axes_check: self.axes_check,
            odometer_clock: self.odometer_clock,
            segments: self.segments.for_other_odometer(),
        }
    }

    /// This derive without the odometer's block series (u̇, ru, r while moving, the rate
    /// of change of "moving"): what passes over it read is its epochs, made of them.
    pub fn without_block_series(mut self) -> Derived {
        for v in [
            &mut self.u_dot_f,
            &mut self.ru_f,
            &mut self.r_moving_f,
            &mut self.moving_dot_f,
        ] {
            *v = Vec::new();
        }
        self
    }

    /// Yaw rate r of sample `k`, rad/s (body z gyro: the angle increment over the
    /// interval).
    #[inline]
    pub fn r_rad_s(&self, k: usize) -> f64 {
        self.dtheta_rad.get(k)[2] / self.dt_s[k]
    }

    /// Eqs 9–11 at the samples `range`: u (the odometer's distance over the interval),
    /// u̇ (its change from the sample before, 0 at the first) and ru.
    pub fn odometer_speeds(
        &self,
        range: std::ops::Range<usize>,
    ) -> impl Iterator<Item = OdometerSpeed> + '_ {
        let u = |k: usize| self.odo_dist_m[k] / self.dt_s[k];
        let mut prev_u = range.start.checked_sub(1).map_or(0.0, u);
        range.map(move |k| {
            let u_mps = u(k);
            let u_dot_mps2 = if k == 0 {
                0.0
            } else {
                (u_mps - prev_u) / self.dt_s[k]
            };
            prev_u = u_mps;
            OdometerSpeed {
                u_mps,
                u_dot_mps2,
                ru_mps2: self.r_rad_s(k) * u_mps,
            }
        })
    }

    /// Absolute time (ns, the log's time base) of a time `t_s` since `t0_ns`.
    pub fn ns_of(&self, t_s: f64) -> i64 {
        ns_since(self.t0_ns, t_s)
    }

    /// Time of sample `k`, ns in the log's time base (as it is stored): [`Self::ns_of`]
    /// its time, bit for bit. A stored time is added to `t0_ns` as it is, without the
    /// round trip through seconds, within [`crate::time_base::ROUND_TRIP_NS_MAX`], where
    /// that trip gives it back.
    ///
    /// # Panics
    /// If `k` is not a sample.
    #[inline]
    pub fn t_ns_at(&self, k: usize) -> i64 {
        match self.t_s.nanos() {
            Some(t) => {
                let ns = t.ns(k);
                if ns.unsigned_abs() <= crate::time_base::ROUND_TRIP_NS_MAX.unsigned_abs() {
                    self.t0_ns + ns
                } else {
                    self.ns_of(t.get(k))
                }
            }
            None => self.ns_of(self.t_s.get(k)),
        }
    }

    /// Times of the samples `range` ([`Self::t_ns_at`] each).
    ///
    /// # Panics
    /// If the range goes past the samples.
    pub fn t_ns(&self, range: std::ops::Range<usize>) -> impl Iterator<Item = i64> + '_ {
        assert!(
            range.end <= self.t_s.len(),
            "{range:?} of {}",
            self.t_s.len()
        );
        range.map(|k| self.t_ns_at(k))
    }

    /// The navigation kernel's inputs.
    pub fn nav_inputs(&self) -> crate::strapdown::NavInputs<'_> {
        crate::strapdown::NavInputs {
            dt_s: &self.dt_s,
            dtheta_rad: self.dtheta_rad.view(),
            odo_dist_m: &self.odo_dist_m,
        }
    }

    /// Epoch times, ns.
    pub fn epoch_t_ns(&self) -> Vec<i64> {
        self.epochs.t_s.iter().map(|&t| self.ns_of(t)).collect()
    }
}

/// Absolute time (ns) of a time `t_s` seconds after `t0_ns` ns, to the nearest
/// nanosecond: how a derive's times are stored. A time beyond i64's nanoseconds is held
/// at its bound.
pub fn ns_since(t0_ns: i64, t_s: f64) -> i64 {
    t0_ns.saturating_add(round_to_i64(t_s * 1e9))
}

/// Seconds from `t0_ns` to `t_ns` (both ns), the way the derive reads its tags: a span
/// beyond i64's nanoseconds (a broken log's tags) is held at its bound, not wrapped.
#[inline]
pub fn seconds_since(t0_ns: i64, t_ns: i64) -> f64 {
    t_ns.saturating_sub(t0_ns) as f64 * 1e-9
}

/// `x.round() as i64`, bit for bit (halves away from zero, saturating, NaN to 0), without
/// libm's `round` call, which the writers paid for every sample: `x as i64` truncates in
/// one instruction, and the part it drops (`x` less an integer it is within one of) is
/// exact.
fn round_to_i64(x: f64) -> i64 {
    let whole = x as i64;
    let dropped = x - whole as f64;
    if dropped >= 0.5 {
        whole.saturating_add(1)
    } else if dropped <= -0.5 {
        whole.saturating_sub(1)
    } else {
        whole
    }
}

/// Epochs at ΔTg: one every `epoch_blocks` blocks.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Epochs {
    /// Block index of each epoch.
    pub block: Vec<usize>,
    /// Time of each epoch (middle of its block), s since `t0_ns`.
    pub t_s: Vec<f64>,
    /// Accelerometer pitch Θ_p, rad (eq 7).
    pub theta_p_rad: Vec<f64>,
    /// Accelerometer roll Φ_p, rad (eq 8).
    pub phi_p_rad: Vec<f64>,
    /// ∂Θ_p/∂δ: change of Θ_p per radian of odometer yaw boresight δ. Eqs 7–8 remove u̇
    /// along body x and ru along body y; with the odometer turned by δ they belong along
    /// (cos δ, sin δ) and (−sin δ, cos δ), which moves a_x's correction by ru·δ and a_y's
    /// by u̇·δ.
    pub theta_p_per_yaw: Vec<f64>,
    /// ∂Φ_p/∂δ, likewise.
    pub phi_p_per_yaw: Vec<f64>,
    /// ∂Θ_p/∂b: change of Θ_p per m/s of odometer speed bias b (u̇ gains b where the
    /// odometer starts or stops moving).
    pub theta_p_per_bias: Vec<f64>,
    /// ∂Φ_p/∂b (ru gains r·b while the odometer moves).
    pub phi_p_per_bias: Vec<f64>,
    /// Whether the epoch is used by the criteria.
    pub valid: Vec<bool>,
}

impl Epochs {
    /// The first `n` epochs (all of them when there are fewer).
    pub fn prefix(&self, n: usize) -> Self {
        let n = n.min(self.block.len());
        Self {
            block: self.block[..n].to_vec(),
            t_s: self.t_s[..n].to_vec(),
            theta_p_rad: self.theta_p_rad[..n].to_vec(),
            phi_p_rad: self.phi_p_rad[..n].to_vec(),
            theta_p_per_yaw: self.theta_p_per_yaw[..n].to_vec(),
            phi_p_per_yaw: self.phi_p_per_yaw[..n].to_vec(),
            theta_p_per_bias: self.theta_p_per_bias[..n].to_vec(),
            phi_p_per_bias: self.phi_p_per_bias[..n].to_vec(),
            valid: self.valid[..n].to_vec(),
        }
    }
}

/// The time the derive gives sample `k` in place of its tag's `t_s` (s from the first
/// tag), after the time it gave the sample before (`prev_t_s`), the next tag's time to
/// hand (`next_t_s`, read only when it matters), and the run's nominal interval; `None`
/// when the tag stands. A tag not after the time before is repaired one interval on; so
/// is one that leapt forward alone, its neighbours in order (a glitch in the recorder's
/// clock, its CRC made after it), short of the next: kept, it would make every later
/// tag go back from it.
#[inline]
pub fn repaired_time(
    k: usize,
    prev_t_s: f64,
    t_s: f64,
    next_t_s: impl FnOnce() -> Option<f64>,
    nominal_s: f64,
) -> Option<f64> {
    if k == 0 {
        return None;
    }
    if t_s <= prev_t_s {
        return Some(prev_t_s + nominal_s);
    }
    let next_t_s = next_t_s()?;
    (prev_t_s < next_t_s && next_t_s < t_s && t_s - prev_t_s > 1.5 * nominal_s)
        .then(|| prev_t_s + nominal_s.min(0.5 * (next_t_s - prev_t_s)))
}

/// Whether a log's first sample stands apart from the rest: the second tag goes back
/// from it while the log goes on from the second (a glitch in the first tag), or a gap
/// longer than `max_gap_s`, which no run bridges, parts it from a second sample that is
/// not apart itself (a lone line a logger wrote before it began). Kept as tagged, the
/// first would make every tag up to its own time go back from it, or fail the run on a
/// gap; the last sample has the same rule for a gap (its tag going back is any tag's).
pub fn first_sample_apart(tags_ns: &[i64], max_gap_s: f64) -> bool {
    let &[t0, t1, t2, ..] = tags_ns else {
        return false;
    };
    let gap_s = seconds_since;
    (t1 < t0 && t1 < t2) || (gap_s(t0, t1) > max_gap_s && gap_s(t1, t2) <= max_gap_s)
}

/// Cumulative odometer distance at time `t` (linear interpolation; held after the last
/// tag, and continued back over one interval before the first). Only tags later than the
/// last one kept, with a finite distance, are kept; they are read from the ingested series
/// as the calls advance, without a copy of the odometer's length.
struct OdoInterp<'a> {
    /// The tags from [`Self::from`] on.
    t_ns: OdoTimesIter<'a>,
    d: &'a [f64],
    /// Distances replacing some of `d`'s, and the rows after them moved.
    patch: Option<PatchCursor>,
    t0_ns: i64,
    offset_s: f64,
    /// The first two kept tags (time s, distance m): the time before the first continues
    /// their interval.
    first: Option<(f64, f64)>,
    second: Option<(f64, f64)>,
    /// The kept tag at or before the last call's time, and the kept tag after it.
    cur: (f64, f64),
    next: Option<(f64, f64)>,
    /// The ingested tag the search for the next kept one starts at.
    from: usize,
    /// The time of the last tag kept, s, and its step from the one kept before
    /// (infinite until there is one).
    last_t: Option<f64>,
    last_step_s: f64,
}

impl<'a> OdoInterp<'a> {
    fn new(
        t_ns: OdoTimes<'a>,
        d: &'a [f64],
        patch: Option<Arc<OdoPatch>>,
        t0_ns: i64,
        offset_s: f64,
    ) -> Self {
        let mut s = Self {
            t_ns: t_ns.iter(),
            d,
            patch: patch.map(PatchCursor::new),
            t0_ns,
            offset_s,
            first: None,
            second: None,
            cur: (0.0, 0.0),
            next: None,
            from: 0,
            last_t: None,
            last_step_s: f64::INFINITY,
        };
        s.first = s.next_kept();
        s.second = s.next_kept();
        s.cur = s.first.unwrap_or_default();
        s.next = s.second;
        s
    }

    /// The next tag kept (time s, distance m), if any. Inline: the navigation's passes
    /// read the odometer through it at every sample (out of line it cost the disupt
    /// process 3 % more instructions). Always: with the check for a tag that leapt
    /// forward, the compiler left it, and the interpolation around it, out of line, and
    /// the disupt process took 15 % longer (129.2 against 111.8 ms, alternately; 113.9
    /// against 117.3 inline).
    #[inline(always)]
    fn next_kept(&mut self) -> Option<(f64, f64)> {
        while self.from < self.d.len() {
            let t_ns = self.t_ns.next()?;
            let i = self.from;
            self.from += 1;
            let ts = seconds_since(self.t0_ns, t_ns) + self.offset_s;
            let d = PatchCursor::distance(&mut self.patch, self.d, i);
            if self.last_t.is_none_or(|last| ts > last) && d.is_finite() {
                if let Some(last) = self.last_t
                    && ts - last > 2.0 * self.last_step_s
                    && self.leapt_alone(last, ts)
                {
                    continue;
                }
                self.last_step_s = self.last_t.map_or(f64::INFINITY, |last| ts - last);
                self.last_t = Some(ts);
                return Some((ts, d));
            }
        }
        None
    }

    /// Whether a tag at `ts`, more than twice the last step after the last kept one (at
    /// `last`), leapt forward alone: the next tag falls between the two (a glitch in the
    /// recorder's clock, as [`derive_owned`] repairs the IMU's). Kept, it would hide every
    /// tag up to its time: a 10-minute run with one record's tag saturated held its
    /// distance from there on. Only such a step reads the next tag.
    #[cold]
    #[inline(never)]
    fn leapt_alone(&self, last: f64, ts: f64) -> bool {
        let next = self.t_ns.clone().next();
        next.is_some_and(|ns| {
            let next_s = seconds_since(self.t0_ns, ns) + self.offset_s;
            last < next_s && next_s < ts
        })
    }

    /// The tag's time, s (as [`Self::next_kept`] reads it).
    fn time_of(&self, t_ns: i64) -> f64 {
        seconds_since(self.t0_ns, t_ns) + self.offset_s
    }

    /// Before the first call of [`Self::at`]`(ts)`, moves on, when it can without reading
    /// the tags between, to a state that call passes through: at the last of `tags`' marks
    /// ([`TagTimes::marks`]) before `ts` where the marked tag and the one before are kept
    /// one after the other. `at` then goes on from there, the same bit for bit as from
    /// where it stood: a split walk's later stretch no longer reads every tag before it
    /// (with a part for each of 16 threads, the 12-hour disupt spent 2 s of CPU more on
    /// those reads). Returns the marked tag's index, or `None` where no mark is so (it
    /// stays).
    fn seek(&mut self, tags: &'a TagTimes, ts: f64) -> Option<usize> {
        /// Reachable marks looked at, at most, before giving up (a stretch of tags going
        /// back, or of failed readings, is read through instead).
        const TRIES: usize = 16;
        let mut tries = 0;
        for m in tags.marks().rev() {
            if m.index <= self.from || m.index >= self.d.len() || self.time_of(m.before_ns) > ts {
                continue;
            }
            if let Some(c) = self.restart_at(m) {
                return Some(c);
            }
            tries += 1;
            if tries == TRIES {
                break;
            }
        }
        None
    }

    /// [`Self::seek`] at mark `m`, if a walk from the first tag keeps the marked tag `c`
    /// and the one before, `c − 1`, one after the other; the state is then the walk's
    /// when it has just kept `c`, which depends on these two tags alone:
    /// - `c − 1` is kept when it is later than every tag before it (so than the last kept)
    ///   and its distance finite (the tag after it, `c`, being later, it did not leap
    ///   alone);
    /// - then `c` is, when later than `c − 1`, its distance finite, and the tag after it
    ///   not between the two (it did not leap alone).
    ///
    /// A distance patched ([`PatchCursor`]) is the patch's, its cursor moved to `c`.
    fn restart_at(&mut self, m: TagsFrom<'a>) -> Option<usize> {
        let c = m.index;
        let mut tags = m.tags;
        let t_before = self.time_of(m.before_ns);
        let t_c = self.time_of(tags.next()?);
        // (A mark's tag is never the first or second: there are tags before `c − 1`.)
        let later_than_all = self.time_of(m.max_earlier_ns) < t_before;
        // As [`Self::leapt_alone`] would find, were `c`'s step long enough to be asked.
        let leapt = tags.clone().next().is_some_and(|ns| {
            let t_next = self.time_of(ns);
            t_before < t_next && t_next < t_c
        });
        if !later_than_all || t_c <= t_before || leapt {
            return None;
        }
        let mut patch = self
            .patch
            .as_ref()
            .map(|p| PatchCursor::new(p.patch.clone()));
        let d_before = PatchCursor::distance(&mut patch, self.d, c - 1);
        let d_c = PatchCursor::distance(&mut patch, self.d, c);
        if !(d_before.is_finite() && d_c.is_finite()) {
            return None;
        }
        self.t_ns = Either::Right(tags);
        self.from = c + 1;
        self.patch = patch;
        self.cur = (t_before, d_before);
        self.next = Some((t_c, d_c));
        self.last_t = Some(t_c);
        self.last_step_s = t_c - t_before;
        Some(c)
    }

    /// Distance at `ts`; calls must come with non-decreasing `ts`.
    fn at(&mut self, ts: f64) -> f64 {
        let Some((t_first, d_first)) = self.first else {
            return 0.0;
        };
        while let Some(next) = self.next.filter(|&(t, _)| t <= ts) {
            self.cur = next;
            self.next = self.next_kept();
        }
        if ts <= t_first {
            // Before the first tag: continue the first interval's speed back over at most
            // that interval (a log that begins in motion), else hold.
            let Some((t_second, d_second)) = self.second else {
                return d_first;
            };
            let span = t_second - t_first;
            let back = (t_first - ts).min(span);
            return d_first - back * (d_second - d_first) / span;
        }
        let (t_i, d_i) = self.cur;
        let Some((t_next, d_next)) = self.next else {
            return d_i;
        };
        let w = (ts - t_i) / (t_next - t_i);
        d_i + w * (d_next - d_i)
    }
}

/// Distances that replace an ingested odometer's over some of its rows (its failures
/// bridged again, [`crate::odo_rebridge`]), each moving the rows after it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OdoPatch {
    /// In row order, not overlapping.
    pub spans: Vec<PatchSpan>,
}

/// Rows of an [`OdoPatch`].
#[derive(Debug, Clone, PartialEq)]
pub struct PatchSpan {
    /// The first row replaced.
    pub first: usize,
    /// The distances of the rows from `first` on, m.
    pub distance_m: Vec<f64>,
    /// Added to the ingested distances of the rows after the span (up to the next one),
    /// m: the moves of every span up to this one.
    pub shift_after_m: f64,
}

/// An [`OdoPatch`] read row by row, in order.
struct PatchCursor {
    patch: Arc<OdoPatch>,
    /// The first span not yet behind the rows read.
    span: usize,
    /// Added to the ingested distances where no span replaces them, m.
    shift_m: f64,
}

impl PatchCursor {
    /// `patch` read from its first row.
    fn new(patch: Arc<OdoPatch>) -> Self {
        Self {
            patch,
            span: 0,
            shift_m: 0.0,
        }
    }

    /// The distance of row `i` of `ingested_m` as `cursor` patches it (none: as ingested).
    /// Inline: [`OdoInterp::next_kept`] reads every row through it.
    #[inline(always)]
    fn distance(cursor: &mut Option<Self>, ingested_m: &[f64], i: usize) -> f64 {
        match cursor {
            Some(p) => p.at(i, ingested_m[i]),
            None => ingested_m[i],
        }
    }

    /// The distance of row `i` (not before the last one asked), whose ingested one is
    /// `ingested_m`. Out of line: most runs have no patch, and their odometer's reading
    /// loop stays as small as it was.
    #[inline(never)]
    fn at(&mut self, i: usize, ingested_m: f64) -> f64 {
        let spans = &self.patch.spans;
        while let Some(s) = spans.get(self.span)
            && s.first + s.distance_m.len() <= i
        {
            self.shift_m = s.shift_after_m;
            self.span += 1;
        }
        match spans.get(self.span) {
            Some(s) if i >= s.first => s.distance_m[i - s.first],
            _ => ingested_m + self.shift_m,
        }
    }
}

/// Runs the stage. `g_mps2` is the normal gravity at the site.
pub fn derive(raw: &RawSeries<'_>, params: &DeriveParams, g_mps2: f64) -> Derived {
    derive_owned(
        raw.imu_t_ns.into(),
        raw.dtheta_rad.to_vec(),
        raw.dvel_mps.to_vec(),
        |at| at.of(raw),
        &LostSamples::ByInterval,
        params,
        g_mps2,
    )
}

/// [`derive()`] of the IMU's increments given by value: they are repaired in place and
/// become the derive's, without a copy of the run's length; the angle increments are
/// compacted first ([`AngleIncrements::compact`], before anything else of the run's
/// length is made). The IMU's time tags, when given by value too, become its times in
/// place. The odometer is read once, by `increments_over` (its increments over the
/// samples: [`IncrementTimes::of`]), before the samples' intervals are made: an odometer
/// it owns goes when it returns. `lost` tells the samples that close a stretch of lost
/// ones (by the tags' intervals, or by a binary log's `seq`: [`LostSamples`]).
pub fn derive_owned(
    imu_t_ns: std::borrow::Cow<'_, [i64]>,
    mut dtheta_rad: Vec<[f64; 3]>,
    mut dvel_mps: Vec<[f64; 3]>,
    increments_over: impl FnOnce(IncrementTimes<'_>) -> Vec<f64>,
    lost: &LostSamples,
    params: &DeriveParams,
    g_mps2: f64,
) -> Derived {
    let n = imu_t_ns.len().min(dtheta_rad.len()).min(dvel_mps.len());
    let mut out = Derived::default();
    if n == 0 {
        return out;
    }
    dtheta_rad.truncate(n);
    let mut dtheta = AngleIncrements::compact(dtheta_rad);
    dvel_mps.truncate(n);
    // The median interval (the element a full sort of the positive ones puts in the
    // middle), read from the tags without a copy of them.
    let intervals_ns = || {
        imu_t_ns[..n]
            .windows(2)
            .filter_map(|w| w[1].checked_sub(w[0]))
            .filter(|&d| d > 0)
            .map(|d| d as u64)
    };
    // A binary log's: the tags' mean step per `seq` step, which a recorder's jitter does
    // not move.
    let nominal = median(intervals_ns)
        .map(|d| lost.period_ns(&imu_t_ns[..n], d))
        .map_or(0.01, |d| d as f64 * 1e-9);
    // A first sample apart from the rest takes its time one interval before the second's.
    let first_apart = first_sample_apart(&imu_t_ns[..n], params.max_gap_s);
    let t0 = if first_apart {
        imu_t_ns[1].saturating_sub((nominal * 1e9).round() as i64)
    } else {
        imu_t_ns[0]
    };
    out.t0_ns = t0;
    out.nominal_dt_s = nominal;

    // Time base, repaired: each tag becomes its time where it was stored (the f64's
    // bits written over the i64's, then the vector taken as the f64s it holds).
    let mut tags = imu_t_ns.into_owned();
    tags.truncate(n);
    let mut prev_t = -nominal;
    let mut last_moved = false;
    for k in 0..n {
        let mut t = seconds_since(t0, tags[k]);
        let next_t = || tags.get(k + 1).map(|&s| seconds_since(t0, s));
        let last_apart = || k + 1 == n && k >= 2 && t - prev_t > params.max_gap_s;
        if let Some(repaired) = repaired_time(k, prev_t, t, next_t, nominal) {
            t = repaired;
            out.repaired_times += 1;
        } else if (k == 0 && first_apart) || last_apart() {
            // Beside the sample next to it: a glitch in its tag, or a lone sample a
            // logger wrote at its start or end, carries no time of its own.
            last_moved = k + 1 == n;
            t = prev_t + nominal;
            out.repaired_times += 1;
        }
        tags[k] = t.to_bits() as i64;
        prev_t = t;
    }
    let t_s: Arc<Vec<f64>> = Arc::new(bytemuck::cast_vec(tags));
    out.t_s = TimeBase::Seconds(Arc::clone(&t_s));
    // The first sample's interval: from the time one nominal interval before it.
    let first_dt_s = t_s[0] - (-nominal);
    // The odometer's increments over the samples: the odometer is read once, and an
    // odometer given by value goes before the intervals are made.
    let increments = increments_over(IncrementTimes {
        t_s: &out.t_s,
        first_dt_s,
        t0_ns: t0,
        offset_s: params.odo_time_offset_s,
    });

    // Lost stretches filled from the rates either side ([`filled`]) and each sample's
    // interval (told by `lost`); increments beyond the instrument's range replaced by the
    // previous sample's rates.
    let mut prev_t = -nominal;
    let mut prev_rates = ([0.0; 3], [0.0; 3]);
    let mut dt_s = Vec::with_capacity(n);
    let mut scales = lost.scales();
    for (k, &t) in t_s.iter().enumerate() {
        let mut closed = scales.of(k, t - prev_t, nominal);
        // A first or last sample apart, placed beside its neighbour, closes no gap
        // whatever `seq` says (a text log's slots count the time apart).
        if (k == 1 && first_apart) || (k + 1 == n && last_moved) {
            closed = Closed {
                samples: 1.0,
                dt_s: nominal,
            };
        }
        let Closed {
            samples: scale,
            dt_s: dt,
        } = closed;
        let (own_dth, own_dv) = (dtheta.get(k), dvel_mps[k]);
        // The sample's own interval, s (one period when it closes a gap), and its
        // increments with the stretch it closes filled.
        let (own_dt, mut dth, mut dv) = if scale != 1.0 {
            out.filled_gaps += 1;
            let fill = |own, rate| filled(own, rate, nominal, dt);
            (
                nominal,
                fill(own_dth, prev_rates.0),
                fill(own_dv, prev_rates.1),
            )
        } else {
            (dt, own_dth, own_dv)
        };
        let replaced = if !increments_in_range(dth, dv, dt) {
            out.out_of_range_samples += 1;
            out.first_out_of_range.get_or_insert(k);
            dth = prev_rates.0.map(|w| w * dt);
            dv = prev_rates.1.map(|a| a * dt);
            true
        } else {
            prev_rates = (own_dth.map(|v| v / own_dt), own_dv.map(|v| v / own_dt));
            scale != 1.0
        };
        if replaced {
            out.replaced_increments.push(k);
            // (Unchanged, a sample is left as it is: times 1 is itself.)
            dtheta.set(k, dth);
        }
        dt_s.push(dt);
        dvel_mps[k] = dv;
        prev_t = t;
    }
    drop(t_s);
    (out.dt_s, out.dtheta_rad, out.dvel_mps) = (dt_s.into(), Arc::new(dtheta), dvel_mps.into());

    // The filter F, then eqs 7–8 at the epochs.
    let lp = LowPass::new(&params.filter, nominal);
    out.block = lp.block;
    let accel = |axis: usize| {
        let mut f = lp.block_means(
            out.dvel_mps
                .iter()
                .zip(out.dt_s.iter())
                .map(|(v, dt)| v[axis] / dt),
        );
        lp.filter_blocks(&mut f);
        f
    };
    (out.ax_f, out.ay_f) = (accel(0).into(), accel(1).into());
    odometer_blocks_from(&mut out, increments, &lp);
    out.epochs = epochs_of(&out, &lp, params, g_mps2);
    out
}

/// A sample's increment `own` over its own interval `own_dt_s` with the lost samples
/// before it filled in, over `dt_s` in all: the lost stretch's rate taken linear between
/// the rate of the sample before it (`prev_rate`) and this sample's own, whose mean over
/// the stretch (centred between the two samples' centres) is the mean of the two.
///
/// Before, the stretch held this sample's rate. Both are guesses of a rate nothing
/// measured, but a rate's error from its neighbours' mean is never larger in expectation
/// than from one of them (for a stationary rate of correlations ρ₁ and ρ₂ a sample and
/// two apart: 1.5 − 2ρ₁ + ρ₂/2 of its variance against 2 − 2ρ₁), and far smaller where
/// the rate turns: one line lost in a pitching turn (Kingston's at 600 s) tilted the
/// dead reckoning by 0.16° for the rest of the run, Kryt1 rose from 0.90 to 1.44 rad and
/// OWPI went 12° off.
fn filled(own: [f64; 3], prev_rate: [f64; 3], own_dt_s: f64, dt_s: f64) -> [f64; 3] {
    let lost_s = dt_s - own_dt_s;
    std::array::from_fn(|i| own[i] + lost_s * (prev_rate[i] + own[i] / own_dt_s) / 2.0)
}

/// Where an odometer's increments are taken ([`derive_owned`]'s): over the IMU's samples,
/// with the odometer's time tags moved by an offset.
#[derive(Debug, Clone, Copy)]
pub struct IncrementTimes<'a> {
    /// The samples' times, s since `t0_ns`.
    pub t_s: &'a TimeBase,
    /// The first sample's interval, s.
    pub first_dt_s: f64,
    /// The IMU's time of the first sample, ns.
    pub t0_ns: i64,
    /// Added to the odometer's times, s.
    pub offset_s: f64,
}

impl<'a> IncrementTimes<'a> {
    /// The odometer distance of `raw` over each sample's interval, m
    /// ([`odometer_increments`]).
    pub fn of(self, raw: &RawSeries<'a>) -> Vec<f64> {
        self.moved(raw).increments().collect()
    }

    /// `raw`'s odometer over these samples, its increments read as a pass goes.
    fn moved(self, raw: &RawSeries<'a>) -> MovedOdometer<'a> {
        MovedOdometer {
            t_s: self.t_s,
            first_dt_s: self.first_dt_s,
            t0_ns: self.t0_ns,
            odo_t_ns: raw.odo_t_ns,
            odo_distance_m: raw.odo_distance_m,
            offset_s: self.offset_s,
            patch: None,
        }
    }
}

/// The odometer's distance over each sample's interval of `d` with the odometer's time
/// tags moved by `offset_s`, m: all a navigation pass reads of the odometer.
pub fn odometer_increments(d: &Derived, raw: &RawSeries<'_>, offset_s: f64) -> Vec<f64> {
    MovedOdometer::new(d, raw, offset_s).increments().collect()
}

/// A derive's odometer increments with the odometer's time tags moved by an offset, read
/// from the ingested odometer as a pass goes instead of stored: what
/// [`odometer_increments`] gives, sample by sample.
#[derive(Debug, Clone)]
pub struct MovedOdometer<'a> {
    t_s: &'a TimeBase,
    /// Distances replacing some of the ingested ones.
    patch: Option<Arc<OdoPatch>>,
    first_dt_s: f64,
    t0_ns: i64,
    odo_t_ns: OdoTimes<'a>,
    odo_distance_m: &'a [f64],
    offset_s: f64,
}

impl<'a> MovedOdometer<'a> {
    /// The increments over the samples of `d` of `raw`'s odometer moved by `offset_s`.
    pub fn new(d: &'a Derived, raw: &RawSeries<'a>, offset_s: f64) -> Self {
        IncrementTimes {
            t_s: &d.t_s,
            first_dt_s: d.dt_s.first().copied().unwrap_or(0.0),
            t0_ns: d.t0_ns,
            offset_s,
        }
        .moved(raw)
    }

    /// This odometer with `patch`'s distances over some of its rows.
    pub fn patched(self, patch: Option<Arc<OdoPatch>>) -> Self {
        Self { patch, ..self }
    }

    /// The increments, m, one per sample from the first.
    pub fn increments(&self) -> OdoIncrements<'a> {
        self.increments_from(0)
    }

    /// The increments from sample `k` on (none past the last sample): those of
    /// [`Self::increments`] from its `k`-th, bit for bit (the interpolation's place in the
    /// odometer's rows depends on the time asked only).
    pub fn increments_from(&self, k: usize) -> OdoIncrements<'a> {
        let mut odo = OdoInterp::new(
            self.odo_t_ns,
            self.odo_distance_m,
            self.patch.clone(),
            self.t0_ns,
            self.offset_s,
        );
        let k = k.min(self.t_s.len());
        let prev_m = match k {
            0 => self
                .t_s
                .first()
                .map_or(0.0, |t| odo.at(t - self.first_dt_s)),
            _ => {
                let t = self.t_s.get(k - 1);
                if let OdoTimes::Tags(tags) = self.odo_t_ns {
                    odo.seek(tags, t);
                }
                odo.at(t)
            }
        };
        OdoIncrements {
            odo,
            t_s: self.t_s.range(k..self.t_s.len()),
            prev_m,
        }
    }
}

/// [`MovedOdometer::increments`].
pub struct OdoIncrements<'a> {
    odo: OdoInterp<'a>,
    t_s: Times<'a>,
    /// The distance at the end of the sample before, m.
    prev_m: f64,
}

impl Iterator for OdoIncrements<'_> {
    type Item = f64;

    fn next(&mut self) -> Option<f64> {
        let t = self.t_s.next()?;
        let now = self.odo.at(t);
        let dd = now - self.prev_m;
        self.prev_m = now;
        Some(dd)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.t_s.size_hint()
    }
}

impl ExactSizeIterator for OdoIncrements<'_> {}

/// The odometer's part of a derive with its time tags moved by `offset_s`: its increments
/// and F's block series of u̇, ru and the odometer-bias sensitivities (r while moving,
/// the rate of change of "moving"): [`odometer_blocks_of`].
pub fn odometer_blocks(out: &mut Derived, raw: &RawSeries<'_>, offset_s: f64, lp: &LowPass) {
    odometer_blocks_from(out, odometer_increments(out, raw, offset_s), lp);
}

/// [`odometer_blocks`] of the odometer's `increments` over each sample, m.
fn odometer_blocks_from(out: &mut Derived, increments: Vec<f64>, lp: &LowPass) {
    [out.u_dot_f, out.ru_f, out.r_moving_f, out.moving_dot_f] =
        odometer_blocks_split(out, lp, OdoBlockSeries::ALL, |k| {
            increments[k.min(increments.len())..].iter().copied()
        });
    out.odo_dist_m = increments;
}

/// F's block series of the odometer's part of `out` (u̇, ru, r while moving, the rate of
/// change of "moving") from its odometer `increments` over each sample (eqs 9–11, as
/// [`Derived::odometer_speeds`]). Block means are taken as the samples come, without
/// per-sample series of the run's length.
pub fn odometer_blocks_of(out: &mut Derived, increments: impl Iterator<Item = f64>, lp: &LowPass) {
    let mut blocks = OdometerBlocks::new(out, lp);
    for dd in increments.take(out.t_s.len()) {
        blocks.push(dd);
    }
    [out.u_dot_f, out.ru_f, out.r_moving_f, out.moving_dot_f] = blocks.finish(lp);
}

/// Blocks of F a run must have before [`odometer_blocks_split`] splits it between threads
/// (about 14 minutes at 100 Hz).
pub const SPLIT_BLOCKS: usize = 8192;

/// F's block series of the odometer's part of `d` ([`odometer_blocks_of`]'s, those
/// `series` leaves out empty), the increments from sample `k` on given by `increments_from(k)`:
/// the run is split into stretches of whole blocks taken side by side on rayon's threads
/// (each stretch resumes from the increment before its first sample), the same, bit for
/// bit, as one walk.
pub fn odometer_blocks_split<I, F>(
    d: &Derived,
    lp: &LowPass,
    series: OdoBlockSeries,
    increments_from: F,
) -> [Vec<f64>; 4]
where
    I: Iterator<Item = f64>,
    F: Fn(usize) -> I + Sync,
{
    let blocks = lp.blocks(d.t_s.len());
    let parts = rayon::current_num_threads().min(blocks / SPLIT_BLOCKS);
    odometer_blocks_in_parts(d, lp, series, increments_from, parts)
}

/// [`odometer_blocks_split`] in `parts` stretches (at least one, at most one a block).
fn odometer_blocks_in_parts<I, F>(
    d: &Derived,
    lp: &LowPass,
    series: OdoBlockSeries,
    increments_from: F,
    parts: usize,
) -> [Vec<f64>; 4]
where
    I: Iterator<Item = f64>,
    F: Fn(usize) -> I + Sync,
{
    use rayon::prelude::*;
    let n = d.t_s.len();
    let blocks = lp.blocks(n);
    let parts = parts.min(blocks).max(1);
    let stretches: Vec<[Vec<f64>; 4]> = (0..parts)
        .into_par_iter()
        .map(|p| {
            let (first, last) = (blocks * p / parts, blocks * (p + 1) / parts);
            let (from, to) = (first * lp.block, (last * lp.block).min(n));
            // The first stretch is sized for all of them: the others are appended to it.
            let room = if p == 0 { blocks } else { last - first };
            let mut b = OdometerBlocks::sized(d, lp, series, room);
            let mut increments = increments_from(from.saturating_sub(1));
            if from > 0 {
                b.resume_after(from, increments.next().unwrap_or(0.0));
            }
            for dd in increments.take(to - from) {
                b.push(dd);
            }
            b.means()
        })
        .collect();
    filtered_stretches(stretches, lp)
}

/// The block means of consecutive stretches of a run (each [`OdometerBlocks::means`]),
/// joined in order (the first's vectors, sized for all, take the others) and filtered by F.
pub(crate) fn filtered_stretches(
    stretches: impl IntoIterator<Item = [Vec<f64>; 4]>,
    lp: &LowPass,
) -> [Vec<f64>; 4] {
    let mut stretches = stretches.into_iter();
    let mut all = stretches.next().unwrap_or_default();
    for more in stretches {
        for (all, mut more) in all.iter_mut().zip(more) {
            all.append(&mut more);
        }
    }
    filtered(all, lp)
}

/// [`odometer_blocks_of`] as the odometer's increments come, one sample at a time (beside
/// other work on the same increments).
#[derive(Debug, Clone)]
pub struct OdometerBlocks<'d> {
    dt_s: &'d [f64],
    dtheta_rad: AngleSlice<'d>,
    /// The next sample.
    k: usize,
    /// u and "moving" of the sample before.
    prev: (f64, f64),
    /// u̇'s, unless left out.
    u_dot: Option<crate::filter::BlockMeans<1>>,
    /// ru's, with or without the odometer-bias sensitivities'.
    turns: TurnMeans,
}

/// Which of the odometer's block series a walk takes: ru's always, u̇'s and the
/// odometer-bias sensitivities' (r while moving, the rate of change of "moving") when
/// asked; a series left out comes out empty.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OdoBlockSeries {
    /// u̇'s.
    pub u_dot: bool,
    /// r while moving's and the rate of change of "moving"'s: what the odometer's speed
    /// bias moves the references by ([`epochs_of`] takes 0 for a series left out).
    pub bias: bool,
}

impl OdoBlockSeries {
    /// Every series: the derive's.
    pub const ALL: Self = Self {
        u_dot: true,
        bias: true,
    };

    /// Those a derive with its odometer moved makes anew (u̇'s is the configured
    /// derive's, moved in time), the bias sensitivities' only when `bias`.
    pub fn moved(bias: bool) -> Self {
        Self { u_dot: false, bias }
    }

    /// How many series of block means a walk holds.
    pub fn count(self) -> usize {
        1 + usize::from(self.u_dot) + 2 * usize::from(self.bias)
    }
}

/// The block means of ru, and of the odometer-bias sensitivities unless left out.
#[derive(Debug, Clone)]
enum TurnMeans {
    /// ru's, r while moving's and the rate of change of "moving"'s.
    WithBias(crate::filter::BlockMeans<3>),
    /// ru's alone.
    Ru(crate::filter::BlockMeans<1>),
}

impl<'d> OdometerBlocks<'d> {
    /// The blocks of `d`'s odometer part, from its IMU's intervals and yaw rates.
    pub fn new(d: &'d Derived, lp: &LowPass) -> Self {
        Self::sized(d, lp, OdoBlockSeries::ALL, lp.blocks(d.t_s.len()))
    }

    /// [`Self::new`] of `series` only, with room for `blocks` blocks.
    pub(crate) fn sized(
        d: &'d Derived,
        lp: &LowPass,
        series: OdoBlockSeries,
        blocks: usize,
    ) -> Self {
        use crate::filter::BlockMeans;
        Self {
            dt_s: &d.dt_s,
            dtheta_rad: d.dtheta_rad.view(),
            k: 0,
            prev: (0.0, 0.0),
            u_dot: series.u_dot.then(|| BlockMeans::new(lp.block, blocks)),
            turns: match series.bias {
                true => TurnMeans::WithBias(BlockMeans::new(lp.block, blocks)),
                false => TurnMeans::Ru(BlockMeans::new(lp.block, blocks)),
            },
        }
    }

    /// Starts at sample `k` (a block's first, above 0), the odometer's increment over
    /// the sample before being `dd_before`: the blocks from there on are those a walk
    /// from the start gives.
    pub(crate) fn resume_after(&mut self, k: usize, dd_before: f64) {
        self.k = k;
        if let Some(&dt) = self.dt_s.get(k - 1) {
            self.prev = (dd_before / dt, f64::from(u8::from(dd_before != 0.0)));
        }
    }

    /// The odometer's increment `dd` over the next sample, m (samples past the IMU's
    /// are left out).
    #[inline]
    pub fn push(&mut self, dd: f64) {
        let k = self.k;
        let (Some(&dt), Some(dtheta)) = (self.dt_s.get(k), self.dtheta_rad.get_checked(k)) else {
            return;
        };
        self.push_at(dd, dt, dd / dt, dtheta[2] / dt);
    }

    /// [`Self::push`] of each of `dd` in turn (those past the IMU's samples left out): the
    /// speeds and yaw rates of a few samples at a time first, side by side.
    pub(crate) fn push_slice(&mut self, dd: &[f64]) {
        const CHUNK: usize = 16;
        let k = self.k.min(self.dt_s.len()).min(self.dtheta_rad.len());
        let n = dd
            .len()
            .min(self.dt_s.len() - k)
            .min(self.dtheta_rad.len() - k);
        let (dd, dt_s) = (&dd[..n], &self.dt_s[k..k + n]);
        let (mut u_mps, mut r_rad_s) = ([0.0; CHUNK], [0.0; CHUNK]);
        crate::with_angle_slice!(self.dtheta_rad.slice(k..k + n), |dtheta| {
            for ((dd, dt_s), dtheta) in dd
                .chunks(CHUNK)
                .zip(dt_s.chunks(CHUNK))
                .zip(dtheta.chunks(CHUNK))
            {
                for (i, ((u, r), (dd, dt))) in u_mps
                    .iter_mut()
                    .zip(&mut r_rad_s)
                    .zip(dd.iter().zip(dt_s))
                    .enumerate()
                {
                    *u = dd / dt;
                    *r = dtheta[i].rad()[2] / dt;
                }
                for (i, (&dd, &dt)) in dd.iter().zip(dt_s).enumerate() {
                    self.push_at(dd, dt, u_mps[i], r_rad_s[i]);
                }
            }
        })
    }

    /// The next sample's increment `dd` over its interval `dt`, with its speed `u_mps`
    /// (dd / dt) and yaw rate `r_rad_s` (its yaw increment / dt).
    #[inline(always)]
    fn push_at(&mut self, dd: f64, dt: f64, u_mps: f64, r_rad_s: f64) {
        let k = self.k;
        self.k += 1;
        let moving = f64::from(u8::from(dd != 0.0));
        // "Moving" changes at a start or a stop: elsewhere its rate is (m − m)/dt = 0,
        // without the division.
        let moving_dot = if k == 0 || moving == self.prev.1 {
            0.0
        } else {
            (moving - self.prev.1) / dt
        };
        if let Some(u_dot) = self.u_dot.as_mut() {
            let u_dot_mps2 = if k == 0 {
                0.0
            } else {
                (u_mps - self.prev.0) / dt
            };
            u_dot.push([u_dot_mps2]);
        }
        self.prev = (u_mps, moving);
        match &mut self.turns {
            TurnMeans::WithBias(m) => m.push([r_rad_s * u_mps, r_rad_s * moving, moving_dot]),
            TurnMeans::Ru(m) => m.push([r_rad_s * u_mps]),
        }
    }

    /// The next sample it takes.
    pub(crate) fn next_sample(&self) -> usize {
        self.k
    }

    /// The block means, unfiltered (those left out empty).
    pub(crate) fn means(self) -> [Vec<f64>; 4] {
        let [u_dot] = self.u_dot.map_or_else(|| [Vec::new()], |m| m.finish());
        let [ru, r_moving, moving_dot] = match self.turns {
            TurnMeans::WithBias(m) => m.finish(),
            TurnMeans::Ru(m) => {
                let [ru] = m.finish();
                [ru, Vec::new(), Vec::new()]
            }
        };
        [u_dot, ru, r_moving, moving_dot]
    }

    /// F(u̇) (empty when left out), F(ru), F(r while moving) and F(d moving/dt) per
    /// block.
    pub fn finish(self, lp: &LowPass) -> [Vec<f64>; 4] {
        filtered(self.means(), lp)
    }
}

/// `means` (u̇'s, ru's, r while moving's, d moving/dt's; u̇'s possibly empty) filtered by
/// F, side by side.
fn filtered(mut means: [Vec<f64>; 4], lp: &LowPass) -> [Vec<f64>; 4] {
    let mut series: Vec<&mut [f64]> = means
        .iter_mut()
        .filter(|m| !m.is_empty())
        .map(|m| m.as_mut_slice())
        .collect();
    lp.filter_blocks_each(&mut series);
    means
}

/// Eqs 7–8 at the epochs (one every ΔTg), from the filtered block series of `d`.
pub fn epochs_of(d: &Derived, lp: &LowPass, params: &DeriveParams, g_mps2: f64) -> Epochs {
    let n = d.t_s.len();
    let block_s = lp.block as f64 * d.nominal_dt_s;
    let epoch_blocks = ((params.epoch_s / block_s).round() as usize).max(1);
    let blocks = d.ax_f.len();
    let mut e = Epochs::default();
    let mut j = epoch_blocks - 1;
    while j < blocks {
        let first = j * lp.block;
        let last = ((j + 1) * lp.block).min(n) - 1;
        let theta = ((d.ax_f[j] - d.u_dot_f[j]) / g_mps2)
            .clamp(-1.0, 1.0)
            .asin();
        let lateral = d.ay_f[j] - d.ru_f[j];
        let phi = -(lateral / (g_mps2 * theta.cos())).clamp(-1.0, 1.0).asin();
        // With boresight δ: a_x − u̇ + ru·δ and a_y − ru − u̇·δ to first order.
        let theta_per_yaw = d.ru_f[j] / g_mps2 / theta.cos();
        let phi_per_yaw = -(-d.u_dot_f[j] / (g_mps2 * theta.cos())
            + lateral * theta.sin() / (g_mps2 * theta.cos().powi(2)) * theta_per_yaw)
            / phi.cos();
        // With speed bias b: a_x − u̇ − b·moving′ and a_y − ru − b·r·moving.
        let at = |v: &[f64]| v.get(j).copied().unwrap_or(0.0);
        let theta_per_bias = -at(&d.moving_dot_f) / (g_mps2 * theta.cos());
        let phi_per_bias = -(-at(&d.r_moving_f) / (g_mps2 * theta.cos())
            + lateral * theta.sin() / (g_mps2 * theta.cos().powi(2)) * theta_per_bias)
            / phi.cos();
        e.block.push(j);
        e.t_s.push(0.5 * (d.t_s.get(first) + d.t_s.get(last)));
        e.theta_p_rad.push(theta);
        e.phi_p_rad.push(phi);
        e.theta_p_per_yaw.push(theta_per_yaw);
        e.phi_p_per_yaw.push(phi_per_yaw);
        e.theta_p_per_bias.push(theta_per_bias);
        e.phi_p_per_bias.push(phi_per_bias);
        e.valid.push(
            d.u_dot_f[j].abs() <= params.gate_long_mps2 && d.ru_f[j].abs() <= params.gate_lat_mps2,
        );
        j += epoch_blocks;
    }
    e
}

/// `x` (a series at one value per block, `block_s` apart) at every block moved by
/// `shift_s` later, by Catmull–Rom interpolation (clamped at the ends). F's output has
/// nothing above its 0.3 Hz, which the cubic follows to ~1e-4 at 10 blocks a second.
pub fn shifted_blocks(x: &[f64], block_s: f64, shift_s: f64) -> Vec<f64> {
    let n = x.len();
    if n == 0 {
        return Vec::new();
    }
    let at = |i: isize| x[i.clamp(0, n as isize - 1) as usize];
    (0..n)
        .map(|j| {
            let pos = j as f64 + shift_s / block_s;
            let i = pos.floor();
            let u = pos - i;
            let i = i as isize;
            let (p0, p1, p2, p3) = (at(i - 1), at(i), at(i + 1), at(i + 2));
            p1 + 0.5
                * u
                * (p2 - p0
                    + u * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + u * (3.0 * (p1 - p2) + p3 - p0)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stored derive's times in ns are each its time in seconds rounded back, bit for
    /// bit: at 100 Hz with jitter, across a gap past a 32-bit offset (a far time), 12 h
    /// in, and past the round trip's bound (the trip taken there), from a start anywhere
    /// in the log's time base; and so are times kept as computed.
    #[test]
    fn sample_times_in_ns_are_their_seconds_rounded_back() {
        let mut ns: Vec<i64> = Vec::new();
        let mut t = 0i64;
        for k in 0..3000i64 {
            t += match k {
                1000 => 6_000_000_000,
                2000 => 43_200_000_000_000,
                2500 => crate::time_base::ROUND_TRIP_NS_MAX,
                _ => 10_000_000 + (k * 7919) % 1000 - 500,
            };
            ns.push(t);
        }
        let stored = TimeBase::from_nanos(ns.iter().copied());
        let computed = TimeBase::from(stored.to_vec());
        for t0_ns in [0, 1_234_567_890_123_456_789, -987_654_321] {
            for t_s in [&stored, &computed] {
                let d = Derived {
                    t0_ns,
                    t_s: t_s.clone(),
                    ..Derived::default()
                };
                let each: Vec<i64> = (0..ns.len()).map(|k| d.ns_of(d.t_s.get(k))).collect();
                assert_eq!(d.t_ns(0..ns.len()).collect::<Vec<_>>(), each);
                assert_eq!(d.t_ns(2499..2502).collect::<Vec<_>>(), each[2499..2502]);
                // Within the bound, the stored times themselves.
                let within: Vec<i64> = ns[..2500].iter().map(|&n| t0_ns + n).collect();
                assert_eq!(each[..2500], within);
            }
        }
    }

    /// The rounding is libm's, bit for bit: halves (either sign), values next to them,
    /// the ends of i64, infinities, NaN, and a million times and products of the kind the
    /// writers round.
    #[test]
    fn rounding_to_i64_is_libms_bit_for_bit() {
        use rand::{Rng, SeedableRng};
        let half_below = 0.5f64.next_down();
        let mut xs = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            -2.5,
            half_below,
            -half_below,
            0.5f64.next_up(),
            1e15 + 0.5,
            -1e15 - 0.5,
            4503599627370495.5,
            -4503599627370495.5,
            2f64.powi(52),
            2f64.powi(53) + 2.0,
            9.2e18,
            -9.2e18,
            2f64.powi(63),
            -(2f64.powi(63)),
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MIN_POSITIVE,
            -1e-310,
        ];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for _ in 0..1_000_000 {
            let t_s: f64 = rng.random_range(-1e5..1e6);
            xs.push(t_s * 1e9);
            xs.push(rng.random_range(-100.0..100.0) + 0.5 * f64::from(rng.random_range(-3..3)));
            xs.push(f64::from_bits(rng.random()));
        }
        for x in xs {
            assert_eq!(
                round_to_i64(x),
                x.round() as i64,
                "{x:e} ({:#x})",
                x.to_bits()
            );
        }
    }

    #[test]
    fn an_epochs_prefix_keeps_every_series_in_step() {
        let n = |k: usize| (0..k).map(|i| i as f64).collect::<Vec<f64>>();
        let e = Epochs {
            block: vec![9, 19, 29],
            t_s: n(3),
            theta_p_rad: n(3),
            phi_p_rad: n(3),
            theta_p_per_yaw: n(3),
            phi_p_per_yaw: n(3),
            theta_p_per_bias: n(3),
            phi_p_per_bias: n(3),
            valid: vec![true, false, true],
        };
        let p = e.prefix(2);
        assert_eq!(
            (p.block.clone(), p.valid.clone()),
            (vec![9, 19], vec![true, false])
        );
        for s in [
            &p.t_s,
            &p.theta_p_rad,
            &p.phi_p_rad,
            &p.theta_p_per_yaw,
            &p.phi_p_per_yaw,
            &p.theta_p_per_bias,
            &p.phi_p_per_bias,
        ] {
            assert_eq!(s, &n(2));
        }
        assert_eq!(e.prefix(10), e);
    }

    /// The interpolation by its definition: the kept tags gathered first, then searched.
    /// A tag is kept when it is after the last kept, its distance finite, and it did not
    /// leap forward alone: a step more than twice the last kept step, over the next tag.
    fn distance_by_definition(t_ns: &[i64], d: &[f64], t0_ns: i64, offset_s: f64, ts: f64) -> f64 {
        let time = |ti: i64| (ti - t0_ns) as f64 * 1e-9 + offset_s;
        let mut kept: Vec<(f64, f64)> = Vec::new();
        for (i, (&ti, &di)) in t_ns.iter().zip(d).enumerate() {
            let t = time(ti);
            let leapt = match kept.as_slice() {
                [.., (before, _), (last, _)] => {
                    let next = t_ns.get(i + 1).map(|&tn| time(tn));
                    t - last > 2.0 * (last - before)
                        && next.is_some_and(|next| *last < next && next < t)
                }
                _ => false,
            };
            if kept.last().is_none_or(|&(last, _)| t > last) && di.is_finite() && !leapt {
                kept.push((t, di));
            }
        }
        match kept.as_slice() {
            [] => 0.0,
            [(_, d0)] => *d0,
            [(t0, d0), (t1, d1), ..] if ts <= *t0 => {
                let span = t1 - t0;
                d0 - (t0 - ts).min(span) * (d1 - d0) / span
            }
            _ => {
                let i = kept.partition_point(|&(t, _)| t <= ts) - 1;
                match kept.get(i + 1) {
                    None => kept[i].1,
                    Some(&(t1, d1)) => {
                        let (t0, d0) = kept[i];
                        d0 + (ts - t0) / (t1 - t0) * (d1 - d0)
                    }
                }
            }
        }
    }

    #[test]
    fn the_odometer_interpolation_is_its_definition_bit_for_bit() {
        // Tags going back, repeated, a NaN distance, one that leapt forward alone, a gap;
        // calls before the first tag, on tags, between them and after the last.
        let t_ns = [
            1_000_000_000,
            1_100_000_000,
            1_050_000_000,
            1_100_000_000,
            1_200_000_000,
            1_300_000_000,
            1_800_000_000,
            1_400_000_000,
            1_900_000_000,
            2_000_000_000,
        ];
        let d = [0.0, 0.4, 9.0, 7.0, f64::NAN, 1.3, 50.0, 1.4, 3.0, 3.1];
        let calls: Vec<f64> = (0..260).map(|i| -0.3 + i as f64 * 0.00731).collect();
        for offset_s in [0.0, 0.0137, -0.25] {
            for (tags, dists) in [
                (&t_ns[..], &d[..]),
                (&t_ns[..1], &d[..1]),
                (&t_ns[..0], &d[..0]),
                (&t_ns[4..], &d[4..]),
            ] {
                let mut odo = OdoInterp::new(tags.into(), dists, None, 1_000_000_000, offset_s);
                for &ts in &calls {
                    let want = distance_by_definition(tags, dists, 1_000_000_000, offset_s, ts);
                    assert_eq!(
                        odo.at(ts).to_bits(),
                        want.to_bits(),
                        "{} tags, offset {offset_s}, at {ts}",
                        tags.len()
                    );
                }
            }
        }
    }

    /// A drive that starts, turns, stops and starts again, the odometer at 10 Hz with its
    /// own time base, and a run length that leaves a partial last block: (IMU times,
    /// angle increments, velocity increments, odometer times, odometer distances).
    #[allow(clippy::type_complexity)]
    fn drive() -> (Vec<i64>, Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<i64>, Vec<f64>) {
        let n = 20_007;
        let t: Vec<i64> = (0..n).map(|k| 5_000_000 + k * 10_000_000).collect();
        let dtheta = (0..n)
            .map(|k| [0.0, 0.0, 3e-3 * (k as f64 * 1e-3).sin()])
            .collect();
        let dvel = (0..n)
            .map(|k| [1e-3 * (k as f64 * 2e-3).cos(), 2e-4, -0.098])
            .collect();
        let odo_t: Vec<i64> = (0..n / 10).map(|k| 3_000_000 + k * 100_000_000).collect();
        let odo_d = (0..n / 10)
            .map(|k| {
                let s = k as f64 * 0.1;
                if s < 60.0 {
                    8.0 * s
                } else if s < 90.0 {
                    480.0
                } else {
                    480.0 + 8.0 * (s - 90.0)
                }
            })
            .collect();
        (t, dtheta, dvel, odo_t, odo_d)
    }

    /// The derive of [`drive`]'s run with the IMU's time tags `tags`.
    #[allow(clippy::type_complexity)]
    fn derived_with_tags(
        tags: Vec<i64>,
        (dtheta, dvel, odo_t, odo_d): (&[[f64; 3]], &[[f64; 3]], &[i64], &[f64]),
    ) -> Derived {
        let columns = (
            tags,
            dtheta.to_vec(),
            dvel.to_vec(),
            odo_t.to_vec(),
            odo_d.to_vec(),
        );
        derive(&series(&columns), &DeriveParams::default(), 9.81)
    }

    /// The ingested series of [`drive`]'s columns.
    #[allow(clippy::type_complexity)]
    fn series(c: &(Vec<i64>, Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<i64>, Vec<f64>)) -> RawSeries<'_> {
        RawSeries {
            imu_t_ns: &c.0,
            dtheta_rad: &c.1,
            dvel_mps: &c.2,
            odo_t_ns: (&c.3).into(),
            odo_distance_m: &c.4,
        }
    }

    /// Eqs 9–11 per sample as whole series, the way the derive once stored them.
    fn per_sample(d: &Derived) -> [Vec<f64>; 6] {
        let n = d.t_s.len();
        let (mut u, mut u_dot, mut ru, mut r_moving, mut moving_dot) =
            (vec![], vec![], vec![], vec![], vec![]);
        let moving: Vec<f64> = d
            .odo_dist_m
            .iter()
            .map(|&x| f64::from(u8::from(x != 0.0)))
            .collect();
        for k in 0..n {
            let r = d.dtheta_rad.get(k)[2] / d.dt_s[k];
            u.push(d.odo_dist_m[k] / d.dt_s[k]);
            u_dot.push(if k == 0 {
                0.0
            } else {
                (u[k] - u[k - 1]) / d.dt_s[k]
            });
            ru.push(r * u[k]);
            r_moving.push(r * moving[k]);
            moving_dot.push(if k == 0 {
                0.0
            } else {
                (moving[k] - moving[k - 1]) / d.dt_s[k]
            });
        }
        let ax = (0..n).map(|k| d.dvel_mps[k][0] / d.dt_s[k]).collect();
        [u, u_dot, ru, r_moving, moving_dot, ax]
    }

    /// Bits, not values: -0.0 and 0.0 would pass `==`.
    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    /// The samples the derive lists as replaced are exactly those whose increments are
    /// not the ingested ones, bit for bit: a gap closed (filled), a saturated gyro and a
    /// NaN accelerometer count (held at the rates before), a tag going back (its time
    /// repaired, its increments kept), and zero increments across a gap (filled from the
    /// rate before them: half of it over the stretch).
    #[test]
    fn the_replaced_increments_are_exactly_those_not_ingested() {
        let (mut t, mut dtheta, mut dvel, odo_t, odo_d) = drive();
        // A gap of 5 samples before 5 000, zero increments closing one of 3 before 9 000.
        for (k, tk) in t.iter_mut().enumerate() {
            *tk += 50_000_000 * i64::from(k >= 5_000) + 30_000_000 * i64::from(k >= 9_000);
        }
        (dtheta[9_000], dvel[9_000]) = ([0.0; 3], [0.0; 3]);
        dtheta[12_000][1] = 1.0; // 100 rad/s over 10 ms: beyond 1000 °/s.
        dvel[15_000][0] = f64::NAN;
        t[17_000] = t[16_999] - 1;
        let columns = (t, dtheta, dvel, odo_t, odo_d);
        let raw = series(&columns);
        let d = derive(&raw, &DeriveParams::default(), 9.81);
        assert_eq!(d.replaced_increments, [5_000, 9_000, 12_000, 15_000]);
        assert_eq!(
            (d.filled_gaps, d.out_of_range_samples, d.repaired_times),
            (2, 2, 1)
        );
        let differs: Vec<usize> = (0..d.t_s.len())
            .filter(|&k| {
                let same = |a: &[f64; 3], b: &[f64; 3]| {
                    a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
                };
                !same(&d.dtheta_rad.get(k), &columns.1[k]) || !same(&d.dvel_mps[k], &columns.2[k])
            })
            .collect();
        // Every listed sample differs.
        assert_eq!(differs, [5_000, 9_000, 12_000, 15_000]);
        // The first replaced as beyond the range (not the gaps before it); with the
        // saturated gyro within range, the NaN accelerometer.
        assert_eq!(d.first_out_of_range, Some(12_000));
        let mut within = columns.clone();
        within.1[12_000][1] = 1e-4;
        let d_within = derive(&series(&within), &DeriveParams::default(), 9.81);
        assert_eq!(d_within.first_out_of_range, Some(15_000));
        let lost_s = d.dt_s[9_000] - d.nominal_dt_s;
        let half_before = |v: [f64; 3]| v.map(|x| 0.0 + lost_s * (x / d.dt_s[8_999] + 0.0) / 2.0);
        assert_eq!(
            (d.dtheta_rad.get(9_000), d.dvel_mps[9_000]),
            (half_before(columns.1[8_999]), half_before(columns.2[8_999]))
        );
        // A re-derive at another odometer timing keeps the IMU's list.
        assert_eq!(
            d.without_odometer_series().replaced_increments,
            d.replaced_increments
        );
    }

    /// A turn's rate and a braking's acceleration ramping while samples are lost: the
    /// stretch filled with the mean of the rates either side is the ramp's own integral
    /// (a rate linear in time is what the fill assumes), to 1e-12 rad and m/s (the
    /// times' rounding 70 s into the run moves the intervals by 1e-14 s). Holding
    /// the closing sample's rate, as before, overshot by the ramp's slope times the
    /// square of the stretch (each lost sample a period's worth of the rate's change).
    #[test]
    fn a_stretch_of_lost_samples_is_filled_by_the_rates_either_side() {
        let (t, _, _, odo_t, odo_d) = drive();
        // Increments over [t − h, t] of rates a + b·t (t in s from the first tag).
        let h = 0.01;
        let over = |k: usize, a: f64, b: f64| {
            let end = k as f64 * h;
            a * h + b * (end * end - (end - h) * (end - h)) / 2.0
        };
        let ramp = |k: usize| [0.0, 0.0, over(k, 0.02, 0.003)];
        let braking = |k: usize| [over(k, 0.5, -0.02), 0.0, -0.0981];
        let n = t.len();
        let (dtheta, dvel): (Vec<_>, Vec<_>) = (0..n).map(|k| (ramp(k), braking(k))).unzip();
        // Samples 7001–7003 lost: 7004 closes the gap.
        let keep = |k: &usize| !(7_001..7_004).contains(k);
        let pick =
            |v: &[[f64; 3]]| -> Vec<[f64; 3]> { (0..n).filter(keep).map(|k| v[k]).collect() };
        let tags = (0..n).filter(keep).map(|k| t[k]).collect();
        let d = derived_with_tags(tags, (&pick(&dtheta), &pick(&dvel), &odo_t, &odo_d));
        assert_eq!(d.filled_gaps, 1);
        let closing = 7_001;
        assert!(
            (d.dt_s[closing] - 0.04).abs() < 1e-12,
            "{}",
            d.dt_s[closing]
        );
        let sum = |v: &[[f64; 3]], i: usize| (7_001..=7_004).map(|k| v[k][i]).sum::<f64>();
        let got = (d.dtheta_rad.get(closing)[2], d.dvel_mps[closing][0]);
        assert!((got.0 - sum(&dtheta, 2)).abs() < 1e-12, "{got:?}");
        assert!((got.1 - sum(&dvel, 0)).abs() < 1e-12, "{got:?}");
        // Held, the stretch would be off by the slope times 6 h² (1 + 2 + 3 periods'
        // change): 1.8e-6 rad, and the braking 1.2e-5 m/s.
        let held = (4.0 * dtheta[7_004][2], 4.0 * dvel[7_004][0]);
        assert!((held.0 - sum(&dtheta, 2) - 0.003 * 6.0 * h * h).abs() < 1e-12);
        assert!((held.1 - sum(&dvel, 0) + 0.02 * 6.0 * h * h).abs() < 1e-12);
    }

    /// A binary log's angle increments (counts of 2⁻²⁶ rad) are held in f32, read back bit
    /// for bit; a gap's scaled increment, not an f32, turns them into f64 at the derive,
    /// each sample then the one an f64 derive makes. The median interval is the tags'.
    #[test]
    fn a_binary_logs_angle_increments_are_held_in_f32_unless_a_repair_needs_f64() {
        let (t, dtheta, dvel, odo_t, odo_d) = drive();
        let lsb = (-26f64).exp2();
        let counts: Vec<[f64; 3]> = (dtheta.iter())
            .map(|v| v.map(|x| (x / lsb).round() * lsb))
            .collect();
        let columns = (t, counts, dvel, odo_t, odo_d);
        let d = derive(&series(&columns), &DeriveParams::default(), 9.81);
        assert!(d.dtheta_rad.is_single());
        assert_eq!(d.dtheta_rad.view().to_vec(), columns.1);
        assert_eq!(d.nominal_dt_s, 0.01);
        // A gap of 2 samples before 5 000: its closing sample fills the 2 with the mean
        // of its rate and the one before's ([`filled`]).
        let mut gap = columns.clone();
        for tk in gap.0.iter_mut().skip(5_000) {
            *tk += 20_000_000;
        }
        let d = derive(&series(&gap), &DeriveParams::default(), 9.81);
        assert!(!d.dtheta_rad.is_single());
        assert_eq!(d.replaced_increments, [5_000]);
        let (dt, nominal) = (d.dt_s[5_000], d.nominal_dt_s);
        let before_rad_s = gap.1[4_999].map(|x| x / d.dt_s[4_999]);
        for k in [0, 4_999, 5_000, 5_001, 20_006] {
            let want = if k == 5_000 {
                std::array::from_fn(|i| {
                    let own = gap.1[k][i];
                    own + (dt - nominal) * (before_rad_s[i] + own / nominal) / 2.0
                })
            } else {
                gap.1[k]
            };
            assert_eq!(
                d.dtheta_rad.get(k).map(f64::to_bits),
                want.map(f64::to_bits)
            );
        }
    }

    /// Regression (probing binary logs with one record's tag damaged, its CRC valid): a
    /// tag that leapt forward alone (by 1 s, by 2^40 µs) made every later tag go back
    /// from it, so a 10-minute run "repaired" 29 999 of its 60 000 times and failed; a
    /// tag going back alone cost one. Each now costs one, in either direction, and the
    /// samples around it keep their times. Two tags out of order by less than a sample
    /// (the second went back a little) cost one too: the second is the one repaired.
    #[test]
    fn a_tag_that_leapt_forward_alone_is_repaired_alone() {
        let (t, dtheta, dvel, odo_t, odo_d) = drive();
        let nominal_ns = 10_000_000;
        for (k, leap_ns) in [
            (17_000, 1_000_000_000),
            (9_000, 1 << 50),
            (3_000, -nominal_ns),
        ] {
            let mut tags = t.clone();
            tags[k] += leap_ns;
            let d = derived_with_tags(tags, (&dtheta, &dvel, &odo_t, &odo_d));
            assert_eq!(d.repaired_times, 1, "a leap of {leap_ns} ns");
            let times: Vec<f64> = (0..t.len()).map(|j| d.t_s.get(j)).collect();
            for (j, &time) in times.iter().enumerate() {
                let given = (t[j] - t[0]) as f64 * 1e-9;
                if j == k {
                    assert!(times[j - 1] < time && time < times[j + 1], "{time}");
                } else {
                    assert!(
                        (time - given).abs() < 1e-12,
                        "sample {j}: {time} for {given}"
                    );
                }
            }
        }
        // The first of two out of order by less than a sample keeps its time.
        let mut tags = t.clone();
        tags[5_001] = tags[5_000] - 1;
        let columns = (tags, dtheta, dvel, odo_t, odo_d);
        let d = derive(&series(&columns), &DeriveParams::default(), 9.81);
        assert_eq!(d.repaired_times, 1);
        assert_eq!(d.t_s.get(5_000), (t[5_000] - t[0]) as f64 * 1e-9);
    }

    /// A stored time (the start plus seconds) beyond i64's nanoseconds is held at its
    /// bound, not wrapped.
    #[test]
    fn a_stored_time_beyond_an_i64_of_nanoseconds_is_held_at_its_bound() {
        assert_eq!(ns_since(i64::MAX - 5, 1.0), i64::MAX);
        assert_eq!(ns_since(i64::MIN + 5, -1.0), i64::MIN);
        assert_eq!(ns_since(-7_000_000_000, 9.5), 2_500_000_000);
    }

    /// Tags further apart than an i64 of nanoseconds holds (a broken log: the first
    /// sample apart, the others 8e9 s apart, so the run's start is placed 7e18 ns before
    /// 0): a time from the start beyond the i64 is held at its bound, not wrapped to
    /// before the start (an overflow the fuzzer's `binary_run` found with debug
    /// assertions, a panic there).
    #[test]
    fn tags_beyond_an_i64_of_nanoseconds_from_the_start_are_held_at_its_bound() {
        let tags: Vec<i64> = vec![5e18 as i64, 1e18 as i64, 9e18 as i64, 9.2e18 as i64];
        let columns = (
            tags,
            vec![[0.0; 3]; 4],
            vec![[0.0; 3]; 4],
            vec![0, 1],
            vec![0.0, 0.0],
        );
        let d = derive(&series(&columns), &DeriveParams::default(), 9.81);
        assert!((d.t0_ns as f64 + 7e18).abs() < 1e4, "{}", d.t0_ns);
        assert_eq!(d.t_s.get(2), i64::MAX as f64 * 1e-9);
        assert!(d.t_s.get(1) < d.t_s.get(2));
    }

    /// A first sample apart from the rest (its tag 1 s or 2^50 ns ahead of the second's,
    /// or 10 s before it across a gap no run bridges) and a last one 10 s after the rest
    /// are placed one interval beside their neighbour, one repaired time each, and the
    /// other samples keep their times on the clock they were logged on: the run's `t0_ns`
    /// is the true first sample's. A first sample across a short gap (0.5 s), or before a
    /// second that is apart itself, keeps its time.
    #[test]
    fn a_lone_first_or_last_sample_is_placed_beside_the_rest() {
        let (t, dtheta, dvel, odo_t, odo_d) = drive();
        let n = t.len();
        let derived = |tags| derived_with_tags(tags, (&dtheta, &dvel, &odo_t, &odo_d));
        for (k, by_ns) in [
            (0, 1_000_000_000),
            (0, 1 << 50),
            (0, -10_000_000_000),
            (n - 1, 10_000_000_000),
        ] {
            let mut tags = t.clone();
            tags[k] += by_ns;
            let d = derived(tags);
            assert_eq!(d.repaired_times, 1, "sample {k} moved by {by_ns} ns");
            assert_eq!(d.t0_ns, t[0], "sample {k} moved by {by_ns} ns");
            for j in 0..n {
                let (time, given) = (d.t_s.get(j), (t[j] - t[0]) as f64 * 1e-9);
                assert!(
                    (time - given).abs() < 1e-9,
                    "sample {j}: {time} for {given}"
                );
            }
            assert!(
                d.dt_s.iter().all(|&dt| dt < 0.011),
                "sample {k} moved by {by_ns} ns"
            );
        }
        let max_gap_s = DeriveParams::default().max_gap_s;
        assert!(!first_sample_apart(
            &[0, 500_000_000, 510_000_000],
            max_gap_s
        ));
        assert!(!first_sample_apart(
            &[0, 5_000_000_000, 10_000_000_000],
            max_gap_s
        ));
        assert!(first_sample_apart(
            &[0, 5_000_000_000, 5_010_000_000],
            max_gap_s
        ));
        assert!(!first_sample_apart(&[0, 10_000_000], max_gap_s));
    }

    /// The IMU's time tags given by value become the derive's times where they were
    /// stored (no second vector of the run's length), repaired as given by reference;
    /// every series is the borrowed derive's, bit for bit, with a gap and a tag going
    /// back among them.
    #[test]
    fn tags_given_by_value_become_the_times_in_place() {
        let (mut t, dtheta, dvel, odo_t, odo_d) = drive();
        for (k, tk) in t.iter_mut().enumerate() {
            *tk += 50_000_000 * i64::from(k >= 5_000);
        }
        t[17_000] = t[16_999] - 1;
        let columns = (t, dtheta, dvel, odo_t, odo_d);
        let params = DeriveParams::default();
        let borrowed = derive(&series(&columns), &params, 9.81);
        let tags = columns.0.clone();
        let tags_at = tags.as_ptr() as usize;
        let mut odometer_reads = 0;
        let owned = derive_owned(
            tags.into(),
            columns.1.clone(),
            columns.2.clone(),
            |at| {
                odometer_reads += 1;
                at.of(&series(&columns))
            },
            &LostSamples::ByInterval,
            &params,
            9.81,
        );
        assert_eq!(odometer_reads, 1);
        let TimeBase::Seconds(times) = &owned.t_s else {
            panic!("a derive's own times are seconds");
        };
        assert_eq!(times.as_ptr() as usize, tags_at, "the tags' vector reused");
        assert_eq!(owned.repaired_times, 1);
        let t0 = columns.0[0];
        for (k, &t) in times.iter().enumerate() {
            let given = (columns.0[k] - t0) as f64 * 1e-9;
            let want = if k == 17_000 {
                times[k - 1] + owned.nominal_dt_s
            } else {
                given
            };
            assert_eq!(t.to_bits(), want.to_bits(), "sample {k}");
        }
        assert_eq!(owned, borrowed);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&owned.dt_s), bits(&borrowed.dt_s));
        assert_eq!(bits(&owned.odo_dist_m), bits(&borrowed.odo_dist_m));
        assert_eq!(bits(&owned.u_dot_f), bits(&borrowed.u_dot_f));
        // A clock that counts up to its epoch: every tag negative (as an f64's bits, a
        // NaN's), the odometer's moved alike. The same times, counted from the first.
        let before_epoch_ns = 1_000_000_000_000;
        let earlier = |t: &[i64]| t.iter().map(|t| t - before_epoch_ns).collect::<Vec<_>>();
        let shifted = (
            earlier(&columns.0),
            columns.1.clone(),
            columns.2.clone(),
            earlier(&columns.3),
            columns.4.clone(),
        );
        let negative = derive_owned(
            earlier(&columns.0).into(),
            columns.1.clone(),
            columns.2.clone(),
            |at| at.of(&series(&shifted)),
            &LostSamples::ByInterval,
            &params,
            9.81,
        );
        assert_eq!(bits(&negative.t_s.to_vec()), bits(times));
        assert_eq!(negative.t0_ns, owned.t0_ns - before_epoch_ns);
        assert_eq!(bits(&negative.odo_dist_m), bits(&owned.odo_dist_m));
    }

    #[test]
    fn block_series_are_the_per_sample_terms_filtered_bit_for_bit() {
        let columns = drive();
        let raw = series(&columns);
        let params = DeriveParams::default();
        let d = derive(&raw, &params, 9.81);
        let lp = LowPass::new(&params.filter, d.nominal_dt_s);
        let filtered = |x: &[f64]| {
            let mut out = Vec::new();
            lp.apply(x, &mut out);
            out
        };
        for offset_s in [0.0, 0.123, -0.4] {
            let mut moved = d.without_odometer_series();
            odometer_blocks(&mut moved, &raw, offset_s, &lp);
            let [_, u_dot, ru, r_moving, moving_dot, ax] = per_sample(&moved);
            assert_eq!(
                bits(&moved.u_dot_f),
                bits(&filtered(&u_dot)),
                "u̇ at {offset_s}"
            );
            assert_eq!(bits(&moved.ru_f), bits(&filtered(&ru)), "ru at {offset_s}");
            assert_eq!(bits(&moved.r_moving_f), bits(&filtered(&r_moving)));
            assert_eq!(bits(&moved.moving_dot_f), bits(&filtered(&moving_dot)));
            assert_eq!(bits(&moved.ax_f), bits(&filtered(&ax)));
            assert!(moving_dot.iter().any(|&v| v != 0.0), "the drive stops");
        }
    }

    /// The run split into stretches of blocks (each resumed from the increment before
    /// it) gives one walk's block series, bit for bit: with u̇ and without, on the
    /// odometer stored and read moved from the ingested one, in more stretches than the
    /// pool has threads.
    #[test]
    fn block_series_in_stretches_are_one_walks_bit_for_bit() {
        let columns = drive();
        let raw = series(&columns);
        let params = DeriveParams::default();
        let d = derive(&raw, &params, 9.81);
        let lp = LowPass::new(&params.filter, d.nominal_dt_s);
        let whole = |d: &Derived, increments: &[f64]| {
            let mut out = d.without_odometer_series();
            odometer_blocks_of(&mut out, increments.iter().copied(), &lp);
            [out.u_dot_f, out.ru_f, out.r_moving_f, out.moving_dot_f]
        };
        let stored = whole(&d, &d.odo_dist_m);
        let from = |k: usize| d.odo_dist_m[k.min(d.odo_dist_m.len())..].iter().copied();
        let moved = MovedOdometer::new(&d, &raw, 0.237);
        let moved_increments: Vec<f64> = moved.increments().collect();
        let moved_whole = whole(&d, &moved_increments);
        for parts in [1, 2, 3, 7] {
            let split = odometer_blocks_in_parts(&d, &lp, OdoBlockSeries::ALL, from, parts);
            for (a, b) in split.iter().zip(&stored) {
                assert_eq!(bits(a), bits(b), "{parts} stretches");
            }
            let moved_from = |k| moved.increments_from(k);
            let split =
                odometer_blocks_in_parts(&d, &lp, OdoBlockSeries::moved(true), moved_from, parts);
            assert!(split[0].is_empty());
            for (a, b) in split.iter().zip(&moved_whole).skip(1) {
                assert_eq!(bits(a), bits(b), "{parts} stretches, moved");
            }
            // Without the bias sensitivities: ru's the same, the others empty.
            let ru_only =
                odometer_blocks_in_parts(&d, &lp, OdoBlockSeries::moved(false), moved_from, parts);
            assert_eq!(
                bits(&ru_only[1]),
                bits(&moved_whole[1]),
                "{parts} stretches"
            );
            assert!([0, 2, 3].iter().all(|&i| ru_only[i].is_empty()));
        }
        assert!(stored[3].iter().any(|&v| v != 0.0), "the drive stops");
    }

    /// An odometer at 100 Hz over 5 minutes, its tags compact: marks at every 4 096 tags
    /// (`MARK_TAGS`), around which the tags and distances are such that the walk's state
    /// there can, or cannot, be known from the tags around them alone.
    fn marked_odometer() -> (Vec<i64>, Vec<f64>) {
        use crate::time_base::MARK_TAGS;
        let n = 30_000;
        let mut tags: Vec<i64> = (0..n as i64)
            .map(|i| 3_000_000 + i * 10_000_000 + (i * 7919) % 400_000 - 200_000)
            .collect();
        let mut dist: Vec<f64> = (0..n).map(|i| i as f64 * 0.08).collect();
        let m = |j: usize| j * MARK_TAGS;
        // Mark 1: the reading before the marked one failed.
        dist[m(1) - 1] = f64::NAN;
        // Mark 2: the clock went back 5 s 92 tags before (those tags not kept until they
        // pass the last kept one's time again).
        for t in &mut tags[m(2) - 92..] {
            *t -= 5_000_000_000;
        }
        // Mark 3: the marked tag leapt 10 s forward alone (the next between).
        tags[m(3)] += 10_000_000_000;
        // Mark 4: clean. Mark 5: inside a patch's span (below). Mark 6: the marked
        // reading failed. Mark 7: clean, the tag after it leapt 10 s forward alone
        // (dropped by a read from the mark as by one from the first: by the step before).
        dist[m(6)] = f64::NAN;
        tags[m(7) + 1] += 10_000_000_000;
        (tags, dist)
    }

    /// Read from any sample on, an odometer held compact ([`TagTimes`]) starts from the
    /// last mark before it whose state is known from the tags there ([`OdoInterp::seek`]):
    /// the same increments as read from the first, bit for bit, past failed readings, a
    /// clock gone back, a tag leapt forward alone and a patch over a mark, at two lags.
    #[test]
    fn an_odometer_read_from_a_mark_gives_the_increments_read_from_the_first() {
        use crate::time_base::MARK_TAGS;
        let columns = drive();
        let d = derive(&series(&columns), &DeriveParams::default(), 9.81);
        let (odo_t, odo_d) = marked_odometer();
        let mut tags = TagTimes::with_room_for(odo_t.len());
        tags.extend(odo_t[..5000].iter().copied());
        tags.extend(odo_t[5000..].iter().copied());
        assert_eq!(tags.marks().len(), 7);
        let m = |j: usize| j * MARK_TAGS;
        // Mark 5 inside a span of replaced distances, its readings moved 2 m after.
        let patch = Arc::new(OdoPatch {
            spans: vec![PatchSpan {
                first: m(5) - 50,
                distance_m: (0..100)
                    .map(|i| (m(5) - 50 + i) as f64 * 0.08 + 0.01)
                    .collect(),
                shift_after_m: 2.0,
            }],
        });
        // The drive's IMU is 200 s long; its samples reach mark 7 with the odometer 90 s
        // early.
        for offset_s in [0.0, -90.0] {
            for patch in [None, Some(patch.clone())] {
                let raw = RawSeries {
                    imu_t_ns: &[],
                    dtheta_rad: &[],
                    dvel_mps: &[],
                    odo_t_ns: OdoTimes::Tags(&tags),
                    odo_distance_m: &odo_d,
                };
                let moved = MovedOdometer::new(&d, &raw, offset_s).patched(patch.clone());
                let all: Vec<u64> = moved.increments().map(f64::to_bits).collect();
                let n = all.len();
                let near_marks = (1..=7).flat_map(|j| {
                    // The IMU's sample at the mark's time, and either side.
                    let t = seconds_since(d.t0_ns, odo_t[m(j)]) + offset_s;
                    let k = d.t_s.partition_point(|s| s < t);
                    [k.saturating_sub(1), k, k + 1, k + 2]
                });
                for k in (0..n).step_by(997).chain(near_marks).chain([n - 1, n]) {
                    let k = k.min(n);
                    let from: Vec<u64> = moved.increments_from(k).map(f64::to_bits).collect();
                    assert!(from == all[k..], "from sample {k}, offset {offset_s} s");
                }
            }
        }
        // Where each read starts (offset 0: the IMU's 200 s reach mark 4, 164 s in).
        let seek = |ts: f64, patch: Option<Arc<OdoPatch>>| {
            let mut odo = OdoInterp::new((&tags).into(), &odo_d, patch, d.t0_ns, -90.0);
            odo.seek(&tags, ts)
        };
        let t = |i: usize| seconds_since(d.t0_ns, odo_t[i]) - 90.0;
        assert_eq!(seek(t(m(1)) + 1.0, None), None, "a failed reading before");
        assert_eq!(seek(t(m(2)) + 1.0, None), None, "a clock gone back");
        assert_eq!(seek(t(m(3) + 1) + 1.0, None), None, "a tag leapt alone");
        assert_eq!(seek(t(m(4)) + 1.0, None), Some(m(4)));
        assert_eq!(seek(t(m(5)) + 1.0, None), Some(m(5)));
        assert_eq!(seek(t(m(5)) + 1.0, Some(patch)), Some(m(5)), "patched");
        assert_eq!(seek(t(m(6)) + 1.0, None), Some(m(5)), "a failed reading");
        assert_eq!(seek(t(m(7)) + 1.0, None), Some(m(7)));
        // Before its mark's tag, a read starts from the mark before.
        assert_eq!(seek(t(m(7) - 1) - 0.001, None), Some(m(5)));
    }

    #[test]
    fn odometer_speeds_are_eqs_9_to_11_over_any_range() {
        let columns = drive();
        let raw = series(&columns);
        let d = derive(&raw, &DeriveParams::default(), 9.81);
        let [u, u_dot, ru, ..] = per_sample(&d);
        let n = d.t_s.len();
        for range in [0..n, 0..1, 1..2, 4321..9876, n - 1..n] {
            let got: Vec<OdometerSpeed> = d.odometer_speeds(range.clone()).collect();
            assert_eq!(got.len(), range.len());
            for (s, k) in got.iter().zip(range.clone()) {
                assert_eq!(s.u_mps.to_bits(), u[k].to_bits(), "u at {k}");
                assert_eq!(s.u_dot_mps2.to_bits(), u_dot[k].to_bits(), "u̇ at {k}");
                assert_eq!(s.ru_mps2.to_bits(), ru[k].to_bits(), "ru at {k}");
            }
        }
        assert!(u.iter().any(|&v| v > 7.0) && u_dot.iter().any(|&v| v != 0.0));
    }
}
