//! The recorder's clock as the IMU's `seq` says it ran.
//!
//! `seq` counts sample periods (+1 per IMU record, a jump for samples lost), so the time
//! between two accepted records is their `seq` step × the sample period, whatever their
//! time tags say. A recorder whose clock is set while it logs (a time sync) leaves tags
//! that leap forward or back by the setting while `seq` runs on; kept, a leap forward
//! reads as samples lost (filled with held rates, or failing the run as a gap no dead
//! reckoning bridges) and a leap back as tags going back, and the marks after it are
//! that far off the samples. A glitch in one record's tag, its neighbours agreeing, is
//! the same on a smaller scale.
//!
//! [`RecorderClock`] takes such leaps out of the time base, as the records stream by: a
//! record whose tag is off its `seq`'s time by more than [`tolerance_us`] is given its
//! `seq`'s time (the previous record's time plus its step's periods); the next record
//! tells which it was: back on the old clock, a lone tag off; on the leapt clock, a
//! clock step, and every later tag (and mark) is moved by the step. Times stay on the
//! clock of the log's start, the clock of `start_time_us`.
//!
//! The period is the mean tag step of the log's first [`LEARN_INTERVALS`] one-`seq`
//! steps without their tenth at either end ([`period_us`]; the header's period is not
//! trusted for it), and the recorder's jitter how far those steps stray from it
//! ([`jitter_us`]). The tolerance is half a period, or
//! [`JITTER_TOLERANCE`] times the jitter when that is more (at most
//! [`MAX_TOLERANCE_PERIODS`] periods): a clock set by a time sync's tens of milliseconds
//! is a leap, which kept would read as samples lost (a leap forward past half a period:
//! a sample's increments scaled as if it closed a gap) or as every later tag going back
//! (a leap back: the derive fails the run). A leap inside the learnt steps is left to the
//! derive, as are tags off by less than the tolerance (within half a period they move the
//! time base by less than a sample and stand for no sample lost).

/// One-`seq` tag steps whose trimmed mean is the period before leaps are looked for.
pub const LEARN_INTERVALS: usize = 64;

/// Times the recorder's jitter (how far its tag steps stray from the period) a tag may
/// be off its `seq`'s time before it is a leap, when that is more than half a period.
pub const JITTER_TOLERANCE: i128 = 4;

/// Sample periods a tag may be off its `seq`'s time at the most before it is a leap, how
/// ever jittery the recorder: 10 (0.1 s at 100 Hz).
pub const MAX_TOLERANCE_PERIODS: i128 = 10;

/// How far, µs, a tag one period of `period_us` after the record before may be off that
/// time and still be on the same clock, for a recorder whose one-`seq` tag steps stray
/// `jitter_us` from the period: half a period or [`JITTER_TOLERANCE`] times the jitter,
/// whichever is more, up to [`MAX_TOLERANCE_PERIODS`] periods.
pub fn one_step_tolerance_us(period_us: i128, jitter_us: i128) -> i128 {
    (JITTER_TOLERANCE * jitter_us).clamp(period_us / 2, MAX_TOLERANCE_PERIODS * period_us)
}

/// How far, µs, a tag `seq_step` periods of `period_us` after the record before may be
/// off that time and still be on the same clock: `one_step_us`
/// ([`one_step_tolerance_us`]), or across a gap of lost samples at least half its span
/// (a recorder's rate off by a little adds up over a long gap).
pub fn tolerance_us(one_step_us: i128, period_us: i128, seq_step: u64) -> i128 {
    one_step_us.max(i128::from(seq_step) * period_us / 2)
}

/// The period, µs, of one-`seq` tag steps `steps_us` (sorted in place): their mean
/// without the tenth at either end (a lone tag off, or a leap, strays one or two steps;
/// a jitter that repeats in a pattern, which a median takes one of, averages out).
pub fn period_us(steps_us: &mut [i128]) -> i128 {
    steps_us.sort_unstable();
    let cut = steps_us.len() / 10;
    let kept = &steps_us[cut..steps_us.len() - cut];
    if kept.is_empty() {
        return 0;
    }
    let n = kept.len() as i128;
    let sum: i128 = kept.iter().sum();
    (2 * sum + n).div_euclid(2 * n)
}

/// The recorder's jitter, µs: how far the one-`seq` tag steps `steps_us` stray from the
/// period `period_us`, at their 90th percentile (a lone tag off, which strays two steps,
/// leaves it as the others make it).
pub fn jitter_us(steps_us: &[i128], period_us: i128) -> i128 {
    let mut strays: Vec<i128> = steps_us.iter().map(|s| (s - period_us).abs()).collect();
    if strays.is_empty() {
        return 0;
    }
    let at = (strays.len() * 9 / 10).min(strays.len() - 1);
    *strays.select_nth_unstable(at).1
}

/// What the record after an IMU record whose tag was off said of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Resolved {
    /// The clock leapt at the record at byte `offset`: by `leap_us` (positive: forward),
    /// taken off its tag and every later one.
    Step {
        /// Byte offset of the first record on the leapt clock.
        offset: u64,
        /// Its tag less its `seq`'s time, µs.
        leap_us: i128,
    },
    /// The record at byte `offset` alone was off, by `off_us`; the records after it are
    /// on the clock before it.
    LoneTag {
        /// Byte offset of the record.
        offset: u64,
        /// Its tag less its `seq`'s time, µs.
        off_us: i128,
    },
}

/// A record whose tag was off its `seq`'s time, before the next record tells why.
#[derive(Debug, Clone, Copy)]
struct Pending {
    /// The offset of the clock it was on, if it leapt, µs.
    offset_us: i128,
    /// Its byte offset in the log.
    at: u64,
}

/// The clock of a stream of accepted IMU records; see the module documentation.
#[derive(Debug, Default)]
pub struct RecorderClock {
    /// One-`seq` tag steps seen while the period is learnt, µs.
    learning: Vec<i128>,
    /// The period, µs, once learnt (`None` while learning, or for good when the learnt
    /// mean does not advance: such tags are the derive's to judge).
    period_us: Option<i128>,
    /// How far a tag one `seq` after the record before may be off that time, µs, once
    /// the period is learnt ([`one_step_tolerance_us`] of the period and the learnt jitter).
    one_step_tolerance_us: i128,
    /// Whether the period's learning has ended.
    learnt: bool,
    /// Added to the recorded tags: the clock steps so far, µs.
    offset_us: i128,
    /// The last record's recorded and corrected tags, µs.
    last: Option<(i128, i128)>,
    /// The last record, when its tag was off.
    pending: Option<Pending>,
}

impl RecorderClock {
    /// The time, µs since the header's start on the clock of the log's start, of the IMU
    /// record at byte `at` tagged `t_us` and `seq_step` periods after the record before
    /// (1 for the first; `None` after a counter reset, which says nothing of the time
    /// between: the tag is then taken as it is, on the clock so far), and what it said
    /// of the record before when that one's tag was off.
    pub fn imu(&mut self, t_us: u64, seq_step: Option<u64>, at: u64) -> (u64, Option<Resolved>) {
        let t = i128::from(t_us);
        let Some((last_t, last_time)) = self.last else {
            self.last = Some((t, t));
            return (t_us, None);
        };
        let Some(seq_step) = seq_step else {
            // Nothing tells a leap from the tag before a lone tag off: it keeps its time.
            let resolved = self.finish();
            let time = t + self.offset_us;
            self.last = Some((t, time));
            return (clamp(time), resolved);
        };
        let Some(period) = self.period_us else {
            if !self.learnt && seq_step == 1 {
                self.learn(t - last_t);
            }
            let time = t + self.offset_us;
            self.last = Some((t, time));
            return (clamp(time), None);
        };
        let expected = last_time + i128::from(seq_step) * period;
        let tolerance = tolerance_us(self.one_step_tolerance_us, period, seq_step);
        let fits = |time: i128| (time - expected).abs() <= tolerance;
        // The record before was off: on the leapt clock this one says the clock stepped;
        // back on the old one (or on neither), that tag alone was off.
        let resolved = self.pending.take().map(|p| {
            let off_us = self.offset_us - p.offset_us;
            if !fits(t + self.offset_us) && fits(t + p.offset_us) {
                self.offset_us = p.offset_us;
                Resolved::Step {
                    offset: p.at,
                    leap_us: off_us,
                }
            } else {
                Resolved::LoneTag {
                    offset: p.at,
                    off_us,
                }
            }
        });
        let time = if fits(t + self.offset_us) {
            t + self.offset_us
        } else {
            self.pending = Some(Pending {
                offset_us: expected - t,
                at,
            });
            expected
        };
        self.last = Some((t, time));
        (clamp(time), resolved)
    }

    /// The time, µs, of a control-point mark tagged `t_us` (on the clock of the records
    /// around it). After a record whose tag was off, the mark is on whichever of the two
    /// clocks (before it, or leapt) puts it nearer that record's time.
    pub fn mark(&self, t_us: u64) -> u64 {
        let t = i128::from(t_us);
        let time = match (self.pending, self.last) {
            (Some(p), Some((_, last_time))) => {
                let (old, leapt) = (t + self.offset_us, t + p.offset_us);
                if (old - last_time).abs() <= (leapt - last_time).abs() {
                    old
                } else {
                    leapt
                }
            }
            _ => t + self.offset_us,
        };
        clamp(time)
    }

    /// At the end of the log: a last record whose tag was off is a lone tag (its time is
    /// its `seq`'s either way).
    pub fn finish(&mut self) -> Option<Resolved> {
        let p = self.pending.take()?;
        Some(Resolved::LoneTag {
            offset: p.at,
            off_us: self.offset_us - p.offset_us,
        })
    }

    /// What the clock steps add to the tags after the last one, µs.
    pub fn offset_us(&self) -> i128 {
        self.offset_us
    }

    fn learn(&mut self, step_us: i128) {
        self.learning.push(step_us);
        if self.learning.len() == LEARN_INTERVALS {
            let period = period_us(&mut self.learning);
            self.period_us = (period > 0).then_some(period);
            self.one_step_tolerance_us =
                one_step_tolerance_us(period, jitter_us(&self.learning, period));
            self.learnt = true;
            self.learning = Vec::new();
        }
    }
}

/// A time in µs as a tag: within u64's range.
fn clamp(t: i128) -> u64 {
    u64::try_from(t.max(0)).unwrap_or(u64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: u64 = 10_000;

    /// Feeds records `seq` 0.. with tags `tag(k)` (one `seq` apart); returns their times
    /// and what was resolved, by record.
    fn feed(n: u64, tag: impl Fn(u64) -> u64) -> (Vec<u64>, Vec<(u64, Resolved)>) {
        let mut clock = RecorderClock::default();
        let mut times = Vec::new();
        let mut said = Vec::new();
        for k in 0..n {
            let (time, r) = clock.imu(tag(k), Some(1), k);
            times.push(time);
            said.extend(r.map(|r| (k, r)));
        }
        said.extend(clock.finish().map(|r| (n, r)));
        (times, said)
    }

    #[test]
    fn a_clock_set_forward_or_back_is_taken_out() {
        // 2 s forward at record 500, 1 s back at record 800.
        let tag = |k: u64| {
            let t = 1_000_000 + k * T;
            match k {
                500..800 => t + 2_000_000,
                800.. => t + 2_000_000 - 1_000_000,
                _ => t,
            }
        };
        let (times, said) = feed(1000, tag);
        assert!(
            (times.iter().enumerate()).all(|(k, &t)| t == 1_000_000 + k as u64 * T),
            "{times:?}"
        );
        assert_eq!(
            said,
            [
                (
                    501,
                    Resolved::Step {
                        offset: 500,
                        leap_us: 2_000_000
                    }
                ),
                (
                    801,
                    Resolved::Step {
                        offset: 800,
                        leap_us: -1_000_000
                    }
                )
            ]
        );
    }

    /// A time sync's steps, a fraction of the old 10 periods' tolerance: 30 ms back, 6 ms
    /// forward (past half a period), each taken out; 4 ms (within half a period) kept.
    #[test]
    fn a_clock_set_by_milliseconds_is_taken_out() {
        let tag = |k: u64| {
            let t = 1_000_000 + k * T;
            match k {
                300..600 => t - 30_000,
                600..900 => t - 30_000 + 6_000,
                900.. => t - 30_000 + 6_000 + 4_000,
                _ => t,
            }
        };
        let (times, said) = feed(1000, tag);
        assert!(
            (times.iter().enumerate())
                .all(|(k, &t)| t == 1_000_000 + k as u64 * T + if k >= 900 { 4_000 } else { 0 }),
            "{times:?}"
        );
        assert_eq!(
            said,
            [
                (
                    301,
                    Resolved::Step {
                        offset: 300,
                        leap_us: -30_000
                    }
                ),
                (
                    601,
                    Resolved::Step {
                        offset: 600,
                        leap_us: 6_000
                    }
                )
            ]
        );
    }

    /// A recorder's jitter learnt: steps beyond four times it are leaps (20 ms with 2 ms
    /// of jitter), steps within it are jitter (15 ms with 4.5 ms of jitter, whose
    /// tolerance is 18 ms: left to the derive, as a leap below 10 periods was before).
    #[test]
    fn the_tolerance_follows_the_recorders_jitter() {
        for (jitter, leap, taken) in [(2_000, 20_000, true), (4_500, 15_000, false)] {
            let tag = |k: u64| {
                let shake = [0, jitter, jitter / 2, jitter][(k % 4) as usize];
                1_000_000 + k * T + shake + if k >= 500 { leap } else { 0 }
            };
            let (times, said) = feed(1000, tag);
            let steps: Vec<_> = said.iter().map(|(_, r)| *r).collect();
            if taken {
                // The leap as its record measured it: within the record before's jitter.
                let [
                    Resolved::Step {
                        offset: 500,
                        leap_us,
                    },
                ] = steps[..]
                else {
                    panic!("jitter {jitter}: {steps:?}");
                };
                assert!((leap_us - i128::from(leap)).abs() <= i128::from(jitter));
                assert_eq!(i128::from(times[999]), i128::from(tag(999)) - leap_us);
            } else {
                assert!(steps.is_empty(), "jitter {jitter}: {steps:?}");
                assert_eq!(times[999], tag(999));
            }
        }
    }

    /// The jitter is the steps' 90th percentile stray and the period their mean without
    /// the tenth at either end: a lone tag off (two steps astray) leaves both at what the
    /// others give.
    #[test]
    fn a_lone_tag_off_leaves_the_period_and_jitter_as_the_others_make_them() {
        let mut steps: Vec<i128> = (0..64).map(|k| 10_000 + [0, 300, -300][k % 3]).collect();
        assert_eq!(jitter_us(&steps, 10_000), 300);
        steps[20] += 5_000_000;
        steps[21] -= 5_000_000;
        assert_eq!(jitter_us(&steps, 10_000), 300);
        // The two strays trimmed with a few of the jitter's steps: 6 µs off.
        assert!((period_us(&mut steps) - 10_000).abs() <= 6);
        let mut even = vec![10_000_i128; 64];
        even[20] += 5_000_000;
        even[21] -= 5_000_000;
        assert_eq!(period_us(&mut even), 10_000);
        // A jitter in a pattern: the median step is 11 ms, the period 10.
        let mut pattern: Vec<i128> = (0..64)
            .map(|k| [12_000, 9_000, 11_000, 8_000][k % 4])
            .collect();
        assert_eq!(period_us(&mut pattern), 10_000);
        assert_eq!(period_us(&mut []), 0);
        assert_eq!(jitter_us(&[], 10_000), 0);
        assert_eq!(one_step_tolerance_us(10_000, 0), 5_000);
        assert_eq!(one_step_tolerance_us(10_000, 3_000), 12_000);
        assert_eq!(one_step_tolerance_us(10_000, 1_000_000), 100_000);
        assert_eq!(tolerance_us(5_000, 10_000, 1), 5_000);
        assert_eq!(tolerance_us(5_000, 10_000, 301), 1_505_000);
    }

    proptest::proptest! {
        /// Any tags, any `seq` steps (counter resets among them): no panic, no overflow.
        #[test]
        fn any_tags_and_steps_are_taken(
            records in proptest::collection::vec(
                (proptest::prelude::any::<u64>(), proptest::option::of(1u64..=1 << 32)),
                0..300,
            ),
        ) {
            let mut clock = RecorderClock::default();
            for (k, (tag, step)) in (0u64..).zip(records) {
                clock.imu(tag, step, k);
                clock.mark(tag);
            }
            clock.finish();
        }

        /// A recorder whose tags jitter by up to an eighth of a period, its clock never
        /// set: every tag is kept as it is, and nothing is said.
        #[test]
        fn a_steady_clock_keeps_its_tags(
            jitter in proptest::collection::vec(0u64..=T / 8, 100..400),
        ) {
            let (times, said) = feed(jitter.len() as u64, |k| 1_000_000 + k * T + jitter[k as usize]);
            proptest::prop_assert!(said.is_empty(), "{said:?}");
            for (k, t) in times.iter().enumerate() {
                proptest::prop_assert_eq!(*t, 1_000_000 + k as u64 * T + jitter[k]);
            }
        }
    }

    #[test]
    fn a_lone_tag_off_is_given_its_seqs_time() {
        let tag = |k: u64| match k {
            300 => u64::MAX,
            600 => 5,
            999 => k * T + 10_000_000,
            _ => k * T,
        };
        let (times, said) = feed(1000, tag);
        assert!(
            (times.iter().enumerate()).all(|(k, &t)| t == k as u64 * T),
            "{times:?}"
        );
        let offsets: Vec<_> = said.iter().map(|(_, r)| *r).collect();
        assert_eq!(
            offsets,
            [
                Resolved::LoneTag {
                    offset: 300,
                    off_us: i128::from(u64::MAX) - 300 * i128::from(T)
                },
                Resolved::LoneTag {
                    offset: 600,
                    off_us: 5 - 600 * i128::from(T)
                },
                Resolved::LoneTag {
                    offset: 999,
                    off_us: 10_000_000
                }
            ]
        );
    }

    #[test]
    fn jitter_and_lost_samples_are_not_leaps() {
        let mut clock = RecorderClock::default();
        let mut seq = 0u64;
        let mut prev = 0u64;
        for k in 0..2000u64 {
            // 3 ms of jitter; 200 samples lost at 1000 (2 s), their tags 2.02 s apart.
            let step = if k == 1000 { 201 } else { 1 };
            seq += step;
            let jitter = [0, 3000, 1000, 2500][(k % 4) as usize];
            let tag = seq * T + jitter + if k >= 1000 { 20_000 } else { 0 };
            let (time, r) = clock.imu(tag, Some(if k == 0 { 1 } else { step }), k);
            assert_eq!(r, None, "record {k}");
            assert_eq!(time, tag, "record {k}");
            assert!(k == 0 || time > prev);
            prev = time;
        }
        assert_eq!(clock.finish(), None);
    }

    #[test]
    fn a_leap_inside_the_learnt_stretch_is_left_as_tagged() {
        let tag = |k: u64| if k >= 10 { k * T + 5_000_000 } else { k * T };
        let (times, said) = feed(200, tag);
        assert!(said.is_empty());
        assert_eq!(times[10], tag(10));
        // Tags that do not advance give no period: nothing is moved.
        let (times, said) = feed(200, |k| if k < 150 { 7 } else { 7 + 3_000_000 });
        assert!(said.is_empty() && times[199] == 3_000_007);
    }

    /// A recorder restarted mid-log, its counter and its clock from 0: `seq` says nothing
    /// of the time between, so the tags are taken as they are (going back: the derive's
    /// to judge), and leaps after the restart are found again.
    #[test]
    fn a_counter_reset_keeps_the_tags() {
        let mut clock = RecorderClock::default();
        for k in 0..500 {
            assert_eq!(
                clock.imu(1_000_000 + k * T, Some(1), k),
                (1_000_000 + k * T, None)
            );
        }
        assert_eq!(clock.imu(0, None, 500), (0, None));
        for k in 1..100 {
            assert_eq!(clock.imu(k * T, Some(1), 500 + k), (k * T, None));
        }
        clock.imu(100 * T + 3_000_000, Some(1), 600);
        let (time, r) = clock.imu(101 * T + 3_000_000, Some(1), 601);
        assert_eq!(time, 101 * T);
        assert!(
            matches!(r, Some(Resolved::Step { offset: 600, .. })),
            "{r:?}"
        );
    }

    #[test]
    fn a_mark_takes_the_clock_that_puts_it_beside_the_record_before() {
        let mut clock = RecorderClock::default();
        for k in 0..100 {
            clock.imu(k * T, Some(1), k);
        }
        // A mark on the old clock, then the clock leaps 5 s: a mark stamped on either.
        assert_eq!(clock.mark(99 * T), 99 * T);
        clock.imu(100 * T + 5_000_000, Some(1), 100);
        assert_eq!(clock.mark(100 * T + 5_000_000 + 10), 100 * T + 10);
        assert_eq!(clock.mark(99 * T + 20), 99 * T + 20);
        let (_, r) = clock.imu(101 * T + 5_000_000, Some(1), 101);
        assert!(matches!(r, Some(Resolved::Step { .. })));
        assert_eq!(clock.mark(101 * T + 5_000_000), 101 * T);
        assert_eq!(clock.offset_us(), -5_000_000);
    }
}
