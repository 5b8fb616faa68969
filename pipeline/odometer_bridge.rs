//! The ingest's bridge of the odometer's failures in a binary log, streamed: those the
//! log flags (status bit 1), and counts that stand while the vehicle moves
//! ([`crate::odometer_stuck`]: by braking, from their last step on, or by the IMU, from
//! its watch's start). The samples of a failure, and those of the odometer working again
//! after it up to [`WINDOW_S`], are held back until it can be bridged
//! ([`unz_stages::odo_bridge::bridge`]), then given out in the order taken, each with the
//! route's distance. Held back at most: the longest bridged failure and a window, about
//! 13 000 samples at 100 Hz (and, while a standing count is judged, the samples since its
//! last step, 0.1 s to a few seconds, or the IMU's watch of it, 5 s).
//!
//! A failed sample's count is never read: the count of a failed odometer may hold,
//! jump, restart or be garbage. The readings after a failure continue the bridge (or,
//! not bridged, the distance held over it), whatever their count did meanwhile.

use std::collections::VecDeque;

use unz_formats::OdometerFailures;
use unz_formats::schema::DistanceSource;
use unz_stages::derive::increments_in_range;
use unz_stages::odo_bridge::{BridgeSample, Reading, WINDOW_S, bridge};

use crate::odometer_stuck::{Count, StuckCount};

/// The longest failure bridged, s. Measured on simulated failures while driving, the
/// bridge's error across a failure is 0.13 m rms (0.33 m at most) over 30 s, 0.69 m
/// (1.6 m) over 60 s and 4.4 m (17 m) over 120 s with the odometer on time (0.4 s late:
/// 0.92 and 1.1 m rms over 30 and 60 s); beyond, the tilt's drift that the readings
/// around it do not see grows with the cube of its length.
pub const MAX_BRIDGED_S: f64 = 120.0;
/// A working stretch shorter than this between flagged samples is taken into one
/// failure, s: too short to see the speed and the tilt after the first.
const MIN_WORKING_S: f64 = 1.0;
/// Samples held back at most, and kept for a failure's window before it, whatever their
/// time tags say (tags that do not advance would otherwise hold a log whole).
const MAX_HELD: usize = 100_000;

/// A sample's distance as given out, m (the route's), and where it comes from.
pub type Given = (f64, DistanceSource);

/// One IMU sample, as the bridge takes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometerSample {
    /// Time tag, s.
    pub t_s: f64,
    /// Angle increments, body FRD, rad.
    pub dtheta_rad: [f64; 3],
    /// Velocity increments, body FRD, m/s.
    pub dvel_mps: [f64; 3],
    /// The odometer's cumulative distance, m (not read when `failed`).
    pub distance_m: f64,
    /// The status flags the odometer failed (or, once taken, its count is stuck).
    pub failed: bool,
}

/// What is held back: a sample, or another item (a mark) between samples.
enum Held<P> {
    Sample(OdometerSample, P),
    Other(P),
}

/// Where the stream is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum State {
    /// The odometer works (samples may be held while a standing count is judged).
    Working,
    /// In a failure since `since_s`; working again since `working_s`, if it is.
    Failed {
        since_s: f64,
        working_s: Option<f64>,
    },
    /// In a failure too long to bridge: its samples hold the distance.
    Unbridged,
}

/// The odometer's distances through its failures, streamed: payloads `P` in, each with
/// its distance (`None` for items that are not samples) out, in order.
pub struct OdometerBridger<P> {
    g_mps2: f64,
    /// The odometer's lag as configured, s: the bridge's lag is searched about it.
    lag_prior_s: f64,
    state: State,
    /// The count judged against a land vehicle's braking.
    stuck: StuckCount,
    /// The interval increments are judged over against the IMU's range, s: twice the
    /// sample period (the ingest's tags may jitter; the derive repairs them).
    range_interval_s: f64,
    /// The last increments within the IMU's range (velocity, angle).
    last_increments: ([f64; 3], [f64; 3]),
    /// The last [`WINDOW_S`] of working samples given out, their readings the route's.
    before: VecDeque<BridgeSample>,
    held: VecDeque<Held<P>>,
    ready: VecDeque<(P, Option<Given>)>,
    /// Added to the odometer's distance to give the route's, m.
    offset_m: f64,
    /// The route's distance at the last sample given out, m.
    last_m: f64,
    failures: OdometerFailures,
}

impl<P> OdometerBridger<P> {
    /// A bridger at a site where gravity is `g_mps2`, for a count of `pulse_m` metres per
    /// pulse sampled every `period_s`, late by `lag_prior_s` as far as is known (the
    /// derive's configured `odo_time_offset_s`, negated).
    pub fn new(g_mps2: f64, pulse_m: f64, period_s: f64, lag_prior_s: f64) -> Self {
        Self {
            g_mps2,
            lag_prior_s,
            state: State::Working,
            stuck: StuckCount::new(pulse_m, period_s, g_mps2),
            range_interval_s: 2.0 * period_s.abs(),
            last_increments: ([0.0; 3], [0.0; 3]),
            before: VecDeque::new(),
            held: VecDeque::new(),
            ready: VecDeque::new(),
            offset_m: 0.0,
            last_m: 0.0,
            failures: OdometerFailures::default(),
        }
    }

    /// Takes the next IMU sample. While the odometer works and nothing is held, the
    /// sample comes straight back with its distance (the common case, without a queue);
    /// otherwise what is ready comes out of [`Self::ready`].
    pub fn sample(&mut self, mut s: OdometerSample, payload: P) -> Option<(P, Given)> {
        // Increments beyond the IMU's range (saturated or corrupt counts) are the last
        // ones within it here, as the derive replaces them: the bridge and the watch of a
        // standing count integrate them.
        if increments_in_range(s.dtheta_rad, s.dvel_mps, self.range_interval_s) {
            self.last_increments = (s.dvel_mps, s.dtheta_rad);
        } else {
            (s.dvel_mps, s.dtheta_rad) = self.last_increments;
        }
        let count = if s.failed {
            self.stuck.flagged();
            Count::Plausible
        } else {
            self.stuck
                .judge(s.t_s, s.distance_m, s.dvel_mps, s.dtheta_rad)
        };
        match count {
            Count::Plausible => {
                if self.state == State::Working && !self.held.is_empty() {
                    // The count judged moved again: what was held was working.
                    self.give_held_working();
                }
            }
            Count::Suspect => {
                if self.state == State::Working {
                    self.held.push_back(Held::Sample(s, payload));
                    self.bound_held_while_judged();
                    return None;
                }
            }
            Count::Standing { release_before_s } => {
                if self.state == State::Working {
                    self.held.push_back(Held::Sample(s, payload));
                    self.give_held_while(|h| h.t_s < release_before_s);
                    self.bound_held_while_judged();
                    return None;
                }
            }
            Count::Found { standing } => {
                s.failed = true;
                self.take_stuck(standing);
            }
            Count::Stuck => {
                s.failed = true;
                self.failures.stuck_samples += 1;
            }
        }
        if self.state == State::Working && !s.failed {
            if self.ready.is_empty() {
                return Some((payload, (self.keep_working(&s), DistanceSource::Reading)));
            }
            self.give_working(s, payload);
            return None;
        }
        match self.state {
            State::Working => {
                self.state = State::Failed {
                    since_s: s.t_s,
                    working_s: None,
                };
                self.held.push_back(Held::Sample(s, payload));
            }
            State::Failed { since_s, working_s } => {
                if s.failed
                    && let Some(w) = working_s
                    && s.t_s - w >= MIN_WORKING_S
                {
                    // Working long enough to bridge the failure before: this sample
                    // begins another.
                    self.resolve();
                    self.state = State::Failed {
                        since_s: s.t_s,
                        working_s: None,
                    };
                    self.held.push_back(Held::Sample(s, payload));
                    return None;
                }
                self.held.push_back(Held::Sample(s, payload));
                let working_s = match (s.failed, working_s) {
                    (true, _) => None,
                    (false, None) => Some(s.t_s),
                    (false, Some(w)) => Some(w),
                };
                self.state = State::Failed { since_s, working_s };
                match working_s {
                    Some(w) if s.t_s - w >= WINDOW_S => self.resolve(),
                    None if s.t_s - since_s > MAX_BRIDGED_S || self.held.len() >= MAX_HELD => {
                        self.give_up()
                    }
                    _ if self.held.len() >= MAX_HELD => self.resolve(),
                    _ => {}
                }
            }
            State::Unbridged => self.give_unbridged(s, payload),
        }
        None
    }

    /// Takes an item that is not a sample (a mark): given out in its place among them.
    pub fn other(&mut self, payload: P) {
        if self.held.is_empty() {
            self.ready.push_back((payload, None));
        } else {
            self.held.push_back(Held::Other(payload));
        }
    }

    /// What is ready, in order.
    pub fn ready(&mut self) -> std::collections::vec_deque::Drain<'_, (P, Option<Given>)> {
        self.ready.drain(..)
    }

    /// Ends the stream: a failure still held is bridged from what there is, and a
    /// standing count not judged stuck was working.
    pub fn finish(&mut self) {
        match self.state {
            State::Failed { .. } => self.resolve(),
            State::Working => self.give_held_working(),
            State::Unbridged => {}
        }
    }

    /// The failures so far; `None` without any.
    pub fn failures(&self) -> Option<&OdometerFailures> {
        let f = &self.failures;
        (f.bridged + f.not_bridged > 0).then_some(f)
    }

    /// A count found stuck: the `standing` samples held before this one fail with it,
    /// and a failure begins at the first of them (or, in one, goes on). Working, what is
    /// held before them (the IMU's watch slid on by a block at this sample) is given out.
    fn take_stuck(&mut self, standing: usize) {
        self.failures.stuck += 1;
        self.failures.stuck_samples += 1 + standing as u64;
        let mut first_t_s = None;
        let mut left = standing;
        for h in self.held.iter_mut().rev() {
            if left == 0 {
                break;
            }
            if let Held::Sample(x, _) = h {
                x.failed = true;
                first_t_s = Some(x.t_s);
                left -= 1;
            }
        }
        match self.state {
            State::Working => {
                if let Some(since_s) = first_t_s {
                    self.give_held_while(|x| !x.failed);
                    self.state = State::Failed {
                        since_s,
                        working_s: None,
                    };
                }
            }
            State::Failed { since_s, .. } => {
                self.state = State::Failed {
                    since_s,
                    working_s: None,
                };
            }
            State::Unbridged => {}
        }
    }

    /// Gives out the held samples from the front while `working` holds for them, as
    /// working samples, with the marks among and after them, in order.
    fn give_held_while(&mut self, working: impl Fn(&OdometerSample) -> bool) {
        while let Some(h) = self.held.front() {
            if matches!(h, Held::Sample(s, _) if !working(s)) {
                break;
            }
            match self.held.pop_front() {
                Some(Held::Other(p)) => self.ready.push_back((p, None)),
                Some(Held::Sample(s, p)) => self.give_working(s, p),
                None => break,
            }
        }
    }

    /// While a standing count is judged, what is held goes out as working once it is
    /// [`MAX_HELD`]: a judgement over time that does not pass (tags that do not advance)
    /// would otherwise hold the rest of the log.
    fn bound_held_while_judged(&mut self) {
        if self.held.len() >= MAX_HELD {
            self.give_held_working();
        }
    }

    /// Gives out what is held as working samples (and the marks among them).
    fn give_held_working(&mut self) {
        self.give_held_while(|_| true);
    }

    fn give_working(&mut self, s: OdometerSample, payload: P) {
        let d = self.keep_working(&s);
        self.ready
            .push_back((payload, Some((d, DistanceSource::Reading))));
    }

    /// The route's distance at a working sample, kept for a failure's window.
    fn keep_working(&mut self, s: &OdometerSample) -> f64 {
        let d = s.distance_m + self.offset_m;
        self.last_m = d;
        self.before.push_back(BridgeSample {
            t_s: s.t_s,
            dtheta_rad: s.dtheta_rad,
            dvel_mps: s.dvel_mps,
            reading: Reading::Before(d),
        });
        while self.before.len() > MAX_HELD
            || self
                .before
                .front()
                .is_some_and(|f| s.t_s - f.t_s > WINDOW_S)
        {
            self.before.pop_front();
        }
        d
    }

    /// Bridges the failure held, gives it out, and goes on working.
    fn resolve(&mut self) {
        self.state = State::Working;
        let samples = || {
            self.held.iter().filter_map(|h| match h {
                Held::Sample(s, _) => Some(s),
                Held::Other(_) => None,
            })
        };
        // The samples up to the last flagged one are the failure's; those after, its
        // readings after.
        let Some(n_failed) = samples()
            .enumerate()
            .filter(|(_, s)| s.failed)
            .last()
            .map(|(k, _)| k + 1)
        else {
            return;
        };
        let flagged = samples().filter(|s| s.failed).count() as u64;
        let first_t_s = samples().next().map_or(0.0, |s| s.t_s);
        let first_after = samples().nth(n_failed).copied();
        let end_t_s = first_after
            .or_else(|| samples().nth(n_failed - 1).copied())
            .map_or(first_t_s, |s| s.t_s);
        let mut window: Vec<BridgeSample> = self.before.iter().copied().collect();
        window.extend(samples().enumerate().map(|(k, s)| BridgeSample {
            t_s: s.t_s,
            dtheta_rad: s.dtheta_rad,
            dvel_mps: s.dvel_mps,
            reading: if k < n_failed {
                Reading::Failed
            } else {
                Reading::After(s.distance_m + self.offset_m)
            },
        }));
        // With no reading before (a log that begins failed), the bridge starts at the
        // route's distance so far.
        let anchor_m = if self.before.is_empty() {
            self.last_m
        } else {
            0.0
        };
        let f = &mut self.failures;
        let (failed_m, source): (Vec<f64>, _) = match bridge(&window, self.g_mps2, self.lag_prior_s)
        {
            Some(b) => {
                f.bridged += 1;
                f.bridged_samples += flagged;
                f.one_ended += u64::from(first_after.is_none());
                f.longest_bridged_s = f.longest_bridged_s.max(end_t_s - first_t_s);
                f.bridged_distance_m += b.across_m;
                f.worst_residual_m = f.worst_residual_m.max(b.rms_residual_m);
                self.offset_m += b.after_offset_m + anchor_m;
                (
                    b.failed_distance_m.iter().map(|d| d + anchor_m).collect(),
                    DistanceSource::Bridged,
                )
            }
            None => {
                // Without readings around it the route holds its distance over it.
                f.not_bridged += 1;
                f.not_bridged_samples += flagged;
                if let Some(s) = first_after {
                    self.offset_m = self.last_m - s.distance_m;
                }
                (vec![self.last_m; n_failed], DistanceSource::Held)
            }
        };
        self.before.clear();
        let mut failed_m = failed_m.into_iter();
        for h in std::mem::take(&mut self.held) {
            match h {
                Held::Other(p) => self.ready.push_back((p, None)),
                Held::Sample(s, p) => match failed_m.next() {
                    Some(d) => {
                        self.last_m = d;
                        self.ready.push_back((p, Some((d, source))));
                    }
                    None => self.give_working(s, p),
                },
            }
        }
    }

    /// A failure too long to bridge: what is held is given out, its flagged samples
    /// holding the distance and its working ones (stretches shorter than
    /// [`MIN_WORKING_S`]) going on from there; so is the rest of the failure.
    fn give_up(&mut self) {
        self.failures.not_bridged += 1;
        self.before.clear();
        self.state = State::Unbridged;
        for h in std::mem::take(&mut self.held) {
            match h {
                Held::Other(p) => self.ready.push_back((p, None)),
                Held::Sample(s, p) => self.give_unbridged(s, p),
            }
        }
    }

    /// A sample of a failure not bridged: flagged, it holds the distance; working, the
    /// readings go on from the distance held.
    fn give_unbridged(&mut self, s: OdometerSample, payload: P) {
        if s.failed {
            // The readings before it do not run on to the readings after it.
            self.before.clear();
            self.failures.not_bridged_samples += 1;
            self.state = State::Unbridged;
            self.ready
                .push_back((payload, Some((self.last_m, DistanceSource::Held))));
        } else {
            if self.state == State::Unbridged {
                self.offset_m = self.last_m - s.distance_m;
            }
            self.state = State::Working;
            self.give_working(s, payload);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The distances of what comes out, without their sources.
    fn metres<P>(
        ready: impl Iterator<Item = (P, Option<Given>)>,
    ) -> impl Iterator<Item = (P, Option<f64>)> {
        ready.map(|(p, g)| (p, g.map(|(m, _)| m)))
    }

    const G: f64 = 9.8;
    const V_MPS: f64 = 10.0;
    const DT_S: f64 = 0.01;
    const PULSE_M: f64 = 0.0125;

    /// A level drive at 10 m/s for `n` samples of 100 Hz, flagged failed where
    /// `failed(t)`, its count held over the failures (the readings after them short);
    /// a mark after every 1000th sample. Returns what comes out, in order: (payload,
    /// distance), payloads numbered as taken.
    fn drive(
        n: usize,
        failed: impl Fn(f64) -> bool,
    ) -> (Vec<(usize, Option<f64>)>, OdometerBridger<usize>) {
        drive_stuck(n, failed, |_| false)
    }

    /// [`drive`], with the count also held, unflagged, where `stuck(t)`.
    fn drive_stuck(
        n: usize,
        failed: impl Fn(f64) -> bool,
        stuck: impl Fn(f64) -> bool,
    ) -> (Vec<(usize, Option<f64>)>, OdometerBridger<usize>) {
        let (out, b) = drive_given(n, failed, stuck);
        (metres(out.into_iter()).collect(), b)
    }

    /// [`drive_stuck`] with each distance's source.
    fn drive_given(
        n: usize,
        failed: impl Fn(f64) -> bool,
        stuck: impl Fn(f64) -> bool,
    ) -> (Vec<(usize, Option<Given>)>, OdometerBridger<usize>) {
        let mut b = OdometerBridger::new(G, PULSE_M, DT_S, 0.0);
        let mut out = Vec::new();
        let mut id = 0;
        let mut missed_m = 0.0;
        for k in 1..=n {
            let t_s = k as f64 * DT_S;
            let f = failed(t_s);
            if f || stuck(t_s) {
                missed_m += V_MPS * DT_S;
            }
            let s = OdometerSample {
                t_s,
                dtheta_rad: [0.0; 3],
                dvel_mps: [0.0, 0.0, -G * DT_S],
                // A count of whole pulses.
                distance_m: if f {
                    f64::NAN
                } else {
                    ((V_MPS * t_s - missed_m) / PULSE_M).round() * PULSE_M
                },
                failed: f,
            };
            if let Some((p, given)) = b.sample(s, id) {
                out.extend(b.ready());
                out.push((p, Some(given)));
            }
            id += 1;
            if k % 1000 == 0 {
                b.other(id);
                id += 1;
            }
            out.extend(b.ready());
        }
        b.finish();
        out.extend(b.ready());
        (out, b)
    }

    /// Every payload out once, in order; the samples' distances those of a drive at
    /// 10 m/s from `d0_m` at the first sample (marks none).
    fn check(out: &[(usize, Option<f64>)], d0_m: f64) {
        let mut k = 0;
        for (i, (id, d)) in out.iter().enumerate() {
            assert_eq!(*id, i);
            if (i + 1) % 1001 == 0 {
                assert_eq!(*d, None, "{i}");
                continue;
            }
            k += 1;
            let want = d0_m + V_MPS * DT_S * (k - 1) as f64;
            assert!(
                (d.unwrap() - want).abs() < 1e-6,
                "{i}: {d:?} against {want}"
            );
        }
    }

    /// Time tags that do not advance (a damaged log's, constant) after a drive, the count
    /// standing with them: the count is judged over time that never passes, and the
    /// samples were held until the log ended (here 199 499 of 200 500; at 12 hours an
    /// estimated 0.7 GB and more). They are held back at most [`MAX_HELD`], then given
    /// out as working, in order.
    #[test]
    fn tags_that_do_not_advance_are_held_back_no_more_than_the_bound() {
        let mut b = OdometerBridger::new(G, PULSE_M, DT_S, 0.0);
        let (mut out, mut most_held) = (Vec::new(), 0);
        let n = 2 * MAX_HELD + 500;
        for k in 0..n {
            // Driving at 10 m/s for 10 s, then the tags and the count stand.
            let t_s = (k.min(1000) as f64) * DT_S;
            let s = OdometerSample {
                t_s,
                dtheta_rad: [0.0; 3],
                dvel_mps: [0.0, 0.0, -G * DT_S],
                distance_m: ((V_MPS * t_s) / PULSE_M).round() * PULSE_M,
                failed: false,
            };
            if let Some((p, given)) = b.sample(s, k) {
                out.extend(b.ready());
                out.push((p, Some(given)));
            }
            out.extend(b.ready());
            most_held = most_held.max(b.held.len());
        }
        b.finish();
        out.extend(b.ready());
        assert!(most_held <= MAX_HELD, "{most_held}");
        assert_eq!(out.len(), n);
        assert!(out.iter().enumerate().all(|(i, (p, _))| *p == i));
        // Never judged (time never passes), so the readings as given.
        let reading = |k: usize| ((V_MPS * k.min(1000) as f64 * DT_S) / PULSE_M).round() * PULSE_M;
        assert!((out.iter()).all(|(k, g)| *g == Some((reading(*k), DistanceSource::Reading))));
    }

    #[test]
    fn a_failure_is_bridged_and_the_stream_keeps_its_order() {
        let (out, b) = drive(6000, |t| (20.0..40.0).contains(&t));
        assert_eq!(out.len(), 6006);
        check(&out, 0.1);
        let f = b.failures().unwrap();
        assert_eq!((f.bridged, f.bridged_samples, f.one_ended), (1, 2000, 0));
        assert!((f.longest_bridged_s - 20.0).abs() < 0.02, "{f:?}");
        // From the last reading before (19.99 s) to the first after (40.00 s).
        assert!((f.bridged_distance_m - 200.1).abs() < 1e-6, "{f:?}");
        assert!(f.worst_residual_m < 1e-6, "{f:?}");
        assert_eq!(f.not_bridged, 0);
    }

    /// Each distance says where it comes from: the readings, the bridge over a failure,
    /// the distance held over one too long to bridge.
    #[test]
    fn each_distance_names_its_source() {
        let (out, _) = drive_given(
            30_000,
            |t| (20.0..40.0).contains(&t) || (60.0..190.0).contains(&t),
            |_| false,
        );
        let source = |t_s: f64| {
            let k = (t_s / DT_S).round() as usize;
            out[k - 1 + (k - 1) / 1000].1.unwrap().1
        };
        for (t_s, want) in [
            (19.99, DistanceSource::Reading),
            (20.0, DistanceSource::Bridged),
            (39.99, DistanceSource::Bridged),
            (40.0, DistanceSource::Reading),
            (59.99, DistanceSource::Reading),
            (60.0, DistanceSource::Held),
            (189.99, DistanceSource::Held),
            (190.0, DistanceSource::Reading),
        ] {
            assert_eq!(source(t_s), want, "at {t_s} s");
        }
        let count = |want| {
            out.iter()
                .filter(|(_, g)| g.is_some_and(|g| g.1 == want))
                .count()
        };
        assert_eq!(count(DistanceSource::Bridged), 2000);
        assert_eq!(count(DistanceSource::Held), 13_000);
    }

    /// A count that stops at 10 m/s without a flag is a failure from its last step on,
    /// bridged like a flagged one; the samples judged while it stood keep their order.
    #[test]
    fn a_count_stuck_while_driving_is_bridged_unflagged() {
        let (out, b) = drive_stuck(6000, |_| false, |t| (20.0..40.0).contains(&t));
        assert_eq!(out.len(), 6006);
        check(&out, 0.1);
        let f = b.failures().unwrap();
        assert_eq!((f.bridged, f.bridged_samples, f.not_bridged), (1, 2000, 0));
        assert_eq!((f.stuck, f.stuck_samples), (1, 2000));
        assert!((f.longest_bridged_s - 20.0).abs() < 0.02, "{f:?}");
        // Stuck for the rest of the log: one-ended, and beyond the longest bridged.
        let (out, b) = drive_stuck(30_000, |_| false, |t| t >= 100.0);
        let f = b.failures().unwrap();
        assert_eq!((f.bridged, f.not_bridged, f.stuck), (0, 1, 1), "{f:?}");
        assert_eq!(f.stuck_samples, 20_001, "{f:?}");
        assert_eq!(out.len(), 30_030);
        // A count that stands at a stop is no failure; neither is a flag's own.
        let (_, b) = drive_stuck(6000, |t| (20.0..21.0).contains(&t), |_| false);
        assert_eq!(b.failures().unwrap().stuck, 0);
    }

    /// A count that stops at rest and stays stopped as the vehicle pulls away (at 1 m/s²
    /// from 30 s to 10 m/s) until 60 s: the IMU's watch finds it, the samples before the
    /// watch go out as working, and the bridge gives the drive's distance; every sample
    /// and mark comes out once, in order.
    #[test]
    fn a_count_stopped_at_rest_is_bridged_as_the_vehicle_drives_off() {
        let route_m = |t: f64| {
            let a = (t - 30.0).clamp(0.0, 10.0);
            0.5 * a * a + 10.0 * (t - 40.0).max(0.0)
        };
        let mut b = OdometerBridger::new(G, PULSE_M, DT_S, 0.0);
        let mut out = Vec::new();
        for k in 1..=9000 {
            let t_s = k as f64 * DT_S;
            // The increment over (t − 0.01 s, t].
            let accel = if (3001..=4000).contains(&k) { 1.0 } else { 0.0 };
            // Stuck from 20 s to 60 s; after, short by what was driven meanwhile.
            let read_m = if (20.0..60.0).contains(&t_s) {
                route_m(20.0)
            } else if t_s >= 60.0 {
                route_m(t_s) - route_m(60.0)
            } else {
                route_m(t_s)
            };
            let s = OdometerSample {
                t_s,
                dtheta_rad: [0.0; 3],
                dvel_mps: [accel * DT_S, 0.0, -G * DT_S],
                distance_m: (read_m / PULSE_M).round() * PULSE_M,
                failed: false,
            };
            if let Some((p, (d, _))) = b.sample(s, k) {
                out.extend(metres(b.ready()));
                out.push((p, Some(d)));
            }
            if k % 1000 == 0 {
                b.other(0);
            }
            out.extend(metres(b.ready()));
        }
        b.finish();
        out.extend(metres(b.ready()));
        let samples: Vec<(usize, f64)> = out
            .iter()
            .filter(|(p, _)| *p > 0)
            .map(|(p, d)| (*p, d.unwrap()))
            .collect();
        assert_eq!(samples.len(), 9000);
        assert_eq!(out.len(), 9009);
        // Exact data (the readings whole pulses of an exact route): the bridge is exact.
        for (i, (k, d)) in samples.iter().enumerate() {
            assert_eq!(*k, i + 1);
            let want = route_m(*k as f64 * DT_S);
            assert!((d - want).abs() < 1e-6, "{k}: {d} against {want}");
        }
        let f = b.failures().unwrap();
        assert_eq!((f.stuck, f.bridged, f.not_bridged), (1, 1, 0), "{f:?}");
        // From the watch's start (5 s before the vehicle is found moving, 1.4–1.7 s after
        // it pulls away) to 60 s.
        assert!((3300..=3600).contains(&f.stuck_samples), "{f:?}");
        assert_eq!(f.stuck_samples, f.bridged_samples);
    }

    #[test]
    fn a_short_working_stretch_is_taken_into_one_failure() {
        let (out, b) = drive(6000, |t| {
            (20.0..25.0).contains(&t) || (25.5..30.0).contains(&t)
        });
        check(&out, 0.1);
        let f = b.failures().unwrap();
        assert_eq!((f.bridged, f.bridged_samples), (1, 950), "{f:?}");
        // Two failures 2 s apart are two.
        let (out, b) = drive(6000, |t| {
            (20.0..25.0).contains(&t) || (27.0..30.0).contains(&t)
        });
        check(&out, 0.1);
        assert_eq!(b.failures().unwrap().bridged, 2);
    }

    #[test]
    fn failures_at_the_log_s_ends_are_bridged_from_one_side() {
        let (out, b) = drive(6000, |t| t >= 50.0);
        check(&out, 0.1);
        let f = b.failures().unwrap();
        assert_eq!((f.bridged, f.one_ended), (1, 1), "{f:?}");
        // A log that begins failed starts its route at 0.
        let (out, b) = drive(6000, |t| t < 5.0);
        check(&out, 0.0);
        assert_eq!(b.failures().unwrap().bridged, 1);
    }

    /// Beyond the longest bridged, the distance holds over the failure and the readings
    /// after it continue from there; a later failure is bridged again.
    #[test]
    fn a_failure_longer_than_the_longest_bridged_holds_the_distance() {
        let (out, b) = drive(30_000, |t| {
            (20.0..150.0).contains(&t) || (200.0..210.0).contains(&t)
        });
        assert_eq!(out.len(), 30_030);
        let distance = |t_s: f64| {
            let k = (t_s / DT_S).round() as usize;
            out[k - 1 + (k - 1) / 1000].1.unwrap()
        };
        assert!((distance(19.99) - 199.9).abs() < 1e-6);
        assert_eq!(distance(100.0), distance(19.99));
        assert_eq!(distance(149.99), distance(19.99));
        // The first reading after (150.00 s) continues from the distance held.
        assert!((distance(160.0) - distance(19.99) - 100.0).abs() < 1e-6);
        assert!((distance(250.0) - distance(160.0) - 900.0).abs() < 1e-6);
        let f = b.failures().unwrap();
        assert_eq!((f.not_bridged, f.not_bridged_samples), (1, 13_000), "{f:?}");
        assert_eq!((f.bridged, f.bridged_samples), (1, 1000), "{f:?}");

        // A flag flickering on every tenth sample for 180 s: its first 120 s are one
        // failure, too long to bridge, whose working samples keep their steps and
        // flagged ones hold; the last minute is another, bridged.
        let (out, b) = drive(30_000, |t| {
            (20.0..200.0).contains(&t) && ((t / DT_S).round() as usize).is_multiple_of(10)
        });
        let f = b.failures().unwrap();
        assert_eq!((f.bridged, f.not_bridged), (1, 1), "{f:?}");
        assert_eq!(f.bridged_samples + f.not_bridged_samples, 1800, "{f:?}");
        assert!(f.longest_bridged_s > 55.0, "{f:?}");
        let speed = f.bridged_distance_m / (f.longest_bridged_s + DT_S);
        assert!((speed - V_MPS).abs() < 1e-6, "{f:?}");
        let distance = |k: usize| out[k - 1 + (k - 1) / 1000].1.unwrap();
        for k in (3000..13_000).step_by(10) {
            // Sample k flagged: it holds, and k + 1 goes on from it; k + 2… step.
            assert_eq!(distance(k), distance(k - 1), "{k}");
            assert_eq!(distance(k + 1), distance(k), "{k}");
            for j in k + 2..k + 10 {
                assert!((distance(j) - distance(j - 1) - 0.1).abs() < 1e-9, "{j}");
            }
        }
    }
}
