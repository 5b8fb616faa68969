//! Text lines that come in bursts: a logger that stamps each line as it receives it,
//! several at once (a serial port's buffer read now and then, or a logger stalled a
//! moment), writes tags a fraction of a period apart within a burst and a burst's worth
//! of periods apart around it. Read as written, a stall's lines read as the clock set
//! back and lines lost; a log wholly in bursts has the spacing within a burst for its
//! period, every gap between bursts reads as samples lost and the run has no dead
//! reckoning.
//!
//! The samples of a burst were made in the periods before it arrived: its first tag is
//! the time its last sample was received, and the lines before that one were made a
//! period apart before it. `BurstSpread` gives each line of a burst its time: the
//! burst's first tag less a period for each line after it. A line lost in a burst is
//! then a gap of one sample before the burst, which the slot clock counts; a burst
//! arriving late or early moves its lines together, a jitter the slot clock follows.
//!
//! A log wholly in bursts is told from its first lines (`burst_period_s`: most steps
//! a quarter of the mean step or less, the steps between bursts, over the samples of
//! the burst they bring, agreeing on one period), and every run of lines close together
//! (each under a quarter of that period after the one before) is spread. In any other
//! log, a run of three lines or more close together (two steps in a row under a quarter
//! of the period, which a jitter of less than ±0.75 of a period never gives) is a
//! stall's burst and is spread, unless its lines so spread would begin less than half a
//! period after the line before it (a line late by more than 0.75 of a period, the next
//! on its slot and the one after early by as much: the reader's rule for lines written
//! late or early alone takes them); two lines close together are left to that rule
//! too.

use std::collections::VecDeque;

use crate::error::FormatError;
use crate::kfgins::TextSample;

/// Lines close together that a log not wholly in bursts spreads as a burst, at least.
pub const MIN_STALL_LINES: usize = 3;
/// Fewest first lines a log is judged in bursts on.
const MIN_LINES: usize = 41;
/// Most first lines a log is judged in bursts on, when its first lines are mostly close
/// together (`mostly_close`): room for [`MIN_BURSTS`] and more of 100 lines and more
/// (a second's buffer of a 100-Hz IMU).
pub(crate) const BURST_WINDOW: usize = 2000;
/// Fewest whole bursts (a burst's step from the one before, over its lines) that must
/// agree on the period.
const MIN_BURSTS: usize = 4;
/// Longest burst held, lines: a longer run of lines close together (a logger's clock
/// standing) is held in parts of this many, each spread from its own first tag in a log
/// wholly in bursts (in any other a clock standing is read as written: spread back, its
/// lines would lie on the lines before).
pub const MAX_BURST_LINES: usize = 1024;

/// Whether `b` repeats `a`'s values (its time aside): a line sent twice, not a sample
/// of its own, and so no slot of its burst.
pub(crate) fn repeats(a: &TextSample, b: &TextSample) -> bool {
    a.dtheta_rad == b.dtheta_rad && a.dvel_mps == b.dvel_mps && a.speed_mps == b.speed_mps
}

/// The period at which the first lines' bursts bring their samples, s, or `None` when
/// the lines do not come in bursts.
///
/// In bursts: at least half the steps between lines (a line repeating the one before
/// aside) are under a quarter of the mean step over the lines, and of the whole bursts
/// (parted by the longer steps), at least [`MIN_BURSTS`], three in four agree within a
/// quarter on one period: each burst's first tag's step from the burst before's, over
/// the samples the burst brings. The period is then those agreeing bursts' steps summed
/// over their samples summed: a burst's lateness moves its step and the next one's
/// apart, and a median of steps that vary so is off by as much as a step's lateness over
/// its samples (Kingston in bursts of 3 to 8 lines, up to 30 ms late: 1.7 %, the last of
/// 8 lines spread 12 ms off). A log whose lines go on a period at a time has no step a
/// quarter of the mean (a jitter of ±0.4 of a period leaves 0.2 of it); one with a gap
/// among its first lines has few bursts, and none agreeing; one whose lines are each
/// written twice has its repeats set aside.
pub(crate) fn burst_period_s(lines: &[TextSample]) -> Option<f64> {
    let starts = burst_starts(lines)?;
    let steps: Vec<(f64, usize)> = (starts.windows(3))
        .map(|w| {
            (
                lines[w[1]].t_s - lines[w[0]].t_s,
                samples(&lines[w[1]..w[2]]),
            )
        })
        .collect();
    if steps.len() < MIN_BURSTS {
        return None;
    }
    let mut periods_s: Vec<f64> = steps.iter().map(|(s, n)| s / *n as f64).collect();
    periods_s.sort_by(f64::total_cmp);
    let median_s = periods_s[periods_s.len() / 2];
    let agrees = |step_s: f64, n: usize| (step_s / n as f64 - median_s).abs() <= median_s / 4.0;
    let (span_s, n) = (steps.iter())
        .filter(|(step_s, n)| agrees(*step_s, *n))
        .fold((0.0, 0), |(span_s, total), (step_s, n)| {
            (span_s + step_s, total + n)
        });
    let agree = steps
        .iter()
        .filter(|(step_s, n)| agrees(*step_s, *n))
        .count();
    let period_s = span_s / n.max(1) as f64;
    (period_s.is_finite() && period_s > 0.0 && agree * 4 >= steps.len() * 3).then_some(period_s)
}

/// Whether at least half the steps between `lines` (a line repeating the one before
/// aside) are under a quarter of their mean step, as in a log wholly in bursts: the
/// first lines of such a log are read further ([`BURST_WINDOW`]) to judge it.
pub(crate) fn mostly_close(lines: &[TextSample]) -> bool {
    burst_starts(lines).is_some()
}

/// The first line of each burst of `lines` (parted by steps of a quarter of their mean
/// step or more), when at least half their steps are shorter (a line repeating the one
/// before aside) and they are [`MIN_LINES`] or more.
fn burst_starts(lines: &[TextSample]) -> Option<Vec<usize>> {
    let n = lines.len();
    if n < MIN_LINES {
        return None;
    }
    let mean_s = (lines[n - 1].t_s - lines[0].t_s) / (n - 1) as f64;
    if !(mean_s.is_finite() && mean_s > 0.0) {
        return None;
    }
    let (mut steps, mut short) = (0usize, 0usize);
    let mut starts = vec![0];
    for (i, pair) in lines.windows(2).enumerate() {
        if repeats(&pair[0], &pair[1]) {
            continue;
        }
        steps += 1;
        if (pair[1].t_s - pair[0].t_s).abs() < mean_s / 4.0 {
            short += 1;
        } else {
            starts.push(i + 1);
        }
    }
    (short * 2 >= steps).then_some(starts)
}

/// The samples a burst's lines bring: its lines less those repeating the line before.
fn samples(burst: &[TextSample]) -> usize {
    1 + burst.windows(2).filter(|w| !repeats(&w[0], &w[1])).count()
}

/// What a text log's bursts were (`ingest.json`'s `text_bursts`).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TextBursts {
    /// The log's lines all come in bursts, found in its first lines (`burst_period_s`);
    /// else the bursts are stalls of [`MIN_STALL_LINES`] lines or more in a log whose
    /// lines otherwise go on a period at a time.
    pub whole_log: bool,
    /// The step between the lines spread over a burst, s: the period the first lines'
    /// bursts agree on, or the log's period.
    pub period_s: f64,
    /// Bursts spread (a run of lines close together longer than [`MAX_BURST_LINES`]
    /// counts as several).
    pub bursts: u64,
    /// Lines spread over them.
    pub lines: u64,
    /// The most lines a burst held.
    pub longest_lines: u64,
}

/// Gives the lines of a burst their times: each burst's lines (lines whose tags are
/// under a quarter of the period from the line before) end at the burst's first tag, a
/// period apart; a line repeating the one before takes its time (the reader then sets it
/// aside as sent again). Lines not in a burst of [`Self::min_lines`] go on as written.
#[derive(Debug)]
pub(crate) struct BurstSpread {
    account: TextBursts,
    /// The fewest lines close together that are spread: 2 in a log wholly in bursts,
    /// [`MIN_STALL_LINES`] else.
    min_lines: usize,
    /// Lines read ahead before the layer began (the log's first lines), given out
    /// through it first.
    unread: VecDeque<TextSample>,
    /// The spread lines of the last burst, not yet given out.
    spread: VecDeque<TextSample>,
    /// The line that ended the last burst: the next one's first.
    next: Option<TextSample>,
    /// An error met reading a burst, returned once its lines are given out.
    failed: Option<FormatError>,
    /// The time of the last line read into [`Self::spread`], s.
    last_t_s: Option<f64>,
}

impl BurstSpread {
    /// Spreads bursts at `period_s`, the lines read so far (`unread`) first: every run of
    /// lines close together when `whole_log` (the first lines are in bursts), runs of
    /// [`MIN_STALL_LINES`] or more else.
    pub(crate) fn new(period_s: f64, whole_log: bool, unread: VecDeque<TextSample>) -> Self {
        Self {
            account: TextBursts {
                whole_log,
                period_s,
                ..TextBursts::default()
            },
            min_lines: if whole_log { 2 } else { MIN_STALL_LINES },
            unread,
            spread: VecDeque::new(),
            next: None,
            failed: None,
            last_t_s: None,
        }
    }

    /// The account so far, once a burst was spread.
    pub(crate) fn account(&self) -> Option<TextBursts> {
        (self.account.bursts > 0).then_some(self.account)
    }

    /// The next line with its time spread over its burst, or `None` at the end; `read`
    /// gives the lines as written.
    pub(crate) fn next(
        &mut self,
        mut read: impl FnMut() -> Result<Option<TextSample>, FormatError>,
    ) -> Result<Option<TextSample>, FormatError> {
        if let Some(s) = self.spread.pop_front() {
            return Ok(Some(s));
        }
        if let Some(e) = self.failed.take() {
            return Err(e);
        }
        let mut line = || match self.unread.pop_front() {
            Some(s) => Ok(Some(s)),
            None => read(),
        };
        let first = match self.next.take() {
            Some(s) => s,
            None => match line()? {
                Some(s) => s,
                None => return Ok(None),
            },
        };
        let close_s = self.account.period_s / 4.0;
        // The burst is read into the (empty) queue of lines to give out, and spread there.
        self.spread.push_back(first);
        while self.spread.len() < MAX_BURST_LINES {
            let last_s = self.spread.back().map_or(first.t_s, |s| s.t_s);
            match line() {
                Ok(Some(s)) if (s.t_s - last_s).abs() < close_s => self.spread.push_back(s),
                Ok(Some(s)) => {
                    self.next = Some(s);
                    break;
                }
                Ok(None) => break,
                Err(e) => {
                    self.failed = Some(e);
                    break;
                }
            }
        }
        let burst = self.spread.make_contiguous();
        let last_slot = samples(burst) - 1;
        let (first_s, period_s) = (first.t_s, self.account.period_s);
        let begins_s = first_s - last_slot as f64 * period_s;
        let overlaps = |before_s: f64| begins_s < before_s + period_s / 2.0;
        if burst.len() < self.min_lines
            || !self.account.whole_log && self.last_t_s.is_some_and(overlaps)
        {
            self.last_t_s = burst.last().map(|s| s.t_s);
            return Ok(self.spread.pop_front());
        }
        let mut slot = 0;
        for i in 0..burst.len() {
            if i > 0 && !repeats(&burst[i - 1], &burst[i]) {
                slot += 1;
            }
            burst[i].t_s = first_s - (last_slot - slot) as f64 * period_s;
        }
        self.last_t_s = Some(first_s);
        let a = &mut self.account;
        a.bursts += 1;
        a.lines += burst.len() as u64;
        a.longest_lines = a.longest_lines.max(burst.len() as u64);
        Ok(self.spread.pop_front())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::kfgins::tests::read_all;
    use crate::report::IngestReport;

    /// A number in [0, 1) drawn from `k` (splitmix64): the tests' draws, the same on
    /// every machine.
    pub(crate) fn unit(k: u64) -> f64 {
        let mut z = k.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        (z ^ (z >> 31)) as f64 / 2f64.powi(64)
    }

    /// A 7-column log of lines `(tag_s, sample)`, each sample's increments its own.
    fn log_of(lines: &[(f64, u64)]) -> String {
        (lines.iter())
            .map(|(t, k)| format!("{t:.7} {k} 2 3 4 5 6\n"))
            .collect()
    }

    /// The samples `text` gives and the reader's account ([`read_all`]'s, its faults
    /// aside).
    fn read(text: &str) -> (Vec<TextSample>, IngestReport) {
        let (v, report, _) = read_all(text);
        (v, report)
    }

    /// Each sample's time less its true time (sample `k` made at `k × period_s`), s.
    fn errors_s(v: &[TextSample], period_s: f64) -> impl Iterator<Item = f64> + '_ {
        v.iter().map(move |s| s.t_s - s.dtheta_rad[0] * period_s)
    }

    /// A 100-Hz log handed over in bursts of 3 to 12 lines, each burst stamped 0 to 3 ms
    /// after its last sample was made and its lines 0.1 ms apart. Read as written its
    /// tags' median step was 0.1 ms and the derive failed on the samples lost. Now every
    /// line takes its sample's time to the burst's lateness plus what the period's error
    /// adds over the burst, and no line is lost, off its slot or stepped.
    #[test]
    fn a_log_wholly_in_bursts_has_its_lines_spread_over_each_burst() {
        let period_s = 0.01;
        let (mut lines, mut k, mut bursts) = (Vec::new(), 1u64, 0u64);
        while k < 3000 {
            let n = 3 + (unit(k) * 10.0) as u64;
            let stamp_s = (k + n - 1) as f64 * period_s + 0.003 * unit(k + 7);
            lines.extend((0..n).map(|j| (stamp_s + 1e-4 * j as f64, k + j)));
            (k, bursts) = (k + n, bursts + 1);
        }
        let (v, rep) = read(&log_of(&lines));
        assert_eq!(v.len(), lines.len());
        let b = rep.text_bursts.expect("bursts");
        assert!(b.whole_log && b.longest_lines <= 12, "{b:?}");
        assert_eq!((b.bursts, b.lines), (bursts, lines.len() as u64));
        assert!((b.period_s / period_s - 1.0).abs() < 0.05, "{b:?}");
        let late_s = 0.003 + 11.0 * (b.period_s - period_s).abs() + 1e-9;
        for e in errors_s(&v, period_s) {
            assert!((0.0 - 1e-9..=late_s).contains(&e), "{e}");
        }
        let counted = (
            rep.lost_samples,
            rep.lines_off_slot,
            rep.text_clock_steps_back,
        );
        assert_eq!(counted, (0, 0, 0), "{rep:?}");
        assert_eq!(rep.text_clock_steps_forward, 0);
    }

    /// A 100-Hz log on its period (jitter ±0.2 of one) whose logger stalls now and then
    /// and hands over 3 to 8 lines at once, stamped up to 0.2 of a period after the last
    /// was made. Read as written, each stall read as the clock set back and lines lost
    /// (Kingston: 500 m off before DISUPT, the run "ok"). Now each burst's lines take
    /// their samples' times to the jitter, no line is lost or stepped; a line lost in a
    /// stall is a sample lost before the burst, counted (the lines before it in the
    /// burst a period late).
    #[test]
    fn a_stalls_burst_in_a_log_on_its_period_is_spread_and_its_lines_lost_counted() {
        let period_s = 0.01;
        let (mut lines, mut k, mut stalls, mut in_stalls, mut dropped) =
            (Vec::new(), 1u64, 0u64, 0u64, 0u64);
        let mut late_by_loss = Vec::new();
        while k < 4000 {
            if k > 150 && unit(k) < 1.0 / 40.0 {
                let n = 3 + (unit(k + 1) * 6.0) as u64;
                let stamp_s = (k + n - 1) as f64 * period_s + 0.002 * unit(k + 2);
                // In one stall in five of 4 lines or more, a line of the burst lost (of 3,
                // the two left would be no burst: see the module's doc).
                let lost =
                    (n > 3 && unit(k + 3) < 0.2).then(|| k + (unit(k + 4) * n as f64) as u64);
                late_by_loss.extend(lost.map_or(0..0, |lost| k..lost));
                let burst: Vec<(f64, u64)> = (k..k + n)
                    .filter(|&s| Some(s) != lost)
                    .enumerate()
                    .map(|(j, s)| (stamp_s + 2e-4 * j as f64, s))
                    .collect();
                (stalls, in_stalls) = (stalls + 1, in_stalls + burst.len() as u64);
                dropped += lost.is_some() as u64;
                lines.extend(burst);
                k += n;
            } else {
                let jitter_s = 0.4 * (unit(k + 5) - 0.5) * period_s;
                lines.push((k as f64 * period_s + jitter_s, k));
                k += 1;
            }
        }
        assert!(stalls > 50 && dropped > 5, "{stalls} {dropped}");
        let (v, rep) = read(&log_of(&lines));
        assert_eq!(v.len(), lines.len());
        let b = rep.text_bursts.expect("bursts");
        assert!(
            !b.whole_log && (b.bursts, b.lines) == (stalls, in_stalls),
            "{b:?}"
        );
        assert!((b.period_s / period_s - 1.0).abs() < 1e-3, "{b:?}");
        // Where in a burst its line was lost its lines do not tell: the gap is taken
        // before the burst, and the lines before the one lost are a period late.
        for (s, e) in v.iter().zip(errors_s(&v, period_s)) {
            let after_loss = late_by_loss.contains(&(s.dtheta_rad[0] as u64));
            let within_s = if after_loss { 1.2 } else { 0.2 } * period_s + 1e-6;
            assert!(e.abs() <= within_s, "{e} at {s:?}");
        }
        assert_eq!((rep.lost_samples, rep.seq_gaps), (dropped, dropped));
        let counted = (rep.lines_off_slot, rep.text_clock_steps_back);
        assert_eq!(counted, (0, 0), "{rep:?}");
        assert_eq!(rep.text_clock_steps_forward, 0);
    }

    /// Lines each written twice are no bursts (a repeat is set aside, not a step of the
    /// log's): the repeats are rejected as sent again, the rest read as written. A log
    /// wholly in bursts whose lines are each sent twice is spread, its repeats rejected.
    #[test]
    fn lines_sent_twice_are_no_burst_and_are_set_aside() {
        let period_s = 0.01;
        let twice: Vec<(f64, u64)> = (1..500)
            .flat_map(|k| [(k as f64 * period_s, k); 2])
            .collect();
        let (v, rep) = read(&log_of(&twice));
        assert_eq!((v.len(), rep.rejected.duplicate_seq), (499, 499));
        assert_eq!(rep.text_bursts, None);

        let bursts: Vec<(f64, u64)> = (0..100u64)
            .flat_map(|b| {
                (0..5).map(move |j| (0.05 * (b + 1) as f64 + 1e-4 * j as f64, 5 * b + j + 1))
            })
            .flat_map(|line| [line; 2])
            .collect();
        let (v, rep) = read(&log_of(&bursts));
        assert_eq!((v.len(), rep.rejected.duplicate_seq), (500, 500));
        assert!(
            rep.text_bursts
                .is_some_and(|b| b.whole_log && b.bursts == 100)
        );
        assert!(errors_s(&v, period_s).all(|e| e.abs() < 1e-9));
        assert_eq!(rep.lost_samples, 0);
    }

    /// A gap among a log's first lines leaves most of their steps short of the mean
    /// step, but no bursts agreeing on a period: the log is read as written.
    #[test]
    fn a_gap_among_the_first_lines_is_no_burst() {
        let lines: Vec<(f64, u64)> = (1..300u64)
            .map(|k| (k as f64 * 0.01 + if k > 50 { 30.0 } else { 0.0 }, k))
            .collect();
        assert!(mostly_close(&read_raw(&lines)[..101]));
        let (v, rep) = read(&log_of(&lines));
        assert_eq!((v.len(), rep.text_bursts), (299, None));
        assert!(
            v.iter()
                .zip(&lines)
                .all(|(s, l)| s.t_s == l.0 || (s.t_s - l.0).abs() < 1e-9)
        );
    }

    /// The samples of `lines` as the reader parses them (for [`burst_period_s`]).
    fn read_raw(lines: &[(f64, u64)]) -> Vec<TextSample> {
        (lines.iter())
            .map(|&(t_s, k)| TextSample {
                line: k,
                t_s,
                dtheta_rad: [k as f64, 2.0, 3.0],
                dvel_mps: [4.0, 5.0, 6.0],
                speed_mps: None,
                slot: 0,
            })
            .collect()
    }

    /// A logger's clock standing for 3000 lines mid-log (every tag the same) is no
    /// stall: its lines spread back from their tag would lie on the lines before them.
    /// They are read as written (held [`MAX_BURST_LINES`] at a time), and the read ends.
    #[test]
    fn a_clock_standing_is_no_burst() {
        let lines: Vec<(f64, u64)> = (1..5000u64)
            .map(|k| {
                (
                    if (1000..4000).contains(&k) {
                        10.0
                    } else {
                        k as f64 * 0.01
                    },
                    k,
                )
            })
            .collect();
        let (v, rep) = read(&log_of(&lines));
        assert_eq!((v.len(), rep.text_bursts), (4999, None));
        assert!(rep.t_non_increasing >= 2999, "{rep:?}");
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// Lines jittering by up to ±0.45 of a period about their slots (as far as the
        /// reader's slots go), lost in stretches before a quarter of them, or by up to
        /// ±0.7 none lost: two steps in a row under a quarter of a period would take a
        /// line 0.75 of a period late two lines before one as early, so no burst is ever
        /// read.
        #[test]
        fn jittering_lines_are_never_a_burst(
            lines in proptest::collection::vec((0u64..12, -1.0f64..1.0), 110..1500),
            wide in proptest::bool::ANY,
        ) {
            let mut slot = 0u64;
            let tagged: Vec<(f64, u64)> = (lines.iter().enumerate())
                .map(|(k, &(lost, jitter))| {
                    slot += 1 + if wide { 0 } else { lost.saturating_sub(8) };
                    let jitter = jitter * if wide { 0.7 } else { 0.45 };
                    ((slot as f64 + jitter) * 0.01, k as u64)
                })
                .collect();
            let (_, rep) = read(&log_of(&tagged));
            proptest::prop_assert_eq!(rep.text_bursts, None);
        }
    }
}
