//! A clock of a text log's slots: which slot of the sample period each line's tag falls
//! in, when the logger stamped its lines as they came.
//!
//! The IMU integrates over its own clock's periods, while a logger's tags jitter about
//! them. A text log has no sequence numbers, so its lines are told by their slots: a line
//! within half a period of the slot after the last line's is one sample over one period,
//! and one that moved on by n slots closes a gap of n − 1 samples lost. The clock
//! follows the tags (a second-order loop: the slots' phase and their period), so that
//! each line is judged against where its slot is, not against the last line's jittering
//! tag: a line 0.4 of a period early after one 0.4 late is one slot on, where their
//! interval, 0.2 of a period, read as a clock set back, and one 0.4 late after one 0.4
//! early, 1.8 periods, as a line lost.

/// How far the clock's phase moves toward each tag, of the tag's offset from its slot.
pub const SLOT_PHASE_GAIN: f64 = 1.0 / 16.0;

/// How far the clock's period moves, of a tag's offset from its slot per slot it moved
/// on. With [`SLOT_PHASE_GAIN`], a loop damped at ζ = g₁ / (2 √g₂) ≈ 0.7 that settles
/// over about 30 lines (1 / (ζ √g₂)): a period given 2 % off (a median of the first
/// intervals of a log jittering by 0.3 of a period) is taken up without a line counted
/// in the wrong slot, and no period error leaves the clock behind. Simulated over
/// 50 000 lines: tags jittering uniformly by up to 0.3 of a period about their slots are
/// each counted in theirs (the clock within 0.16 of a period of them, 0.053 at 0.1); at
/// 0.4, about one line in 200 is not.
pub const SLOT_PERIOD_GAIN: f64 = 1.0 / 512.0;

/// The most the clock's period moves from the one given, of it: a tag stream it cannot
/// follow (a damaged log) never takes it far.
const MAX_PERIOD_CHANGE: f64 = 1.0 / 8.0;

/// The most slots a line may move on for the clock to follow it: across more, an offset
/// from the slot is lost in the interval's rounding (a leap of 9e9 s over 0.5-ns periods
/// is 1.8e19 of them, its offset to a microsecond), and the clock takes the line's phase
/// afresh.
const MAX_FOLLOWED_SLOTS: f64 = (1u64 << 20) as f64;

/// Where the last line's slot is, as its tag's lateness from it, and the slots' period as
/// the tags keep it, as a correction to the one given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlotClock {
    /// The period given, s.
    given_period_s: f64,
    /// The last tag's time less its slot's, s.
    late_s: f64,
    /// The slots' period less the one given, s.
    period_change_s: f64,
}

impl SlotClock {
    /// A clock of slots `period_s` apart whose first line's tag is `late_s` after its
    /// slot.
    pub fn new(period_s: f64, late_s: f64) -> Self {
        Self {
            given_period_s: period_s,
            late_s,
            period_change_s: 0.0,
        }
    }

    /// The last line's slot's time, its tag being `t_s`.
    pub fn slot_of(&self, t_s: f64) -> f64 {
        t_s - self.late_s
    }

    /// The slots' period as the tags keep it, s.
    pub fn period_s(&self) -> f64 {
        self.given_period_s + self.period_change_s
    }

    /// The slots a line tagged `interval_s` after the last one moved on: at least one (a line stands for itself). A line that did not move
    /// on by half a period from the last slot (its tag going back, repeated, or the clock
    /// set back beyond what the reader takes out) is one slot on, and the clock takes its
    /// phase afresh from it; so it does from a line more than 2^20 slots on.
    pub fn step(&mut self, interval_s: f64) -> u64 {
        let p = self.period_s();
        let from_slot_s = interval_s + self.late_s;
        let slots = (from_slot_s / p).round();
        if slots > MAX_FOLLOWED_SLOTS {
            self.late_s = 0.0;
            // `as` saturates: a tag leapt beyond counting is a gap of u64::MAX slots.
            slots as u64
        } else if slots >= 1.0 {
            let off_s = from_slot_s - slots * p;
            let limit_s = MAX_PERIOD_CHANGE * self.given_period_s.abs();
            self.period_change_s =
                (self.period_change_s + SLOT_PERIOD_GAIN * off_s / slots).clamp(-limit_s, limit_s);
            self.late_s = off_s * (1.0 - SLOT_PHASE_GAIN);
            slots as u64
        } else {
            self.late_s = 0.0;
            1
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lines jittering by up to 0.45 of a period about their slots, each a slot on from
    /// the last, are one slot each; lines lost are counted as slots; a tag going back is
    /// one slot, the clock taken afresh from it.
    #[test]
    fn jittering_lines_are_a_slot_each_and_lost_ones_counted() {
        let period = 0.01;
        let jitter = [0.0, 0.45, -0.45, 0.4, -0.3, 0.45, -0.45, -0.45, 0.45, 0.0];
        let mut clock = SlotClock::new(period, 0.0);
        let mut prev = 0.0;
        let mut slots = Vec::new();
        for (k, j) in jitter.iter().enumerate().skip(1) {
            let t = (k as f64 + j) * period;
            slots.push(clock.step(t - prev));
            prev = t;
        }
        assert_eq!(slots, [1; 9]);
        // Three lines lost: the next line four slots on, a little late.
        let t = prev + 4.3 * period;
        assert_eq!(clock.step(t - prev), 4);
        assert!((clock.slot_of(t) - (13.0 * period)).abs() < 0.1 * period);
        // A tag going back: one slot, the clock from it.
        assert_eq!(clock.step(-0.05), 1);
        assert_eq!(clock.slot_of(1.0), 1.0);
        // A tag leapt beyond counting.
        assert_eq!(clock.step(1e300), u64::MAX);
    }

    /// 50 000 lines jittering uniformly by up to 0.3 of a period about their slots, one
    /// in twenty after a stretch of one to three lost, the clock given a period 2 % off:
    /// every line is counted in its slot, and the clock stays within 0.2 of a period of
    /// the slots once it has taken up the period (after 300 lines).
    #[test]
    fn a_jitter_of_three_tenths_of_a_period_keeps_every_line_in_its_slot() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(81);
        let period = 0.01;
        let mut clock = SlotClock::new(1.02 * period, 0.0);
        let (mut slot, mut prev_t) = (0u64, 0.0);
        for k in 1..50_000 {
            let lost = if rng.random_bool(0.05) {
                rng.random_range(1..=3)
            } else {
                0
            };
            slot += 1 + lost;
            let t = (slot as f64 + rng.random_range(-0.3..0.3)) * period;
            assert_eq!(clock.step(t - prev_t), 1 + lost, "line {k}");
            if k > 300 {
                let off = (clock.slot_of(t) - slot as f64 * period) / period;
                assert!(off.abs() < 0.2, "line {k}: the clock {off} of a period off");
            }
            prev_t = t;
        }
    }
}
