//! The odometer's clock against the IMU's: the shift of the odometer's time tags at
//! which its acceleration (u̇) is the accelerometers' along the vehicle's x.
//!
//! The joint fit estimates the odometer's lag within ±`[disupt] odo_lag_bound_s` (1 s)
//! of the offset configured (`[derive] odo_time_offset_s`): a filter's or a bus's delay.
//! An odometer file written on another clock (a logger's, set by hand) is seconds off,
//! beyond it, and the whole run is then wrong: the dead reckoning resolves each distance
//! with another moment's heading, the odometer stands while the vehicle drives, and the
//! control points' errors are tens of metres (Kingston's odometer 5 s late: hold-out
//! errors of 39 and 55 m, against 2.2 and 3.0 m). The drive shows the shift directly:
//! the accelerometers' x follows the odometer's u̇ (pulling away, braking) at one shift.
//!
//! The correlation is taken over F's filtered block series (`ax_f`, `u_dot_f`: 0.1-s
//! blocks low-passed at 0.3 Hz), first every second over the shifts the setting takes,
//! then every block within a second of the best, and the peak read off the parabola
//! through its neighbours. Slopes add g·sin(pitch) to the accelerometers' x: a slow
//! noise the correlation takes.
//!
//! Beyond the setting's reach ([`ClockFit::far`]): a logger's clock set minutes off
//! leaves nothing within ±60 s that the accelerometers follow. Over half the log either
//! way (6 hours at most), the series' 10-s means are correlated first (a hundredth of the
//! blocks, and as many shifts), then the blocks near the best. Kingston's
//! file 90, ±150 and −200 s off: found within 0.4 s, at correlations of 0.82–0.92
//! against 0.06–0.22 at best within the reach.
//!
//! F's start-up is left out at both ends ([`crate::filter::FilterParams::settling_s`],
//! 5.2 s at 0.3 Hz): F's forward pass starts from steady state on the first block, and a
//! log begun while driving has in its first block's u̇ the odometer's pulses at speed
//! (−6.5 m/s² filtered on one simulated log), a transient of seconds with nothing like it
//! in the accelerometers'. Left in, it read 0.46–0.67 s of lag on 5 of 14 simulated logs
//! begun while driving, with none simulated.
//!
//! Measured on simulated runs without a lag: −0.05 to +0.07 s on 50 with a static start,
//! −0.07 to +0.23 s on 14 begun while driving (0.23 s at a correlation of 0.59);
//! correlations 0.58–0.89. On Kingston −0.40 s (the joint fit: −0.58 ± 0.17 s), and its
//! odometer file shifted by 3, ±5, 10, 30 and −60 s found within 0.4 s of the shift.

use std::borrow::Cow;
use std::ops::RangeInclusive;

use crate::derive::Derived;
use crate::imu_axes::{MIN_FORWARD_CORRELATION, MIN_SCALE_EXCITATION};
use crate::odo_lag::parabola;

/// Largest lag an odometer's own timing has, s: its filter's and its bus's delay are
/// tenths of a second, and the joint fit estimates ±1 s of it about the offset
/// configured. Beyond, the odometer's time tags are another clock's.
pub const MAX_ODOMETER_LAG_S: f64 = 2.0;

/// Length of the means [`ClockFit::far`] first correlates, s: the accelerations of
/// pulling away and braking last seconds, their speeds' changes tens of seconds.
pub const FAR_MEAN_S: f64 = 10.0;

/// Farthest shift [`ClockFit::far`] searches either way, s: a time zone's hours (on a
/// log long enough to overlap), and a bound on its shifts whatever the log's length.
pub const FAR_REACH_S: f64 = 6.0 * 3600.0;

/// What the drive says of the odometer's clock.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClockFit {
    /// The shift of the odometer's time tags, beyond the offset configured, at which its
    /// u̇ follows the accelerometers' x best, s: positive when the odometer reports late
    /// (its pulling away comes this long after the accelerometers'), as the joint fit's
    /// lag. Its offset is then `odo_time_offset_s − lag_s`.
    pub lag_s: f64,
    /// The correlation there (−1 to 1).
    pub correlation: f64,
    /// The correlation at no shift: the odometer's clock as configured.
    pub correlation_as_given: f64,
    /// Sum of the odometer's squared u̇ over 1-s samples at the best shift, (m/s²)².
    pub excitation: f64,
}

impl ClockFit {
    /// The fit of `d`'s odometer against its accelerometers' x over the lags `lags_s`
    /// (within a quarter of the log either way), when the log has F's series, their
    /// first and last `edge_s` left out: F's start-up ([`FilterParams::settling_s`]).
    ///
    /// [`FilterParams::settling_s`]: crate::filter::FilterParams::settling_s
    pub fn of(d: &Derived, lags_s: RangeInclusive<f64>, edge_s: f64) -> Option<Self> {
        Self::of_readings(d, lags_s, edge_s, &[])
    }

    /// [`Self::of`] over the odometer's own readings: its blocks within `edge_s` (F's
    /// settling) of a span of `not_readings_s` (s from the log's first sample, on the
    /// IMU's clock, in time order and apart: the rows the ingest bridged or held over the
    /// odometer's failures) are left out. A bridge's distances are the inertial speed's, which the accelerometers
    /// follow at no shift whatever the odometer's clock: Kingston's speed file 18 s early
    /// had both its stands found moving and bridged (53 s of 877), and its clock read
    /// −18.3 s at a correlation of 0.43, not shown; its readings alone show it.
    pub fn of_readings(
        d: &Derived,
        lags_s: RangeInclusive<f64>,
        edge_s: f64,
        not_readings_s: &[[f64; 2]],
    ) -> Option<Self> {
        let (ax, u_dot, block_s) = series(d, edge_s, not_readings_s)?;
        Self::search(ax, &u_dot, block_s, lags_s, ax.len() / 4)
    }

    /// The fit beyond any setting: the best shift within half the log and
    /// [`FAR_REACH_S`] either way (an overlap of half the log or more), found first on
    /// [`FAR_MEAN_S`] means of the series, then as [`Self::of`] within two means of it.
    /// The means are a hundredth of the blocks, and their shifts as many up to the
    /// reach's 4 320: about 2·10⁷ products at 12 hours (25 ms, about twice the search
    /// within ±60 s), linear beyond.
    pub fn far(d: &Derived, edge_s: f64, not_readings_s: &[[f64; 2]]) -> Option<Self> {
        let (ax, u_dot, block_s) = series(d, edge_s, not_readings_s)?;
        let u_dot = &u_dot[..];
        let per = ((FAR_MEAN_S / block_s).round() as usize).max(1);
        let means = |x: &[f64]| -> Vec<f64> {
            (x.chunks_exact(per))
                .map(|c| c.iter().sum::<f64>() / per as f64)
                .collect()
        };
        let (a, u) = (means(ax), means(u_dot));
        let reach = (FAR_REACH_S / (per as f64 * block_s)).floor() as usize;
        let half = (a.len() / 2).min(reach) as isize;
        let coarse = (-half..=half)
            .map(|k| (k, correlation(&a, &u, k, 1).0))
            .filter(|(_, c)| c.is_finite())
            .max_by(|a, b| a.1.total_cmp(&b.1))?
            .0;
        let centre_s = (coarse * per as isize) as f64 * block_s;
        let reach_s = 2.0 * per as f64 * block_s;
        Self::search(
            ax,
            u_dot,
            block_s,
            centre_s - reach_s..=centre_s + reach_s,
            ax.len() / 2,
        )
    }

    /// The fit over the lags `lags_s` and within `reach` blocks either way.
    fn search(
        ax: &[f64],
        u_dot: &[f64],
        block_s: f64,
        lags_s: RangeInclusive<f64>,
        reach: usize,
    ) -> Option<Self> {
        // Shifts in blocks: those of `lags_s` within the reach.
        let reach = reach as f64;
        let first = (lags_s.start() / block_s).ceil().max(-reach) as isize;
        let last = (lags_s.end() / block_s).floor().min(reach) as isize;
        if first > last {
            return None;
        }
        let within = |k: isize| (first..=last).contains(&k);
        let stride = ((1.0 / block_s).round() as isize).max(1);
        // Every second, then every block within a second of the best.
        let coarse = (first..=last)
            .step_by(stride as usize)
            .map(|k| (k, correlation(ax, u_dot, k, stride)))
            .filter(|(_, c)| c.0.is_finite())
            .max_by(|a, b| a.1.0.total_cmp(&b.1.0))?
            .0;
        let fine = |k: isize| correlation(ax, u_dot, k, 1);
        let (best, at_best) = (coarse - stride..=coarse + stride)
            .filter(|&k| within(k))
            .map(|k| (k, fine(k)))
            .filter(|(_, c)| c.0.is_finite())
            .max_by(|a, b| a.1.0.total_cmp(&b.1.0))?;
        let at = best as f64;
        let vertex = (within(best - 1) && within(best + 1))
            .then(|| {
                let y = [fine(best - 1).0, at_best.0, fine(best + 1).0];
                parabola([at - 1.0, at, at + 1.0], y.map(|c| -c))
            })
            .flatten()
            .map(|(v, _)| v)
            .filter(|v| (v - at).abs() <= 1.0)
            .unwrap_or(at);
        Some(Self {
            lag_s: vertex * block_s,
            correlation: at_best.0,
            correlation_as_given: if within(0) { fine(0).0 } else { f64::NAN },
            excitation: at_best.1 / stride as f64,
        })
    }

    /// Whether the drive shows the odometer's clock: enough of its accelerations, as
    /// well followed by the accelerometers' as the axes' check asks
    /// ([`MIN_FORWARD_CORRELATION`], [`MIN_SCALE_EXCITATION`]).
    pub fn shown(&self) -> bool {
        self.correlation >= MIN_FORWARD_CORRELATION && self.excitation >= MIN_SCALE_EXCITATION
    }

    /// Whether the drive shows the odometer's time tags on another clock: a lag beyond
    /// [`MAX_ODOMETER_LAG_S`].
    pub fn off(&self) -> bool {
        self.shown() && self.lag_s.abs() > MAX_ODOMETER_LAG_S
    }
}

/// The accelerometers' x and the odometer's u̇ (NaN where no reading), F's blocks, and
/// the blocks' length, s.
type Series<'d> = (&'d [f64], Cow<'d, [f64]>, f64);

/// `d`'s F series of the accelerometers' x and the odometer's u̇, of one length, their
/// first and last `edge_s` left out, and the blocks' length, s; `None` when the log is
/// no longer than eight blocks and its two ends. The u̇ of blocks within `edge_s` of a
/// span of `not_readings_s` (s from the first sample) is NaN: no reading.
fn series<'d>(d: &'d Derived, edge_s: f64, not_readings_s: &[[f64; 2]]) -> Option<Series<'d>> {
    let (ax, u_dot) = (d.ax_f.as_slice(), d.u_dot_f.as_slice());
    let block_s = d.block as f64 * d.nominal_dt_s;
    if !(block_s > 0.0 && block_s.is_finite()) {
        return None;
    }
    let edge = (edge_s.max(0.0) / block_s).ceil().min(usize::MAX as f64) as usize;
    let n = ax.len().min(u_dot.len());
    if n < 8 + 2 * edge.min(n) {
        return None;
    }
    let u_dot = if not_readings_s.is_empty() {
        Cow::Borrowed(&u_dot[edge..n - edge])
    } else {
        let mut masked = u_dot[..n].to_vec();
        let margin_s = edge_s.max(0.0);
        let mut spans = not_readings_s.iter().peekable();
        let last = d.t_s.len().checked_sub(1);
        for (j, u) in masked.iter_mut().enumerate() {
            let from_s = match last {
                Some(last) => d.t_s.get((j * d.block).min(last)),
                None => j as f64 * block_s,
            };
            let to_s = from_s + block_s;
            // Spans ended before this block's reach are done with (blocks come in order).
            while spans.next_if(|s| s[1] + margin_s < from_s).is_some() {}
            if spans.peek().is_some_and(|s| s[0] - margin_s <= to_s) {
                *u = f64::NAN;
            }
        }
        masked.truncate(n - edge);
        masked.drain(..edge);
        Cow::Owned(masked)
    };
    Some((&ax[edge..n - edge], u_dot, block_s))
}

/// Pearson's correlation of `ax[i]` with `u_dot[i + k]` over every `stride`-th block both
/// have, and the sum of the odometer's squared u̇ over them.
fn correlation(ax: &[f64], u_dot: &[f64], k: isize, stride: isize) -> (f64, f64) {
    let n = ax.len() as isize;
    let (from, to) = ((-k).max(0), (n - k).min(n));
    if to - from < 3 * stride {
        return (f64::NAN, 0.0);
    }
    let (mut sa, mut su, mut saa, mut suu, mut sau, mut m) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for i in (from..to).step_by(stride as usize) {
        let (a, u) = (ax[i as usize], u_dot[(i + k) as usize]);
        // No reading there ([`series`]).
        if u.is_nan() {
            continue;
        }
        sa += a;
        su += u;
        saa += a * a;
        suu += u * u;
        sau += a * u;
        m += 1.0;
    }
    // Readings left out may leave too few to correlate.
    if m < 3.0 {
        return (f64::NAN, 0.0);
    }
    let cov = sau - sa * su / m;
    let (va, vu) = (saa - sa * sa / m, suu - su * su / m);
    (cov / (va * vu).sqrt(), suu)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// A drive's accelerations (pulling away and braking, 10–30 s apart) seen by the
    /// accelerometers and, `lag_s` later, by the odometer, in 0.1-s blocks.
    fn drive(lag_s: f64) -> Derived {
        let (block_s, n) = (0.1, 6000);
        let accel = |t: f64| {
            // Smooth pulses of ±1.5 m/s², one every 17 s, their signs and sizes varied.
            let (period, k) = (17.0, (t / 17.0).floor());
            let phase = t - k * period;
            let size = 1.5 * ((k * 2.39).sin() + 0.3 * (k * 0.71).cos());
            if phase < 6.0 {
                size * (std::f64::consts::PI * phase / 6.0).sin().powi(2)
            } else {
                0.0
            }
        };
        let t = |i: usize| i as f64 * block_s;
        Derived {
            nominal_dt_s: 0.01,
            block: 10,
            ax_f: Arc::new(
                (0..n)
                    .map(|i| accel(t(i)) + 0.05 * (i as f64 * 0.37).sin())
                    .collect(),
            ),
            u_dot_f: (0..n).map(|i| accel(t(i) - lag_s)).collect(),
            ..Derived::default()
        }
    }

    #[test]
    fn the_odometers_shift_is_found_to_a_tenth_of_a_second() {
        for lag_s in [0.0, 0.35, -1.0, 4.8, -7.25, 42.0] {
            let fit = ClockFit::of(&drive(lag_s), -60.0..=60.0, 5.0).unwrap();
            assert!((fit.lag_s - lag_s).abs() < 0.1, "{lag_s}: {fit:?}");
            assert!(fit.correlation > 0.95 && fit.shown(), "{fit:?}");
            assert_eq!(fit.off(), lag_s.abs() > MAX_ODOMETER_LAG_S, "{fit:?}");
        }
    }

    /// Stretches of u̇ that are the accelerometers' own (the ingest's inertial bridges
    /// over the odometer's failures, at no shift) blur an odometer 18 s early (here half
    /// of the drive: a correlation of 0.64, 0.43 at no shift; with four fifths bridged the
    /// shift read is 0); left out as no
    /// reading, with F's settling about them, the shift is found as without them.
    #[test]
    fn bridges_are_no_reading_of_the_clock() {
        let mut d = irregular_drive(-18.0);
        let bridges = [1000..2500, 3500..5000];
        let ax = Arc::clone(&d.ax_f);
        for b in bridges.clone() {
            d.u_dot_f[b.clone()].copy_from_slice(&ax[b]);
        }
        let all = ClockFit::of(&d, -60.0..=60.0, 5.0).unwrap();
        assert!(all.correlation < 0.7, "{all:?}");
        let spans = bridges.map(|b| [b.start as f64 * 0.1, (b.end - 1) as f64 * 0.1]);
        let readings = ClockFit::of_readings(&d, -60.0..=60.0, 5.0, &spans).unwrap();
        assert!((readings.lag_s + 18.0).abs() < 0.01, "{readings:?}");
        assert!(
            readings.correlation > 0.99 && readings.off(),
            "{readings:?}"
        );
        let far = ClockFit::far(&d, 5.0, &spans).unwrap();
        assert!((far.lag_s + 18.0).abs() < 0.1, "{far:?}");
        // Every block no reading: nothing to correlate.
        let whole = [[-100.0, 1000.0]];
        assert!(ClockFit::of_readings(&d, -60.0..=60.0, 5.0, &whole).is_none());
    }

    /// Only the lags the setting takes are searched: a shift beyond them is not found
    /// there (and not taken for one within).
    #[test]
    fn the_search_keeps_to_the_lags_given() {
        let fit = ClockFit::of(&drive(30.0), -10.0..=10.0, 5.0).unwrap();
        assert!(fit.lag_s.abs() <= 10.0, "{fit:?}");
        assert!(fit.correlation < 0.5, "{fit:?}");
        assert!(ClockFit::of(&drive(0.0), 5.0..=4.0, 5.0).is_none());
    }

    /// F's start-up at either end is left out: a transient there (a log begun while
    /// driving starts its u̇ from one block's odometer pulses) changes nothing.
    #[test]
    fn the_filters_start_up_is_left_out() {
        let clean = drive(0.35);
        let mut started = drive(0.35);
        let n = started.u_dot_f.len();
        for i in 0..50 {
            let decay = -6.5 * (-1.33 * i as f64 * 0.1).exp();
            started.u_dot_f[i] += decay;
            started.u_dot_f[n - 1 - i] -= decay;
        }
        let fit = |d: &Derived, edge_s| ClockFit::of(d, -60.0..=60.0, edge_s).unwrap();
        assert_eq!(fit(&started, 5.0), fit(&clean, 5.0));
        assert_ne!(fit(&started, 0.0), fit(&clean, 0.0));
        // A log no longer than its two ends: no fit (and no slice out of its bounds).
        let short = Derived {
            ax_f: Arc::new(clean.ax_f[..100].to_vec()),
            u_dot_f: clean.u_dot_f[..100].to_vec(),
            ..clean.clone()
        };
        assert!(ClockFit::of(&short, -1.0..=1.0, 5.0).is_none());
        assert!(ClockFit::of(&short, -1.0..=1.0, f64::INFINITY).is_none());
    }

    /// An irregular drive of 10 minutes (pulling away and braking at random times, of
    /// random sizes: no shift but the odometer's repeats it), its odometer `lag_s` late.
    fn irregular_drive(lag_s: f64) -> Derived {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let pulses: Vec<(f64, f64)> = (0..60)
            .map(|_| (rng.random_range(-300.0..900.0), rng.random_range(-2.0..2.0)))
            .collect();
        let accel = |t: f64| -> f64 {
            (pulses.iter())
                .filter(|&&(at, _)| (at..at + 6.0).contains(&t))
                .map(|&(at, size)| size * (std::f64::consts::PI * (t - at) / 6.0).sin().powi(2))
                .sum()
        };
        let (block_s, n) = (0.1, 6000);
        let t = |i: usize| i as f64 * block_s;
        Derived {
            nominal_dt_s: 0.01,
            block: 10,
            ax_f: Arc::new((0..n).map(|i| accel(t(i))).collect()),
            u_dot_f: (0..n).map(|i| accel(t(i) - lag_s)).collect(),
            ..Derived::default()
        }
    }

    /// A shift beyond the setting's reach is found by the far search, not by the near.
    #[test]
    fn a_shift_of_minutes_is_found_beyond_the_reach() {
        for lag_s in [150.0, -222.2, 0.4] {
            let d = irregular_drive(lag_s);
            let far = ClockFit::far(&d, 5.0, &[]).unwrap();
            assert!((far.lag_s - lag_s).abs() < 0.1, "{lag_s}: {far:?}");
            assert!(far.correlation > 0.95 && far.shown(), "{far:?}");
            let near = ClockFit::of(&d, -60.0..=60.0, 5.0).unwrap();
            assert_eq!(near.shown(), lag_s.abs() < 60.0, "{lag_s}: {near:?}");
        }
        // Beyond half the log (600 s), no overlap left to judge: not found.
        let far = ClockFit::far(&irregular_drive(400.0), 5.0, &[]).unwrap();
        assert!(far.lag_s.abs() <= 300.0, "{far:?}");
    }

    /// An odometer that stands still the whole log shows no clock.
    #[test]
    fn no_drive_no_clock() {
        let mut d = drive(0.0);
        d.u_dot_f = vec![0.0; d.u_dot_f.len()];
        assert!(ClockFit::of(&d, -60.0..=60.0, 5.0).is_none_or(|f| !f.shown()));
    }
}
