//! A text log's gaps of lost samples, with a first or last line that stands apart left
//! out of them.
//!
//! A text log says nothing of samples lost but its time tags: an interval of several
//! sample periods is a gap of the samples that would have filled it. A lone line a
//! logger wrote before it began (or after it stopped), an hour from the rest, is no such
//! gap: the derive places that line beside its neighbour (`first_sample_apart` in
//! `unz_stages::derive`, with the same `max_gap_s`), and counted, the hour read as
//! 360 000 samples lost in `ingest.json` and the campaign's summary. The line is kept and
//! counted as accepted; its interval is reported apart.
//!
//! The rule is the derive's: the first line stands apart when the interval after it is
//! longer than `max_gap_s` and the next is not; the last, when the interval before it is
//! longer than `max_gap_s` in a log of three samples or more. A binary log's lost samples
//! are its `seq`'s jumps, which the recorder counted: they stay as counted.

use crate::report::IngestReport;

/// An interval longer than the longest gap a run bridges: its samples lost (with the
/// period they were counted in) when it is a gap of them, and its length, s.
#[derive(Debug, Clone, Copy)]
struct Long {
    lost: Option<(u64, f64)>,
    length_s: f64,
}

/// The gaps of a text log's accepted samples, interval by interval.
#[derive(Debug)]
pub(crate) struct GapAccount {
    /// The longest gap a run bridges, s (the derive's `max_gap_s`): infinite, no line
    /// stands apart.
    max_gap_s: f64,
    /// Intervals taken so far.
    intervals: u64,
    /// The first interval while the second is awaited, when it is longer than
    /// `max_gap_s`: not counted yet.
    first: Option<Long>,
    /// The last interval taken, when it is longer than `max_gap_s` (counted).
    last: Option<Long>,
}

impl GapAccount {
    /// An account for a run that bridges gaps up to `max_gap_s`.
    pub(crate) fn new(max_gap_s: f64) -> Self {
        Self {
            max_gap_s,
            intervals: 0,
            first: None,
            last: None,
        }
    }

    /// The longest gap a run bridges, s.
    pub(crate) fn max_gap_s(&self) -> f64 {
        self.max_gap_s
    }

    /// Takes the interval of `length_s` from the sample before, a gap of `lost` samples
    /// (their count and the period they were counted in; `None`: no gap).
    pub(crate) fn interval(
        &mut self,
        report: &mut IngestReport,
        length_s: f64,
        lost: Option<(u64, f64)>,
    ) {
        self.intervals += 1;
        let long = (length_s > self.max_gap_s).then_some(Long { lost, length_s });
        match self.intervals {
            // Held until the second tells whether the first line stands apart.
            1 if long.is_some() => self.first = long,
            2 => {
                if let Some(first) = self.first.take() {
                    if long.is_none() {
                        report.first_line_apart_s = Some(first.length_s);
                    } else {
                        count(report, first.lost);
                    }
                }
                count(report, lost);
            }
            _ => count(report, lost),
        }
        self.last = long;
    }

    /// At the log's end: a first interval still held is a gap like any other; a long last
    /// one after two samples or more parts the last line from them.
    pub(crate) fn end(&mut self, report: &mut IngestReport) {
        if let Some(first) = self.first.take() {
            count(report, first.lost);
        } else if let Some(last) = self.last.take()
            && self.intervals >= 2
        {
            uncount(report, last.lost);
            report.last_line_apart_s = Some(last.length_s);
        }
    }
}

/// Counts a gap of `lost` samples of a period (none: no gap).
fn count(report: &mut IngestReport, lost: Option<(u64, f64)>) {
    if let Some((lost, period_s)) = lost {
        report.seq_gaps += 1;
        // Saturating: a tag of 1e300 (a damaged line) is a gap of more samples than a
        // u64 counts (`as` saturates too).
        report.lost_samples = report.lost_samples.saturating_add(lost);
        report.lost_duration_s = report.lost_samples as f64 * period_s;
    }
}

/// Takes back a gap [`count`] counted.
fn uncount(report: &mut IngestReport, lost: Option<(u64, f64)>) {
    if let Some((lost, period_s)) = lost {
        report.seq_gaps = report.seq_gaps.saturating_sub(1);
        report.lost_samples = report.lost_samples.saturating_sub(lost);
        report.lost_duration_s = report.lost_samples as f64 * period_s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The report of samples at `tags_s` (period 0.01 s), gaps beyond 2 s apart.
    fn account(tags_s: &[f64]) -> IngestReport {
        let mut report = IngestReport::default();
        let mut gaps = GapAccount::new(2.0);
        for w in tags_s.windows(2) {
            let dt = w[1] - w[0];
            let steps = (dt / 0.01).round();
            let lost = (steps >= 2.0).then_some(((steps - 1.0) as u64, 0.01));
            gaps.interval(&mut report, dt, lost);
        }
        gaps.end(&mut report);
        report
    }

    fn run(from_s: f64, n: usize) -> Vec<f64> {
        (0..n).map(|k| from_s + k as f64 * 0.01).collect()
    }

    #[test]
    fn a_lone_first_line_an_hour_before_is_apart_not_lost_samples() {
        let mut tags = vec![0.0];
        tags.extend(run(3600.0, 100));
        let r = account(&tags);
        assert_eq!((r.seq_gaps, r.lost_samples), (0, 0));
        assert_eq!(r.first_line_apart_s, Some(3600.0));
        assert_eq!(r.last_line_apart_s, None);
    }

    #[test]
    fn a_lone_last_line_is_apart_and_the_gaps_between_are_lost_samples() {
        let mut tags = run(0.0, 100);
        // A gap of 4 samples, under the longest a run bridges.
        tags.extend(run(1.04, 100));
        tags.push(7200.0);
        let r = account(&tags);
        assert_eq!((r.seq_gaps, r.lost_samples), (1, 4));
        assert!((r.lost_duration_s - 0.04).abs() < 1e-12);
        assert_eq!(r.first_line_apart_s, None);
        assert!((r.last_line_apart_s.unwrap() - (7200.0 - 2.03)).abs() < 1e-9);
    }

    #[test]
    fn two_stretches_apart_are_a_gap_of_lost_samples() {
        // The first two lines are a stretch of their own: no line stands apart.
        let mut tags = run(0.0, 2);
        tags.extend(run(10.0, 100));
        let r = account(&tags);
        assert_eq!((r.seq_gaps, r.lost_samples), (1, 998));
        assert_eq!((r.first_line_apart_s, r.last_line_apart_s), (None, None));
        // Long gaps one after the other: the first line stands apart from nothing, the
        // last is apart from the line before it.
        let r = account(&[0.0, 10.0, 20.0, 20.01, 20.02, 40.0]);
        assert_eq!(r.seq_gaps, 2);
        assert_eq!(r.lost_samples, 999 + 999);
        assert_eq!(r.first_line_apart_s, None);
        assert!((r.last_line_apart_s.unwrap() - 19.98).abs() < 1e-9);
    }

    #[test]
    fn a_log_of_two_lines_has_its_gap_counted() {
        let r = account(&[0.0, 10.0]);
        assert_eq!((r.seq_gaps, r.lost_samples), (1, 999));
        assert_eq!((r.first_line_apart_s, r.last_line_apart_s), (None, None));
        // Nothing bridged beyond infinity: every gap is lost samples.
        let mut report = IngestReport::default();
        let mut gaps = GapAccount::new(f64::INFINITY);
        gaps.interval(&mut report, 3600.0, Some((359_999, 0.01)));
        gaps.interval(&mut report, 0.01, None);
        gaps.end(&mut report);
        assert_eq!(report.lost_samples, 359_999);
        assert_eq!(report.first_line_apart_s, None);
    }
}
