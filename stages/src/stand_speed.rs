//! The odometer's speed over the static start the crew gave: a vehicle that stood reads
//! 0 there, or a sensor's few cm/s ([`crate::initial::StandTravel`]).
//!
//! One that reads a steady speed through the stand, the same metres per second barely
//! changing, counts from another zero: a CAN or OBD-II speed decoded with a wrong
//! offset, which adds it to every reading of the drive too. The dead reckoning then
//! drives the offset through every stop, and the static start is lost (the odometer shows
//! the vehicle moving from the log's first second). Kingston's speeds read 1 m/s high ran
//! "ok" 2.6 km off at its last control point before DISUPT, its joint fit refused; 3 m/s
//! high were read by the turns as "about 1.3 m/s" ([`crate::imu_axes::SpeedOffset`]);
//! 3 m/s low failed as a sign to check ("runs backward over 55 % of its travel").
//!
//! An offset is the floor of every reading: the vehicle's speed is never below zero but
//! in a reversing manoeuvre's seconds. A logger that held its last speed through the
//! stand reads 0 at the drive's stops, below it, and is not taken for one: its odometer
//! reads 0 at rest, so the stand's steady speed is a reading held, or the vehicle driving
//! where the crew gave a stand. Either way the static start is lost (the odometer shows
//! the vehicle moving from the log's first second): Kingston's stand read 0.56 m/s ran
//! "ok" 2.3 km off at its last control point before DISUPT, its joint fit refused.
//!
//! The stand's first half is read: a crew's static start is approximate at its end (the
//! vehicle pulling away a little before it), never at the log's start. A speed that
//! barely changes over the whole log as well is no speed at all, not an offset: a column
//! of a temperature or a voltage, or one flat near the vehicle's speed in its turns,
//! which the axes' check cannot tell from a speed (Kingston's 8th column a constant
//! 5 m/s ran "ok" 3.6 km off at its last control point).

use crate::derive::Derived;
use crate::initial::{MIN_STATIC_S, MOVE_WINDOW_S, MOVED_M};

/// Spread (σ) of the speeds over the stand within which they are steady, m/s: an
/// OBD-II speed steps by 1 km/h (0.28 m/s), a stopped engine's or a parked car's reading
/// does not step at all; a creeping vehicle's changes by more.
pub const STEADY_SIGMA_MPS: f64 = 0.05;

/// Least spread (σ) of the speeds over the whole log that is a drive's, m/s: a drive's
/// speeds spread metres per second (Kingston's 4.8); a flat column's (a temperature, a
/// voltage) tenths.
pub const MIN_DRIVE_SIGMA_MPS: f64 = 1.0;

/// Least speed read over the stand that is an offset, m/s: a move's ([`MOVED_M`] over
/// [`MOVE_WINDOW_S`]); a sensor's noise at rest reads less.
pub const MIN_OFFSET_MPS: f64 = MOVED_M / MOVE_WINDOW_S;

/// Readings of the log below the stand's speed by more than this, m/s, are the vehicle's
/// speed below zero if the stand's is an offset: a reversing manoeuvre's, or none.
pub const BELOW_STAND_MPS: f64 = 0.1;

/// Largest share of the log's readings below the stand's speed ([`BELOW_STAND_MPS`]) for
/// it to be an offset: a parking manoeuvre's seconds. A logger that held its last speed
/// through the stand (0.56 m/s, say) and reads 0 at the drive's stops is no offset.
pub const MAX_BELOW_SHARE: f64 = 0.01;

/// Least share of the log's readings at 0 (within [`MIN_OFFSET_MPS`]) for its odometer to
/// read 0 at rest: the drive's stops, a few seconds in a hundred (Kingston's 6.5 %).
pub const MIN_STOPPED_SHARE: f64 = 0.01;

/// A steady speed read over the static start given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StandSpeed {
    /// The static start given, s.
    pub given_s: f64,
    /// The stand read: its first half, s.
    pub read_s: f64,
    /// Mean speed over it, m/s.
    pub mean_mps: f64,
    /// Spread (σ) of the speeds over it, m/s.
    pub sigma_mps: f64,
    /// Spread (σ) of the speeds over the whole log, m/s.
    pub log_sigma_mps: f64,
    /// Share of the log's readings below the stand's speed ([`BELOW_STAND_MPS`]).
    pub below_share: f64,
    /// Share of the log's readings at 0 ([`MIN_OFFSET_MPS`]).
    pub stopped_share: f64,
    /// When the speed first leaves the stand's ([`BELOW_STAND_MPS`] either way), s from
    /// the first sample; the log's last sample's time if it never does.
    pub left_s: f64,
}

impl StandSpeed {
    /// The speed of `d`'s odometer over the first half of the static start `given_s`,
    /// when it is steady ([`STEADY_SIGMA_MPS`]) at [`MIN_OFFSET_MPS`] or more either
    /// way, with the whole log's spread, its shares of readings below it and at 0, and
    /// when the speed leaves it (read only then); `None` for a static start under
    /// [`MIN_STATIC_S`].
    pub fn of(d: &Derived, given_s: f64) -> Option<Self> {
        if given_s < MIN_STATIC_S {
            return None;
        }
        let read_s = given_s / 2.0;
        // The readings as speeds, m/s, the first `n` of them.
        let speeds = |n: usize| {
            (d.odo_dist_m.iter().zip(d.dt_s.iter()))
                .take(n)
                .map(|(dd_m, dt_s)| dd_m / dt_s)
        };
        // The stand first: most logs read 0 there, and are read no further.
        let stood = d.t_s.iter().take_while(|&t_s| t_s <= read_s).count();
        let mut stand = Spread::default();
        speeds(stood)
            .filter(|v| v.is_finite())
            .for_each(|v| stand.push(v));
        let (mean_mps, sigma_mps) = stand.mean_sigma()?;
        if mean_mps.abs() < MIN_OFFSET_MPS || sigma_mps > STEADY_SIGMA_MPS {
            return None;
        }
        let (mut log, mut below, mut stopped) = (Spread::default(), 0_usize, 0_usize);
        let mut left_s = None;
        for (k, v) in speeds(d.t_s.len()).enumerate() {
            if !v.is_finite() {
                continue;
            }
            log.push(v);
            below += usize::from(v < mean_mps - BELOW_STAND_MPS);
            stopped += usize::from(v.abs() < MIN_OFFSET_MPS);
            if left_s.is_none() && (v - mean_mps).abs() > BELOW_STAND_MPS {
                left_s = Some(d.t_s.get(k));
            }
        }
        let (_, log_sigma_mps) = log.mean_sigma()?;
        Some(Self {
            given_s,
            read_s,
            mean_mps,
            sigma_mps,
            log_sigma_mps,
            below_share: below as f64 / log.n,
            stopped_share: stopped as f64 / log.n,
            left_s: left_s.or(d.t_s.last()).unwrap_or(0.0),
        })
    }

    /// Whether the log's speeds spread as a drive's ([`MIN_DRIVE_SIGMA_MPS`]): the
    /// stand's speed is then an offset of them; else the odometer is no speed.
    pub fn drove(&self) -> bool {
        self.log_sigma_mps >= MIN_DRIVE_SIGMA_MPS
    }

    /// Whether the stand's speed is an offset of every reading: the log's speeds spread
    /// as a drive's ([`Self::drove`]) and hardly any reads below it
    /// ([`MAX_BELOW_SHARE`]).
    pub fn is_offset(&self) -> bool {
        self.drove() && self.below_share <= MAX_BELOW_SHARE
    }

    /// Whether the stand's speed is a reading held (or the vehicle driving where a stand
    /// was given): the log's speeds spread as a drive's, are no offset of it
    /// ([`Self::is_offset`]), and read 0 at the drive's stops ([`MIN_STOPPED_SHARE`]):
    /// its odometer reads 0 at rest.
    pub fn is_held(&self) -> bool {
        self.drove() && !self.is_offset() && self.stopped_share >= MIN_STOPPED_SHARE
    }
}

/// Mean and spread of values as they come (Welford's).
#[derive(Debug, Default)]
struct Spread {
    n: f64,
    mean: f64,
    m2: f64,
}

impl Spread {
    fn push(&mut self, v: f64) {
        self.n += 1.0;
        let delta = v - self.mean;
        self.mean += delta / self.n;
        self.m2 += delta * (v - self.mean);
    }

    /// Mean and σ, when there are two values or more.
    fn mean_sigma(&self) -> Option<(f64, f64)> {
        (self.n >= 2.0).then(|| (self.mean, (self.m2 / self.n).sqrt()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time_base::TimeBase;

    /// A 100-Hz log of `n` samples whose odometer reads `speed(t_s)`, m/s.
    fn log(n: usize, speed: impl Fn(f64) -> f64) -> Derived {
        let t_s: Vec<f64> = (0..n).map(|k| 0.01 * k as f64).collect();
        Derived {
            odo_dist_m: t_s.iter().map(|&t| 0.01 * speed(t)).collect(),
            dt_s: std::sync::Arc::new(vec![0.01; n]),
            t_s: TimeBase::from(t_s),
            ..Derived::default()
        }
    }

    /// A drive after a 100-s stand: 0 to 12 m/s and back, twice a minute.
    fn drive(t_s: f64) -> f64 {
        if t_s < 100.0 {
            0.0
        } else {
            6.0 - 6.0 * (0.1 * t_s).cos()
        }
    }

    /// Speeds offset by ±3 m/s and by 0.2 m/s are read off the stand to the mm/s, over a
    /// drive; one at 0, a sensor's noise of 0–4 cm/s and a creep of 0.3 m/s changing by
    /// its tenths are not; nor is a stand under 5 s. A flat column (21.5, or 5 m/s near
    /// the vehicle's speed in its turns) reads steady over the stand with no drive.
    #[test]
    fn a_steady_speed_where_the_vehicle_stood_is_an_offset() {
        for offset in [3.0, -3.0, 0.2] {
            let s = StandSpeed::of(&log(60_000, |t| drive(t) + offset), 100.0).unwrap();
            assert!((s.mean_mps - offset).abs() < 1e-3, "{offset}: {s:?}");
            assert!(s.sigma_mps < 1e-9 && s.read_s == 50.0, "{offset}: {s:?}");
            assert!(
                s.is_offset() && (4.0..5.0).contains(&s.log_sigma_mps),
                "{s:?}"
            );
        }
        assert_eq!(StandSpeed::of(&log(60_000, drive), 100.0), None);
        let noise = |t: f64| drive(t) + 0.04 * ((t * 7919.0) % 1.0);
        assert_eq!(StandSpeed::of(&log(60_000, noise), 100.0), None);
        let creep = |t: f64| {
            if t < 100.0 {
                0.3 + 0.1 * t.sin()
            } else {
                drive(t)
            }
        };
        assert_eq!(StandSpeed::of(&log(60_000, creep), 100.0), None);
        assert_eq!(StandSpeed::of(&log(60_000, |t| drive(t) + 3.0), 4.0), None);
        // A logger that held 0.56 m/s through the stand and reads 0 at the drive's stops.
        // It is held: the drive reads 0 at its stops (4.9 % of the log's readings within
        // 0.1 m/s of 0: 5.8 % of the drive's), and leaves the held speed as it pulls away
        // at 100 s.
        let held = |t: f64| if t < 100.0 { 0.56 } else { drive(t) };
        let s = StandSpeed::of(&log(60_000, held), 100.0).unwrap();
        assert!(s.drove() && !s.is_offset() && s.below_share > 0.1, "{s:?}");
        assert!(
            s.is_held() && (0.045..0.055).contains(&s.stopped_share),
            "{s:?}"
        );
        assert!((s.left_s - 100.0).abs() < 0.015, "{s:?}");
        // An offset never reads 0 but at its stand; a drive that never stops held
        // nothing it can be told by.
        let offset = StandSpeed::of(&log(60_000, |t| drive(t) + 3.0), 100.0).unwrap();
        assert!(
            !offset.is_held() && offset.stopped_share == 0.0,
            "{offset:?}"
        );
        let cruise = |t: f64| {
            if t < 100.0 {
                20.0
            } else {
                15.0 + drive(t) / 6.0
            }
        };
        let s = StandSpeed::of(&log(60_000, cruise), 100.0).unwrap();
        assert!(s.drove() && !s.is_offset() && !s.is_held(), "{s:?}");
        for flat in [21.5, 5.0] {
            let s = StandSpeed::of(&log(60_000, |_| flat), 100.0).unwrap();
            assert!(
                !s.drove() && s.log_sigma_mps < 1e-9 && !s.is_held(),
                "{s:?}"
            );
        }
    }
}
