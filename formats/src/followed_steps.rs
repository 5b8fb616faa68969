//! A separate odometer file written on a text log's clock (one logger stamping both
//! files), when that clock was set back or forward while it logged: the file's tags are
//! moved by the steps the log's were ([`IngestReport::text_clock_steps`]), each where the
//! file's own tags show it.
//!
//! The log's steps are taken out of its time base by the reader ([`crate::kfgins`]), and
//! a separate file is taken on the log's clock at its start. Left as written, a file on
//! the stepped clock runs late or early of the IMU by the steps after each: a clock set
//! back failed the derive as an odometer on another clock, and one set forward by 0.44
//! s near the end of Kingston's drive moved OWPI's azimuth by 0.2°. A file on a clock of
//! its own (the odometer's device stamping its readings) shows no step and is left as
//! written. Its interval across the step tells: the step's length off its interval
//! before (a clock set forward lengthens it, one set back shortens it), and nearer that
//! than its interval before.
//!
//! [`IngestReport::text_clock_steps`]: crate::IngestReport::text_clock_steps

use crate::report::TextClockStep;

/// The longest step followed, s: across a longer one set back, the file's lines going
/// back are rejected while its speeds' gaps are found (before the log's steps are known),
/// and could read as a gap of a few seconds; up to it, a file's interval across a step
/// (its period and the step) is no gap (one is longer than 3 s and three of its recent
/// intervals). A longer step is left as written: the derive's clock check names it.
pub const MAX_FOLLOWED_STEP_S: f64 = 2.0;

/// A separate odometer file's tags as written, moved by the log's clock steps its tags
/// show.
#[derive(Debug, Clone)]
pub struct FollowedSteps {
    /// The log's steps, in order.
    steps: Vec<TextClockStep>,
    /// The first step not yet passed.
    next: usize,
    /// What the steps followed add to the tags, s.
    shift_s: f64,
    /// The last tag, as written, s.
    last_s: Option<f64>,
    /// The interval before it, s.
    last_interval_s: Option<f64>,
    /// Steps the file's tags showed, followed.
    followed: u64,
    /// Steps they did not (or could not, at the file's start), left.
    not_shown: u64,
}

impl FollowedSteps {
    /// Follows `steps` (the log's, in order; longer than [`MAX_FOLLOWED_STEP_S`] never).
    pub fn new(steps: &[TextClockStep]) -> Self {
        Self {
            steps: steps.to_vec(),
            next: 0,
            shift_s: 0.0,
            last_s: None,
            last_interval_s: None,
            followed: 0,
            not_shown: 0,
        }
    }

    /// The file's next tag as written, `tag_s`, on the log's clock at its start: moved by
    /// the steps followed up to it. Tags must come in the file's order.
    pub fn time_s(&mut self, tag_s: f64) -> f64 {
        while let Some(step) = self.steps.get(self.next)
            && self.is_past(step, tag_s)
        {
            self.next += 1;
            let shown = self.shows(step, tag_s);
            if shown {
                self.shift_s += step.step_s;
                self.followed += 1;
            } else {
                self.not_shown += 1;
            }
        }
        if let Some(last_s) = self.last_s {
            self.last_interval_s = Some(tag_s - last_s);
        }
        self.last_s = Some(tag_s);
        tag_s + self.shift_s
    }

    /// Whether a tag `tag_s` of the file, after its last, was written after `step`: past
    /// the middle of the log's tags either side of a step forward; for a step back, past
    /// the log's slot after it (on the clock before) or going back from the file's last
    /// tag no earlier than the log's tag before the step less the step (a file's own tag
    /// going back long before is its own, and rejected).
    fn is_past(&self, step: &TextClockStep, tag_s: f64) -> bool {
        if step.step_s < 0.0 {
            tag_s >= 0.5 * (step.tag_before_s + step.tag_s)
        } else {
            let went_back = self
                .last_s
                .is_some_and(|last_s| tag_s < last_s && tag_s >= step.tag_before_s - step.step_s);
            went_back || tag_s >= step.tag_s + step.step_s
        }
    }

    /// Whether the file's interval to `tag_s` across `step` shows it: nearer its interval
    /// before less the step (longer by a clock set forward, shorter by one set back) than
    /// its interval before, and within half the step of it; never at the file's start, or
    /// for a step longer than [`MAX_FOLLOWED_STEP_S`].
    fn shows(&self, step: &TextClockStep, tag_s: f64) -> bool {
        let (Some(last_s), Some(before_s)) = (self.last_s, self.last_interval_s) else {
            return false;
        };
        let interval_s = tag_s - last_s;
        let stepped_s = before_s - step.step_s;
        let off_s = (interval_s - stepped_s).abs();
        step.step_s.abs() <= MAX_FOLLOWED_STEP_S
            && off_s < (interval_s - before_s).abs()
            && off_s < 0.5 * step.step_s.abs()
    }

    /// Steps the file's tags showed, followed.
    pub fn followed(&self) -> u64 {
        self.followed
    }

    /// Steps the file's tags passed without showing them, left.
    pub fn not_shown(&self) -> u64 {
        self.not_shown
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step at the log's line tagged `tag_s` as written (the line before at
    /// `tag_before_s`), adding `step_s` to the tags after it.
    fn step(tag_before_s: f64, tag_s: f64, step_s: f64) -> TextClockStep {
        TextClockStep {
            line: 1,
            step_s,
            tag_s,
            tag_before_s,
        }
    }

    /// A 1-Hz file whose clock was set forward by 0.437 s and back by 1.5 s as the
    /// log's (a 10-Hz log's lines either side): its tags after each are moved back on
    /// the log's clock at its start.
    #[test]
    fn a_file_on_the_stepped_clock_follows_each_step() {
        let steps = [step(100.25, 100.787, -0.437), step(200.687, 199.287, 1.5)];
        let mut f = FollowedSteps::new(&steps);
        // True times 95..=300 s at 1 Hz; written: +0.437 from 100.3 s, −1.5 more from
        // 200.3 s (the log's step instants).
        let written =
            |t: f64| t + if t >= 100.3 { 0.437 } else { 0.0 } - if t >= 200.3 { 1.5 } else { 0.0 };
        for t in 95..=300 {
            let t = t as f64;
            let got = f.time_s(written(t));
            assert!((got - t).abs() < 1e-9, "{t}: {got}");
        }
        assert_eq!((f.followed(), f.not_shown()), (2, 0));
    }

    /// A file on a clock of its own (its tags regular through the log's steps), and one
    /// beginning after a step: left as written.
    #[test]
    fn a_file_on_its_own_clock_is_left_as_written() {
        let steps = [step(100.25, 100.787, -0.437), step(200.687, 199.287, 1.5)];
        let mut f = FollowedSteps::new(&steps);
        for t in 95..=300 {
            let t = t as f64 + 0.5;
            assert_eq!(f.time_s(t), t);
        }
        assert_eq!((f.followed(), f.not_shown()), (0, 2));
        let mut late = FollowedSteps::new(&steps[..1]);
        assert_eq!(late.time_s(150.437), 150.437);
        assert_eq!((late.followed(), late.not_shown()), (0, 1));
    }

    /// A step longer than [`MAX_FOLLOWED_STEP_S`] is left, shown or not.
    #[test]
    fn a_long_step_is_left() {
        let mut f = FollowedSteps::new(&[step(100.0, 97.1, 3.0)]);
        for t in [98.0, 99.0, 100.0, 98.5, 99.5] {
            assert_eq!(f.time_s(t), t);
        }
        assert_eq!((f.followed(), f.not_shown()), (0, 1));
    }
}
