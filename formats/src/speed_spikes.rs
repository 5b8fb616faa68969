//! Spikes in an odometer's speed readings: a reading, or a burst of them, that jumps away
//! from the speed faster than a land vehicle can change it and comes back.
//!
//! A bus error or a logger that misreads a frame writes one wrong speed, or a run of them
//! (an OBD-II logger's "invalid" 255 km/h), between good ones. The trapezoid turns each
//! into distance: a 1-Hz file with one reading 30 m/s too fast puts the route 30 m ahead,
//! and nothing said so.
//!
//! - **Bursts.** A reading that the speed before it cannot reach ([`MAX_BRAKING_MPS2`],
//!   [`MAX_ACCEL_MPS2`], with a slack for the reading's resolution and its age) opens a
//!   burst. The burst ends at the first reading that jumps back to a speed the reading
//!   before the burst reaches over the time between, and that the readings after it agree
//!   with in a row ([`CONFIRM`] and [`CONFIRM_S`] at least: junk agrees with itself by
//!   chance only). The burst's readings are left out: the trapezoid spans them, or, 3 s
//!   and longer, the gap they leave is bridged by the IMU as a dropout is.
//! - **Short dips.** Up to [`MAX_DIP_READINGS`] readings that the vehicle could brake
//!   into but not pull away from, the speeds either side of them agreeing without them
//!   (zeros between two readings at 11 m/s a second apart), are spikes too; a short peak
//!   only when it was entered by a jump up from rest.
//! - **Kept.** A jump whose speed does not come back within [`MAX_BURST_S`] is kept and
//!   counted: a speed alone cannot say which side of it is wrong. Zeros over
//!   [`STAND_MIN_S`] or more are a stand, which the IMU judges: a burst of them is kept, a
//!   rise from zero opens no burst (a stand's end, or a drive-off), and a jump to zero
//!   that stays is not counted.
//! - **The first reading**, with no speed before it, is kept when the readings after it
//!   agree with it, or when it reaches the first reading that those after agree with.
//!
//! Streaming: readings are held only while a burst or a dip may be open (at most
//! [`MAX_BURST_S`] and [`MAX_HELD`] readings), then given out in order with their
//! verdict. Readings without a speed (a line rejected, an IMU sample without a speed) go
//! through in their place.

use std::collections::VecDeque;

/// Hardest braking of a land vehicle, m/s² (1.2 g: road tyres' grip on dry asphalt).
pub const MAX_BRAKING_MPS2: f64 = 12.0;
/// Hardest acceleration of a land vehicle, m/s² (0.6 g: 0-100 km/h in 4.7 s; a faster
/// car's launch is a jump that does not come back, kept). Kingston's 1-Hz OBD speeds
/// change by 2 m/s² at most either way.
pub const MAX_ACCEL_MPS2: f64 = 6.0;
/// Slack on a change of speed, m/s: the reading's resolution (1 km/h) and rounding.
const SLACK_MPS: f64 = 0.5;
/// A reading may be this much older than its time tag, s: a speed sampled at 10 Hz and
/// written at each IMU sample steps once per tenth of a second.
const HOLD_S: f64 = 0.1;
/// Readings in a row that agree for the speed to be back, at least: the burst's end and
/// the two after it, over [`CONFIRM_S`] at least.
pub const CONFIRM: usize = 3;
/// Least time the readings that agree span, s: at 10 Hz, ten of them (random speeds
/// agree ten in a row about once in a billion); at 1 Hz, [`CONFIRM`].
pub const CONFIRM_S: f64 = 1.0;
/// Readings in a row that agree at most (time tags that stand never span
/// [`CONFIRM_S`]).
const MAX_CONFIRM: usize = 2_000;
/// Longest burst left out, s, from the reading before it to the reading it ends at.
pub const MAX_BURST_S: f64 = 60.0;
/// Shortest burst of zeros kept, s, from the reading before it to the one after: a
/// logger that writes zero when it loses the speed leaves a stand, which the IMU judges
/// (`unz::odometer_gaps`, from this long); shorter, it is a spike.
pub const STAND_MIN_S: f64 = 3.0;
/// Readings a short dip or peak holds at most: a 1-Hz file's dropouts written as zero
/// for up to three readings (four span a stand, which the IMU judges).
pub const MAX_DIP_READINGS: usize = 3;
/// Readings held at most, whatever their time tags (a column at 1 kHz over a burst).
pub const MAX_HELD: usize = 100_000;
/// Readings without a speed in a row after which no more speeds are waited for: the
/// held ones are decided on what there is (a column that lost its speeds holds little).
const MAX_NO_SPEED: usize = 1_000;

/// What became of a reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// Kept: the speed before it reaches it, or its jump did not come back.
    Kept,
    /// Left out, in a burst: the last speed kept before it (time, s, and speed, m/s), or
    /// `None` at the start, where the readings after it did not agree with it.
    Spike(Option<(f64, f64)>),
    /// It had no speed; passed through in its place.
    NoSpeed,
}

/// Whether a vehicle at the reading `a` (time, s; speed, m/s) can be at the reading `b`
/// (after it or before it).
fn reaches(a: (f64, f64), b: (f64, f64)) -> bool {
    let (early, late) = if b.0 >= a.0 { (a, b) } else { (b, a) };
    let limit_mps2 = if late.1 >= early.1 {
        MAX_ACCEL_MPS2
    } else {
        MAX_BRAKING_MPS2
    };
    (late.1 - early.1).abs() <= SLACK_MPS + limit_mps2 * ((late.0 - early.0) + HOLD_S)
}

/// A reading held, with what goes with it.
struct Held<P> {
    speed: Option<(f64, f64)>,
    payload: P,
}

/// Where a burst ends, if it does.
enum Exit {
    /// At the held reading of this index.
    At(usize),
    /// Not within [`MAX_BURST_S`]: the jump stays.
    Never,
    /// More readings needed.
    Wait,
}

/// The readings' verdicts, streamed: [`SpeedSpikes::push`] each reading, take the
/// decided ones in order with [`SpeedSpikes::pop`], and call [`SpeedSpikes::finish`] at
/// the end.
pub struct SpeedSpikes<P> {
    /// The last reading kept: time, s, and speed, m/s.
    anchor: Option<(f64, f64)>,
    held: VecDeque<Held<P>>,
    decided: VecDeque<(P, Verdict)>,
    /// Where the open burst's search for its end goes on (an index into `held`).
    search_from: usize,
    /// No reading is to come.
    finished: bool,
    /// Readings without a speed pushed since the last with one.
    no_speed: usize,
    /// Readings left out.
    pub spikes: u64,
    /// Jumps kept: the speed did not come back within [`MAX_BURST_S`].
    pub jumps_kept: u64,
}

impl<P> Default for SpeedSpikes<P> {
    fn default() -> Self {
        Self {
            anchor: None,
            held: VecDeque::new(),
            decided: VecDeque::new(),
            search_from: 1,
            finished: false,
            no_speed: 0,
            spikes: 0,
            jumps_kept: 0,
        }
    }
}

impl<P> SpeedSpikes<P> {
    /// Takes the next reading: its time, s, and speed, m/s (finite), or `None` without
    /// one, with what goes with it.
    pub fn push(&mut self, speed: Option<(f64, f64)>, payload: P) {
        self.no_speed = if speed.is_some() {
            0
        } else {
            self.no_speed.saturating_add(1)
        };
        self.held.push_back(Held { speed, payload });
        self.decide();
    }

    /// No reading is to come: the held ones are decided on what there is.
    pub fn finish(&mut self) {
        self.finished = true;
        self.decide();
    }

    /// [`SpeedSpikes::finish`] was called: every reading is decided.
    pub fn is_finished(&self) -> bool {
        self.finished
    }

    /// The next reading decided, in order.
    pub fn pop(&mut self) -> Option<(P, Verdict)> {
        self.decided.pop_front()
    }

    fn give(&mut self, verdict: Verdict) {
        if let Some(h) = self.held.pop_front() {
            if verdict == Verdict::Kept {
                self.anchor = h.speed;
            }
            if matches!(verdict, Verdict::Spike(_)) {
                self.spikes += 1;
            }
            self.decided.push_back((h.payload, verdict));
        }
        self.search_from = 1;
    }

    /// The first `n` readings held given `verdict`, those without a speed
    /// [`Verdict::NoSpeed`].
    fn give_run(&mut self, n: usize, verdict: Verdict) {
        for _ in 0..n {
            let speed = self.held.front().is_some_and(|h| h.speed.is_some());
            self.give(if speed { verdict } else { Verdict::NoSpeed });
        }
    }

    fn decide(&mut self) {
        while let Some(front) = self.held.front() {
            let Some(c) = front.speed else {
                self.give(Verdict::NoSpeed);
                continue;
            };
            match self.anchor {
                None => match self.first_kept(c) {
                    Some(false) => self.give(Verdict::Spike(None)),
                    Some(true) => self.give(Verdict::Kept),
                    None => return,
                },
                // A rise from zero opens no burst: it is a stand's end, which the IMU
                // judges, or a drive-off (a lone peak from rest is still a spike).
                Some(a) if a.1 == 0.0 || reaches(a, c) => match self.dip_end(a, c) {
                    Some(Some(end)) => self.give_run(end, Verdict::Spike(Some(a))),
                    Some(None) => self.give(Verdict::Kept),
                    None => return,
                },
                Some(a) => match self.exit(a) {
                    Exit::At(end) if self.is_stand(a, end) => {
                        self.give_run(end, Verdict::Kept);
                        // The speed after the stand is judged from the speed before it.
                        self.anchor = Some(a);
                    }
                    Exit::At(end) => self.give_run(end, Verdict::Spike(Some(a))),
                    Exit::Never => {
                        // The speed did not come back: the readings held are kept as
                        // they are (each reading is searched over once). A jump to zero
                        // is a stand's start, which the IMU judges: not counted.
                        if c.1 != 0.0 {
                            self.jumps_kept += 1;
                        }
                        self.give_run(self.held.len(), Verdict::Kept);
                    }
                    Exit::Wait => return,
                },
            }
        }
    }

    /// Whether the first reading `c`, at the front, is kept: when the readings after it
    /// agree with it, or it reaches the first reading that those after agree with (a
    /// spike may follow it); `None` while more readings are needed.
    fn first_kept(&mut self, c: (f64, f64)) -> Option<bool> {
        if self.held.len() >= MAX_HELD {
            return Some(true);
        }
        if self.agree_from(0)? {
            return Some(true);
        }
        for k in self.search_from..self.held.len() {
            let Some(s) = self.held[k].speed else {
                continue;
            };
            if s.0 - c.0 > MAX_BURST_S {
                return Some(true);
            }
            match self.agree_from(k) {
                Some(true) => return Some(reaches(c, s)),
                Some(false) => {}
                None => {
                    self.search_from = k;
                    return None;
                }
            }
        }
        self.search_from = self.held.len().max(1);
        self.starved().then_some(true)
    }

    /// No more speeds are waited for: the end, the readings held at their most, or
    /// [`MAX_NO_SPEED`] without one.
    fn starved(&self) -> bool {
        self.finished || self.held.len() >= MAX_HELD || self.no_speed >= MAX_NO_SPEED
    }

    /// Where a short dip that begins at the front reading `c` ends (the held index of
    /// the reading after it), if it is one: at most [`MAX_DIP_READINGS`] readings within
    /// [`STAND_MIN_S`] of `c`, all below `a` and the reading after them, which jumps back
    /// up from them to a speed `a` reaches and that the readings after it agree with. A
    /// vehicle can brake into such a dip, but not pull away from it as fast. A peak the
    /// same way, but only one entered by a jump up from rest (no vehicle drives into a
    /// peak it cannot brake out of but from a speed it could not reach). `Some(None)`
    /// when it is none; `None` while more readings are needed.
    fn dip_end(&self, a: (f64, f64), c: (f64, f64)) -> Option<Option<usize>> {
        let below = c.1 < a.1;
        if c.1 == a.1 || (!below && reaches(a, c)) {
            return Some(None);
        }
        let (mut prev, mut extreme, mut readings) = (c, c.1, 1);
        for j in 1..self.held.len() {
            let Some(s) = self.held[j].speed else {
                continue;
            };
            if !reaches(prev, s) {
                // Back across: up out of a dip, down from a peak.
                let beyond = if below {
                    s.1 > prev.1 && extreme < a.1.min(s.1)
                } else {
                    s.1 < prev.1 && extreme > a.1.max(s.1)
                };
                if !(beyond && reaches(a, s)) {
                    return Some(None);
                }
                // The speed back is itself confirmed (not the next spike).
                return self.agree_from(j).map(|agree| agree.then_some(j));
            }
            let same_side = if below { s.1 < a.1 } else { s.1 > a.1 };
            readings += 1;
            if !same_side || readings > MAX_DIP_READINGS || s.0 - c.0 >= STAND_MIN_S {
                return Some(None);
            }
            extreme = if below {
                extreme.max(s.1)
            } else {
                extreme.min(s.1)
            };
            prev = s;
        }
        if self.starved() { Some(None) } else { None }
    }

    /// Whether the burst from `a` to the held index `end` is zeros over [`STAND_MIN_S`]
    /// or more: a stand, kept for the IMU to judge.
    fn is_stand(&self, a: (f64, f64), end: usize) -> bool {
        let end_s = self.held[end].speed.map_or(a.0, |s| s.0);
        end_s - a.0 >= STAND_MIN_S
            && (self.held.range(..end)).all(|h| h.speed.is_none_or(|s| s.1 == 0.0))
    }

    /// Whether the [`CONFIRM`] readings with a speed from the held index `i` agree in a
    /// row; `None` while fewer are held and more may come (at the end, those there are).
    fn agree_from(&self, i: usize) -> Option<bool> {
        let mut speeds = self.held.range(i..).filter_map(|h| h.speed);
        let first = speeds.next()?;
        let mut last = first;
        for n in 1..MAX_CONFIRM {
            if n >= CONFIRM && last.0 - first.0 >= CONFIRM_S {
                break;
            }
            match speeds.next() {
                Some(s) if reaches(last, s) => last = s,
                Some(_) => return Some(false),
                None => return self.starved().then_some(true),
            }
        }
        Some(true)
    }

    /// Where the burst opened by the front reading's jump from `a` ends: at a reading
    /// that jumps back from the one before it to a speed `a` reaches, and that the
    /// readings after it agree with.
    fn exit(&mut self, a: (f64, f64)) -> Exit {
        if self.held.len() >= MAX_HELD {
            return Exit::Never;
        }
        let mut before = (self.held.range(..self.search_from))
            .filter_map(|h| h.speed)
            .next_back();
        for j in self.search_from..self.held.len() {
            let Some(s) = self.held[j].speed else {
                continue;
            };
            if s.0 - a.0 > MAX_BURST_S {
                return Exit::Never;
            }
            let jumps_back = before.is_some_and(|b| !reaches(b, s));
            if jumps_back && reaches(a, s) {
                match self.agree_from(j) {
                    Some(true) => return Exit::At(j),
                    Some(false) => {}
                    None => {
                        self.search_from = j;
                        return Exit::Wait;
                    }
                }
            }
            before = Some(s);
        }
        self.search_from = self.held.len().max(1);
        if self.starved() {
            Exit::Never
        } else {
            Exit::Wait
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every reading's verdict, in order, with the counts.
    fn verdicts(readings: &[(f64, f64)]) -> (Vec<Verdict>, u64, u64) {
        let mut f = SpeedSpikes::default();
        let mut out = Vec::new();
        for (k, &r) in readings.iter().enumerate() {
            f.push(Some(r), k);
            while let Some((k, v)) = f.pop() {
                assert_eq!(k, out.len(), "in order");
                out.push(v);
            }
        }
        f.finish();
        while let Some((k, v)) = f.pop() {
            assert_eq!(k, out.len(), "in order");
            out.push(v);
        }
        assert_eq!(out.len(), readings.len(), "every reading decided");
        (out, f.spikes, f.jumps_kept)
    }

    /// `n` readings `period_s` apart of a drive at 11 m/s, zero over `zeros` (s).
    fn drive_with_zeros(n: usize, period_s: f64, zeros: std::ops::Range<f64>) -> Vec<(f64, f64)> {
        (0..n)
            .map(|k| {
                let t = k as f64 * period_s;
                (t, if zeros.contains(&t) { 0.0 } else { 11.0 })
            })
            .collect()
    }

    fn left_out(v: &[Verdict]) -> Vec<usize> {
        (v.iter().enumerate())
            .filter(|(_, v)| matches!(v, Verdict::Spike(_)))
            .map(|(k, _)| k)
            .collect()
    }

    /// A 1-Hz file at 20 m/s with a reading 30 m/s too fast, and one at 0 (2 g either
    /// way): both left out, nothing else. At 10 m/s, a zero is a spike too (a car can
    /// brake to it in a second, but not pull away from it to 10 m/s in the next); at
    /// 6 m/s it is not.
    #[test]
    fn a_lone_spike_is_left_out() {
        let mut r: Vec<(f64, f64)> = (0..20).map(|k| (k as f64, 20.0)).collect();
        r[5].1 = 50.0;
        r[12].1 = 0.0;
        let (v, spikes, jumps) = verdicts(&r);
        assert_eq!(left_out(&v), vec![5, 12]);
        assert_eq!((spikes, jumps), (2, 0));
        assert_eq!(v[5], Verdict::Spike(Some((4.0, 20.0))));
        let mut r: Vec<(f64, f64)> = (0..20).map(|k| (k as f64, 10.0)).collect();
        r[12].1 = 0.0;
        let (v, spikes, jumps) = verdicts(&r);
        assert_eq!((left_out(&v), spikes, jumps), (vec![12], 1, 0));
        let mut r: Vec<(f64, f64)> = (0..20).map(|k| (k as f64, 6.0)).collect();
        r[12].1 = 0.0;
        assert_eq!(verdicts(&r), (vec![Verdict::Kept; 20], 0, 0));
    }

    /// One to three zeros at 1 Hz in a drive at 11 m/s (a logger's dropouts) are left
    /// out; four are a stand, kept for the IMU; three readings at 6 m/s are a car that
    /// braked and pulled away, kept.
    #[test]
    fn short_dips_are_spikes() {
        for (zeros, spikes) in [(1, 1), (2, 2), (3, 3), (4, 0)] {
            let r = drive_with_zeros(20, 1.0, 10.0..10.0 + zeros as f64);
            let (v, n, jumps) = verdicts(&r);
            assert_eq!((n, jumps), (spikes, 0), "{zeros} zeros");
            assert_eq!(left_out(&v), (10..10 + spikes as usize).collect::<Vec<_>>());
        }
        let r: Vec<(f64, f64)> = (0..20)
            .map(|k| (k as f64, if (10..13).contains(&k) { 6.0 } else { 11.0 }))
            .collect();
        assert_eq!(verdicts(&r), (vec![Verdict::Kept; 20], 0, 0));
        // A car slowing from 11 to 9.5 m/s, then a reading 25 m/s too fast: the spike
        // alone is left out, not the slowing before it.
        let r: Vec<(f64, f64)> = (0..20)
            .map(|k| {
                let v = if k < 10 {
                    11.0
                } else {
                    11.0 - 0.5 * (k - 9).min(3) as f64
                };
                (k as f64, if k == 13 { v + 25.0 } else { v })
            })
            .collect();
        let (v, n, _) = verdicts(&r);
        assert_eq!((left_out(&v), n), (vec![13], 1));
    }

    /// A car pulling away at 10 Hz whose speed then reads zero for good (a stand's start,
    /// the IMU's to judge): nothing left out, no jump counted.
    #[test]
    fn a_stand_that_starts_while_driving_is_left_to_the_imu() {
        let r: Vec<(f64, f64)> = (0..1000)
            .map(|k| {
                let t = k as f64 * 0.1;
                (t, if t < 10.0 { 3.0 + 0.25 * t } else { 0.0 })
            })
            .collect();
        assert_eq!(verdicts(&r), (vec![Verdict::Kept; 1000], 0, 0));
    }

    /// A 10-Hz speed that reads 255 km/h for 5 s while the car brakes from 15 to 5 m/s,
    /// and a car that brakes at 1 g and pulls away at 0.5 g: the burst left out, the
    /// braking kept.
    #[test]
    fn a_burst_is_left_out_and_hard_braking_kept() {
        let r: Vec<(f64, f64)> = (0..300)
            .map(|k| {
                let t = k as f64 * 0.1;
                let v = if (10.0..15.0).contains(&t) {
                    70.8
                } else {
                    (15.0 - 0.4 * t).max(5.0)
                };
                (t, v)
            })
            .collect();
        let (v, spikes, _) = verdicts(&r);
        assert_eq!(left_out(&v), (100..150).collect::<Vec<_>>());
        assert_eq!(spikes, 50);

        let r: Vec<(f64, f64)> = (0..200)
            .map(|k| {
                let t = k as f64 * 0.1;
                (
                    t,
                    if t < 2.0 {
                        20.0 - 9.8 * t
                    } else {
                        0.4 + 4.9 * (t - 2.0)
                    },
                )
            })
            .collect();
        assert_eq!(verdicts(&r), (vec![Verdict::Kept; 200], 0, 0));
        // A sports car's launch at 0.9 g from rest, at 1 Hz: kept, its speed from 8.8 m/s
        // on counted as one jump that did not come back (the rise from zero opens none).
        let r: Vec<(f64, f64)> = (0..10)
            .map(|k| (k as f64, (8.8 * (k as f64 - 3.0)).max(0.0)))
            .collect();
        assert_eq!(verdicts(&r), (vec![Verdict::Kept; 10], 0, 1));
    }

    /// A speed that jumps and stays (a scale that changed, or junk longer than a burst)
    /// is kept and counted; so is one that jumps at the end of the readings.
    #[test]
    fn a_jump_that_does_not_come_back_is_kept_and_counted() {
        let r: Vec<(f64, f64)> = (0..800)
            .map(|k| (k as f64 * 0.1, if k < 100 { 10.0 } else { 30.0 }))
            .collect();
        assert_eq!(verdicts(&r), (vec![Verdict::Kept; 800], 0, 1));
        let r = [(0.0, 10.0), (1.0, 10.0), (2.0, 10.0), (3.0, 50.0)];
        assert_eq!(verdicts(&r), (vec![Verdict::Kept; 4], 0, 1));
    }

    /// Readings at the start that the ones after them do not agree with are left out; a
    /// file of one or two readings is kept as it is.
    #[test]
    fn the_first_readings_are_kept_when_the_next_agree() {
        let r = [(0.0, 60.0), (1.0, 5.0), (2.0, 5.5), (3.0, 6.0), (4.0, 6.0)];
        let (v, spikes, _) = verdicts(&r);
        assert_eq!(v[0], Verdict::Spike(None));
        assert_eq!(left_out(&v), vec![0]);
        assert_eq!(spikes, 1);
        assert_eq!(verdicts(&[(0.0, 3.0)]).0, vec![Verdict::Kept]);
        assert_eq!(
            verdicts(&[(0.0, 3.0), (1.0, 4.0)]).0,
            vec![Verdict::Kept; 2]
        );
    }

    /// Random speeds of 0-50 m/s for 20 s at 10 Hz in a drive at 10 m/s: all left out,
    /// the drive around them kept.
    #[test]
    fn junk_speeds_at_ten_hertz_are_left_out() {
        let mut state = 12345u64;
        let mut random = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let r: Vec<(f64, f64)> = (0..600)
            .map(|k| {
                let t = k as f64 * 0.1;
                (
                    t,
                    if (20.0..40.0).contains(&t) {
                        50.0 * random()
                    } else {
                        10.0
                    },
                )
            })
            .collect();
        let (v, spikes, _) = verdicts(&r);
        let out = left_out(&v);
        assert!(out.iter().all(|&k| (200..400).contains(&k)), "{out:?}");
        assert_eq!(spikes, 200);
    }

    /// Zeros at 10 Hz in a drive at 11 m/s: 2 s of them are a spike, left out; 5 s are a
    /// stand, kept for the IMU to judge.
    #[test]
    fn short_zeros_are_a_spike_and_long_ones_a_stand() {
        for (zeros_s, spikes) in [(2.0, 20), (5.0, 0)] {
            let r = drive_with_zeros(300, 0.1, 10.0..10.0 + zeros_s);
            let (v, n, jumps) = verdicts(&r);
            assert_eq!((n, jumps), (spikes, 0), "{zeros_s} s");
            assert_eq!(left_out(&v).len(), spikes as usize);
        }
    }

    /// Readings without a speed go through in their place, in a burst too.
    #[test]
    fn readings_without_a_speed_keep_their_place() {
        let mut f = SpeedSpikes::default();
        let speeds = [
            Some(10.0),
            None,
            Some(40.0),
            None,
            Some(10.0),
            Some(10.0),
            Some(10.0),
        ];
        for (k, s) in speeds.iter().enumerate() {
            f.push(s.map(|s| (k as f64, s)), k);
        }
        f.finish();
        let got: Vec<(usize, Verdict)> = std::iter::from_fn(|| f.pop()).collect();
        let want = [
            Verdict::Kept,
            Verdict::NoSpeed,
            Verdict::Spike(Some((0.0, 10.0))),
            Verdict::NoSpeed,
            Verdict::Kept,
            Verdict::Kept,
            Verdict::Kept,
        ];
        assert_eq!(got, want.into_iter().enumerate().collect::<Vec<_>>());
    }

    /// A reading followed by readings without a speed is decided within
    /// [`MAX_NO_SPEED`] of them, not held with them.
    #[test]
    fn readings_without_speeds_do_not_hold_a_reading() {
        let mut f = SpeedSpikes::default();
        f.push(Some((0.0, 10.0)), 0);
        f.push(Some((0.1, 10.0)), 1);
        for k in 2..(MAX_NO_SPEED + 10) {
            f.push(None, k);
            assert!(f.held.len() <= MAX_NO_SPEED + 1, "{k}");
        }
        let got: Vec<usize> = std::iter::from_fn(|| f.pop()).map(|(k, _)| k).collect();
        assert_eq!(got, (0..MAX_NO_SPEED + 10).collect::<Vec<_>>());
    }

    /// Time tags that stand or go back hold at most [`MAX_HELD`] readings.
    #[test]
    fn held_readings_are_bounded_whatever_the_time_tags() {
        let mut f = SpeedSpikes::default();
        f.push(Some((0.0, 10.0)), ());
        f.push(Some((0.0, 10.0)), ());
        f.push(Some((0.0, 10.0)), ());
        for k in 0..(MAX_HELD + 10) {
            f.push(Some((0.0, if k % 2 == 0 { 50.0 } else { 0.0 })), ());
            assert!(f.held.len() <= MAX_HELD);
        }
        f.finish();
        assert!(f.held.is_empty());
    }
}
