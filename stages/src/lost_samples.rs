//! How the derive tells the IMU samples that close a stretch of lost ones, how many
//! samples each then stands for (its increments filled over them from the rates either
//! side), and
//! the interval its increments were integrated over.
//!
//! A text log has no sequence numbers: its tags' intervals are the samples' intervals,
//! and a sample whose interval is over 1.5 nominal ones closes a gap of `dt / nominal`
//! samples. A binary log's recorder numbers its samples (`seq`), and its tags, taken as
//! its records come, may jitter while the IMU integrates over its own clock's periods: a
//! sample's interval is its `seq` step times the period, whatever the tags' interval (a
//! tag late by more than half a period, within the jitter the reader's clock allows, is
//! no gap, and gives no rate of its own), and `seq` says how many were lost.

/// A sample whose sequence number stepped by more than one from the sample before.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SeqStep {
    /// The sample (its row in the IMU's table).
    pub sample: usize,
    /// Its `seq` less the one before: the samples lost before it, plus one.
    pub step: u64,
}

/// The rule the derive tells lost samples by.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum LostSamples {
    /// By the tags' intervals (a log without sequence numbers).
    #[default]
    ByInterval,
    /// By the recorder's sequence numbers (a binary log).
    BySeq {
        /// The samples whose `seq` stepped by more than one, in order.
        steps: Vec<SeqStep>,
        /// The longest interval, in nominal ones, a one-step sample's tags span when
        /// the reader's clock kept both (each within its tolerance of its `seq`'s time).
        /// Longer, only a counter reset (which the unwrapped `seq` counts as one step and
        /// which says nothing of the time between) parts them: the interval tells.
        longest_one_step_periods: f64,
    },
}

impl LostSamples {
    /// The sample period, ns, given the tags (ns) and the median of their positive
    /// steps. By the intervals, that median. By `seq`, the tags' mean step per `seq`
    /// step over the log (a counter reset's pause and a first or last tag apart left
    /// out), which the recorder's jitter does not move: a median of jittering steps is
    /// off by about the jitter over the root of the samples' count (1 µs in 10 ms over a
    /// 200-s run with ±2.5 ms of it), and every interval with it.
    pub fn period_ns(&self, tags_ns: &[i64], median_ns: u64) -> u64 {
        let LostSamples::BySeq {
            steps,
            longest_one_step_periods,
        } = self
        else {
            return median_ns;
        };
        let longest_ns = longest_one_step_periods * median_ns as f64;
        let (mut span_ns, mut periods) = (0_i128, 0_u128);
        let mut next = steps.iter().peekable();
        for (k, w) in tags_ns.windows(2).enumerate() {
            let interval_ns = i128::from(w[1]) - i128::from(w[0]);
            while next.next_if(|s| s.sample < k + 1).is_some() {}
            let step = next.next_if(|s| s.sample == k + 1).map_or(1, |s| s.step);
            // An interval beyond a kept tag's (a counter reset's pause; a first or last
            // tag apart) says nothing of the period. Shorter ones, going back or not (a
            // jitter, a tag back the derive repairs), are taken: their sum is the span
            // of the tags about them.
            if beyond_kept(interval_ns as f64, step as f64, longest_ns) {
                continue;
            }
            periods += u128::from(step);
            span_ns += interval_ns;
        }
        if span_ns <= 0 || periods == 0 {
            return median_ns;
        }
        let periods = periods as i128;
        u64::try_from((span_ns + periods / 2) / periods).unwrap_or(median_ns)
    }

    /// What the samples close, in order, sample by sample ([`Scales::of`]).
    pub fn scales(&self) -> Scales<'_> {
        Scales {
            rule: self,
            next: 0,
        }
    }
}

/// What each sample closes, asked in the samples' order.
#[derive(Debug, Clone)]
pub struct Scales<'a> {
    rule: &'a LostSamples,
    /// The next of `BySeq`'s steps not yet reached.
    next: usize,
}

/// What a sample closes, as [`Scales::of`] tells it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closed {
    /// The samples it stands for (the lost ones before it and itself), 1 for a sample
    /// that closes no gap.
    pub samples: f64,
    /// The interval its increments were integrated over, s.
    pub dt_s: f64,
}

impl Scales<'_> {
    /// What sample `k` closes, the interval from the time before it to its time being
    /// `interval_s`. Ask each sample once, in order.
    pub fn of(&mut self, k: usize, interval_s: f64, nominal_dt_s: f64) -> Closed {
        let by_interval = || Closed {
            samples: by_interval(interval_s, nominal_dt_s),
            dt_s: interval_s,
        };
        match self.rule {
            LostSamples::ByInterval => by_interval(),
            LostSamples::BySeq {
                steps,
                longest_one_step_periods,
            } => {
                while steps.get(self.next).is_some_and(|s| s.sample < k) {
                    self.next += 1;
                }
                let samples = match steps.get(self.next) {
                    Some(s) if s.sample == k => s.step as f64,
                    _ if beyond_kept(interval_s, 1.0, longest_one_step_periods * nominal_dt_s) => {
                        return by_interval();
                    }
                    _ => 1.0,
                };
                Closed {
                    samples,
                    dt_s: samples * nominal_dt_s,
                }
            }
        }
    }
}

/// Whether an interval (either way) spans more than two tags the reader's clock kept
/// `steps` of `seq` apart can be, the longest one step apart being `longest_one_step`
/// (in the interval's unit): only a counter reset (or a tag apart at a log's end) parts
/// them so far.
fn beyond_kept(interval: f64, steps: f64, longest_one_step: f64) -> bool {
    interval.abs() > longest_one_step * steps
}

/// The samples a sample stands for when only its interval tells: a sample that closes a
/// gap (an interval `dt_s` over 1.5 nominal ones) stands for `dt_s / nominal_dt_s`, the
/// stretch filled from the rates either side; any other, 1.
pub fn by_interval(dt_s: f64, nominal_dt_s: f64) -> f64 {
    if dt_s > 1.5 * nominal_dt_s {
        dt_s / nominal_dt_s
    } else {
        1.0
    }
}

/// [`SeqStep`]s of a table's `seq` column, read a batch at a time.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SeqSteps {
    /// The last `seq` read.
    last: Option<u64>,
    /// Rows read.
    rows: usize,
    steps: Vec<SeqStep>,
}

impl SeqSteps {
    /// Reads the next rows' sequence numbers.
    pub fn extend(&mut self, seq: impl IntoIterator<Item = u64>) {
        for s in seq {
            if let Some(step) = self.last.map(|last| s.wrapping_sub(last))
                && step > 1
            {
                self.steps.push(SeqStep {
                    sample: self.rows,
                    step,
                });
            }
            self.last = Some(s);
            self.rows += 1;
        }
    }

    /// The steps over one, in order.
    pub fn finish(self) -> Vec<SeqStep> {
        self.steps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The steps over one are listed at their rows, across batches; the first row and
    /// steps of one are not.
    #[test]
    fn seq_steps_list_the_rows_after_lost_samples() {
        let mut steps = SeqSteps::default();
        steps.extend([7, 8, 11]);
        steps.extend([12, 14]);
        steps.extend([]);
        steps.extend([15]);
        assert_eq!(
            steps.finish(),
            [
                SeqStep { sample: 2, step: 3 },
                SeqStep { sample: 4, step: 2 }
            ]
        );
    }

    /// By the interval, a sample late by 0.8 of a period is a gap of 1.8 samples; by
    /// `seq`, it is none and its interval the period, and a step of 3 is 3 samples and 3
    /// periods whatever its interval. A one-step interval longer than a kept tag could be
    /// (a counter reset's pause) is told by the interval.
    #[test]
    fn seq_tells_a_late_tag_from_lost_samples() {
        let nominal = 0.01;
        assert!((by_interval(0.018, nominal) - 1.8).abs() < 1e-12);
        assert_eq!(by_interval(0.015, nominal), 1.0);
        let rule = LostSamples::BySeq {
            steps: vec![
                SeqStep { sample: 3, step: 3 },
                SeqStep { sample: 9, step: 2 },
            ],
            longest_one_step_periods: 21.0,
        };
        let mut scales = rule.scales();
        let got: Vec<(f64, f64)> = [(1, 0.018), (3, 0.0285), (5, 0.5), (6, 0.004), (9, 0.012)]
            .into_iter()
            .map(|(k, dt)| scales.of(k, dt, nominal))
            .map(|c| (c.samples, c.dt_s))
            .collect();
        assert_eq!(
            got,
            [
                (1.0, 0.01),
                (3.0, 0.03),
                (0.5 / nominal, 0.5),
                (1.0, 0.01),
                (2.0, 0.02)
            ]
        );
        let mut scales = LostSamples::ByInterval.scales();
        let c = scales.of(1, 0.018, nominal);
        assert!((c.samples - 1.8).abs() < 1e-12 && c.dt_s == 0.018, "{c:?}");
    }

    /// By `seq`, the period is the tags' mean step per `seq` step: a jitter about it, a
    /// stretch of lost samples (3 steps), a counter reset's pause and a first tag that
    /// leapt 1 s forward (both left out) do not move it, where the jittering steps'
    /// median does; by the intervals, the median.
    #[test]
    fn seq_takes_the_period_as_the_tags_mean_step() {
        // (The tags beside the pause, whose step is left out, and at the ends on time:
        // what the mean is taken over telescopes to their span.)
        let jitter_ns = [0, 0, -1_700_000, 2_100_000, 0, 0, 0];
        let mut tags: Vec<i64> = (0..7)
            .map(|k| k * 10_000_000 + jitter_ns[k as usize])
            .collect();
        // Samples 3 and 4 lost before the fifth; a reset's half-second pause before the
        // sixth, then one more step.
        for t in &mut tags[4..] {
            *t += 20_000_000;
        }
        for t in &mut tags[5..] {
            *t += 500_000_000;
        }
        let rule = LostSamples::BySeq {
            steps: vec![SeqStep { sample: 4, step: 3 }],
            longest_one_step_periods: 21.0,
        };
        let mut steps: Vec<i64> = tags.windows(2).map(|w| w[1] - w[0]).collect();
        steps.sort_unstable();
        let median_ns = steps[steps.len() / 2] as u64;
        assert_ne!(median_ns, 10_000_000);
        assert_eq!(rule.period_ns(&tags, median_ns), 10_000_000);
        assert_eq!(
            LostSamples::ByInterval.period_ns(&tags, median_ns),
            median_ns
        );
        let mut first_leapt = tags.clone();
        first_leapt[0] += 1_000_000_000;
        assert_eq!(rule.period_ns(&first_leapt, median_ns), 10_000_000);
    }

    proptest::proptest! {
        /// Any recorder jittering by up to 40 % of a 10-ms period, losing stretches of up
        /// to 5 samples now and then: the period by `seq` is within the two ends' jitter
        /// over the log's periods of the true one, and the samples' intervals sum to the
        /// periods `seq` counts, each the period times its step; the late tags fill no gap.
        #[test]
        fn a_jittering_recorder_with_lost_stretches_keeps_its_period(
            jitter_ns in proptest::collection::vec(-4_000_000_i64..=4_000_000, 50..400),
            lost in proptest::collection::vec(0_u64..=5, 50..400),
        ) {
            const PERIOD_NS: i64 = 10_000_000;
            let n = jitter_ns.len().min(lost.len());
            let mut seq = 0_u64;
            let (mut tags, mut seqs) = (Vec::with_capacity(n), Vec::with_capacity(n));
            for k in 0..n {
                // A stretch lost before one sample in seven.
                if k > 0 && k % 7 == 0 {
                    seq += lost[k];
                }
                tags.push(seq as i64 * PERIOD_NS + jitter_ns[k]);
                seqs.push(seq);
                seq += 1;
            }
            let mut steps = SeqSteps::default();
            steps.extend(seqs.iter().copied());
            let rule = LostSamples::BySeq {
                steps: steps.finish(),
                longest_one_step_periods: 21.0,
            };
            let mut sorted: Vec<i64> = tags.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > 0).collect();
            sorted.sort_unstable();
            let median_ns = sorted[sorted.len() / 2] as u64;
            let period_ns = rule.period_ns(&tags, median_ns) as i64;
            let spans = (seqs[n - 1] - seqs[0]) as i64;
            proptest::prop_assert!(
                (period_ns - PERIOD_NS).abs() <= 8_000_000 / spans + 1,
                "period {period_ns} ns over {spans} periods"
            );
            let nominal_s = period_ns as f64 * 1e-9;
            let mut scales = rule.scales();
            let mut samples = 0.0;
            for k in 1..n {
                let interval_s = (tags[k] - tags[k - 1]) as f64 * 1e-9;
                let c = scales.of(k, interval_s, nominal_s);
                let step = (seqs[k] - seqs[k - 1]) as f64;
                proptest::prop_assert_eq!(c.samples, step);
                proptest::prop_assert!((c.dt_s - step * nominal_s).abs() <= 1e-15);
                samples += c.samples;
            }
            proptest::prop_assert_eq!(samples, spans as f64);
        }
    }
}
