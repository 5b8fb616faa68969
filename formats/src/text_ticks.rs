//! Text lines stamped by a coarse clock: a logger whose clock ticks more slowly than the
//! IMU samples (a PC's 15.625-ms timer under a 100-Hz IMU, or tags printed to 0.01 s
//! for a 125-Hz one) gives the lines made within one tick its tag, and the next tick's
//! lines the next: tags alike or a tick apart, each up to a tick before its sample's
//! time. Read as written, the tick was taken for the sample period (the median of the
//! steps) and the lines sharing a tag for the clock set back: Kingston (10 Hz) stamped
//! by a 156.25-ms clock read as its clock set back 3153 times, and the derive failed on
//! accelerometers "not in m/s".
//!
//! Such tags are a regular clock's slots read through the tick: a line's sample was made
//! within the tick from its tag on. `TickRetime` gives each line its slot's time on a
//! clock that follows the tags: the first slot after the last line's that falls within
//! the line's tick (slots passed over are lines lost, which the reader's slot clock then
//! counts), the clock's phase and period moved toward the tick's middle by a
//! second-order loop, as the slot clock's, with smaller gains (the tick is a jitter of
//! half a tick either side of it).
//!
//! A line lost shows where a tick holds no slot after the line before's; where among
//! the lines before it the sample was lost their ticks may not tell (two lines to a
//! tick), and the gap is put halfway along the lines it could follow.
//!
//! A coarse clock is told from the log's first lines (`coarse_tick`): every step a whole
//! number of ticks, tags shared by lines of different values, a stretch with no line
//! lost whose ticks' middles lie within a tick of one straight line through the lines'
//! count, and from it every first line's slot, 99 in 100 of their middles within a tick
//! of the line through the slots, at a period shorter than the tick. A clock standing
//! or a stall's burst parts lines from any such line; a regular log's lines do not share
//! tags, nor does a log whose tags glitch or whose lines are lost fit a period shorter
//! than its step. A tick of whole periods is the burst layer's (`crate::text_bursts`)
//! when its first lines come in bursts.
//!
//! A tick shorter than the period (a 15.625-ms timer under a 50-Hz IMU) shares no tag:
//! its steps of one tick and of two are the tags a regular log losing lines writes, but
//! in a regular proportion. Such a log is judged over 1000 first lines or more
//! and from a stretch of 256 lines at least, at a period longer than the tick by 2 % to
//! twice it: lines lost at random wander from any straight line by their count's own
//! wandering. A log losing lines as regularly (one line in ten, say) writes the same
//! tags, a tick of `T` at a period of `T k / (k − 1)`: the tags cannot tell the two
//! apart, but the lines' velocity increments can. Each spans its sample's interval, so
//! their sum over the lines judged, over their count and gravity, is the interval
//! (within a percent or two of it when the vehicle drives, its accelerations and turns
//! added): where it is the tick's to a quarter of the way to the period, the log is
//! read as losing lines at a period of the tick ([`TextRegularLoss`]).

use std::collections::VecDeque;

use crate::error::FormatError;
use crate::kfgins::TextSample;
use crate::text_bursts::repeats;

/// Lines a stretch the clock is fitted on holds, at most.
const FIT_LINES: usize = 512;
/// Fewest lines a stretch the clock is fitted on holds.
const MIN_FIT_LINES: usize = 64;
/// Fewest first lines judged for a tick shorter than the period: a regular log's lines
/// lost at random, read through such a tick, wander from its line by their count's own
/// wandering, about two periods over 1000 lines at one lost in 50 (the fewest that read
/// a period 2 % past the tick, [`MIN_TICK_PERIODS`]).
const FINER_LINES: usize = 1000;
/// Fewest tags shared by lines of different values (or steps of two ticks or more) among
/// the first lines for the log to be judged on a coarse clock.
pub(crate) const MIN_SHARED_TAGS: usize = 2;
/// How far a step may be off a whole number of ticks, of a tick (a tick printed to a
/// coarser unit: 15.625 ms in whole milliseconds, steps of 15 and 16).
const TICK_TOLERANCE: f64 = 0.1;
/// How near the tick the span of the lines' velocity increments must lie, of the way
/// from it to the period fitted, for a log whose steps read as a tick finer than its
/// period to be read as losing lines regularly at a period of the tick: a quarter,
/// where an IMU's scale error and a drive's accelerations move the span by a percent
/// or two, and the nearest such tick (one line lost in fifty) is 2 % off the period.
const REGULAR_LOSS_SHARE: f64 = 0.25;
/// Standard gravity, m/s²: the size of the lines' velocity increments' sum over their
/// count and this is the span of each line's increments, s.
const GRAVITY_MPS2: f64 = 9.806_65;
/// The shortest tick, in periods, read as a coarse clock's: a regular log whose tags
/// glitched, a line's tag repeating the one before, fits the line through its lines'
/// count at a period within a few thousandths of its step.
const MIN_TICK_PERIODS: f64 = 1.02;
/// How far beyond the tick a line's slot may lie, of a period, at least (the clock's own
/// error as it follows the tags): more by half what the lines' tags spread beyond a tick
/// about their line ([`tolerance`]), the jitter of a logger that stamps its lines as
/// they come.
const SLOT_TOLERANCE: f64 = 0.25;
/// The margin over half that spread, of a period.
const SPREAD_MARGIN: f64 = 0.15;
/// How far the clock's phase moves toward each line's tick middle, of its offset.
const PHASE_GAIN: f64 = 1.0 / 64.0;
/// How far the clock's period moves, of that offset per slot (with [`PHASE_GAIN`], a
/// loop damped at ζ ≈ 0.7 that settles over about 128 lines).
const PERIOD_GAIN: f64 = 1.0 / 8192.0;
/// The most the clock's period moves from the one fitted, of it.
const MAX_PERIOD_CHANGE: f64 = 1.0 / 64.0;
/// Slots a line may move on for the clock to keep its phase: beyond (or a line earlier
/// than its slot by more than a tick and a period: the clock set back), it takes the
/// line's tick middle afresh.
const MAX_FOLLOWED_SLOTS: f64 = (1u64 << 20) as f64;

/// Whether `lines` step as a clock's ticks of about their period do: their steps whole
/// ticks ([`tick_grid`]), [`MIN_SHARED_TAGS`] or more of them of none (lines sharing a
/// tag) or of two ticks or more. What makes the reader read further to judge them
/// ([`coarse_tick`]).
pub(crate) fn may_be_ticked(lines: &[TextSample]) -> bool {
    tick_grid(&written_tags_s(lines))
        .is_some_and(|g| g.shared >= MIN_SHARED_TAGS || g.skipping >= MIN_SHARED_TAGS)
}

/// `lines`, a line repeating the one before (its tag and values) left out.
fn written(lines: &[TextSample]) -> impl Iterator<Item = &TextSample> {
    (lines.iter().enumerate())
        .filter(|&(i, s)| i == 0 || !(s.t_s == lines[i - 1].t_s && repeats(&lines[i - 1], s)))
        .map(|(_, s)| s)
}

/// The tags of `lines`, a line repeating the one before left out ([`written`]).
fn written_tags_s(lines: &[TextSample]) -> Vec<f64> {
    written(lines).map(|s| s.t_s).collect()
}

/// The steps of tags on a clock's ticks.
#[derive(Debug, Clone, Copy)]
struct TickGrid {
    tick_s: f64,
    /// Steps of none (lines sharing a tag), and of two ticks or more.
    shared: usize,
    skipping: usize,
    steps: usize,
}

/// The ticks `tags_s` step by, when every step in fifty but one is a whole number of
/// ticks to [`TICK_TOLERANCE`] of one: roughly the mean of the steps within that
/// tolerance of the tenth shortest step in ten, then the steps on the grid over the
/// ticks they make.
fn tick_grid(tags_s: &[f64]) -> Option<TickGrid> {
    let steps: Vec<f64> = tags_s.windows(2).map(|w| w[1] - w[0]).collect();
    let mut positive: Vec<f64> = steps.iter().copied().filter(|&d| d > 0.0).collect();
    if positive.is_empty() {
        return None;
    }
    positive.sort_by(f64::total_cmp);
    let shortest_s = positive[positive.len() / 10];
    let near: Vec<f64> = (positive.iter().copied())
        .filter(|d| (d - shortest_s).abs() <= TICK_TOLERANCE * shortest_s)
        .collect();
    let rough_s = near.iter().sum::<f64>() / near.len() as f64;
    let (mut on_grid, mut shared, mut skipping) = (0, 0, 0);
    let (mut span_s, mut ticks_in_span) = (0.0, 0.0);
    for &d in &steps {
        let ticks = d / rough_s;
        if ticks > -TICK_TOLERANCE && (ticks - ticks.round()).abs() <= TICK_TOLERANCE {
            on_grid += 1;
            shared += usize::from(d == 0.0);
            skipping += usize::from(ticks.round() >= 2.0);
            span_s += d;
            ticks_in_span += ticks.round();
        }
    }
    // The steps on the grid over the ticks they make: a tick printed to a coarser unit
    // (78.125 ms in whole milliseconds, steps of 78 and 79 and of 156 and 157) to a
    // thousandth of that unit over 1000 lines, where the steps of one tick alone gave
    // 78.111 ms.
    let tick_s = span_s / ticks_in_span;
    (tick_s.is_finite() && tick_s > 0.0 && 50 * (steps.len() - on_grid) <= steps.len()).then_some(
        TickGrid {
            tick_s,
            shared,
            skipping,
            steps: steps.len(),
        },
    )
}

/// A coarse clock's tick and the slots of the lines it stamped, as its stretch of lines
/// gives them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TickFit {
    /// The clock's tick, s.
    pub tick_s: f64,
    /// The samples' period, s.
    pub period_s: f64,
    /// The first of the log's lines judged, and its slot's time, s: the stretch's line
    /// through its ticks' middles, taken back over the lines before it.
    pub first_slot_s: f64,
    /// How far beyond its tick a line's slot may lie, of a period ([`tolerance`]).
    pub tolerance: f64,
}

/// How far beyond its tick a line's slot may lie, of a period, for lines whose ticks'
/// middles spread `spread_s` about their line: [`SLOT_TOLERANCE`], or half their spread
/// beyond a tick and [`SPREAD_MARGIN`] where more (a logger's jitter under its tick:
/// Kingston's 40-minute 100-Hz log, jittering by 0.4 of a period, on a 15.625-ms clock
/// read 4058 lines lost at a quarter).
fn tolerance(spread_s: f64, tick_s: f64, period_s: f64) -> f64 {
    SLOT_TOLERANCE.max((spread_s - tick_s) / (2.0 * period_s) + SPREAD_MARGIN)
}

/// The least-squares line through lines' ticks' middles against their slots
/// ([`fitted_line`]).
#[derive(Debug, Clone, Copy)]
struct FittedLine {
    period_s: f64,
    /// The first line's slot time, s.
    first_slot_s: f64,
    /// How far the middles spread about the line (the share asked of them), s.
    spread_s: f64,
}

/// The coarse clock `lines` (the log's first, as written) were stamped by, or `None`.
///
/// The tick is the mean of the steps within [`TICK_TOLERANCE`] of the tenth shortest
/// step in ten; every step in fifty but one must be a whole number of ticks to that
/// tolerance, and lines must share tags ([`MIN_SHARED_TAGS`]). A stretch with no line
/// lost then seeds the clock ([`seed`]), which walks from its first line to the last of
/// `lines` and back to the first ([`TickClock`]), giving each line its slot (lines lost
/// between); the period and the first line's slot are the least-squares line through
/// the ticks' middles against the slots, which 99 lines in 100 must lie within a tick and
/// a quarter period of (a stall, a clock standing, lines lost beyond the clock's
/// following part the rest from it). The period must be shorter than the tick by
/// [`MIN_TICK_PERIODS`]. A tick finer than the period is read as lines lost regularly
/// instead when the lines' velocity increments span the tick ([`regular_loss`]).
pub(crate) fn coarse_tick(lines: &[TextSample]) -> Option<TickReading> {
    let tags_s = written_tags_s(lines);
    let grid = tick_grid(&tags_s)?;
    let tick_s = grid.tick_s;
    // Lines sharing tags: a tick longer than the period. Else steps of one tick and of
    // two, in the proportion a tick shorter than the period gives, not a few lines lost.
    let finer = if grid.shared >= MIN_SHARED_TAGS {
        false
    } else if grid.skipping >= MIN_SHARED_TAGS && 50 * grid.skipping >= grid.steps {
        true
    } else {
        return None;
    };
    if tags_s.len() < if finer { FINER_LINES } else { MIN_FIT_LINES } {
        return None;
    }
    let (from, seeded) = seed(&tags_s, tick_s, finer)?;
    let (period_s, slot_s) = (seeded.period_s, seeded.first_slot_s);
    let walk_tolerance = tolerance(seeded.spread_s, tick_s, period_s);
    // Each line's slot from the seed's first line's: forward as the tags go, backward on
    // the tags negated (a tick [t, t + tick) is (−t − tick, −t] there).
    let mut slots = vec![0.0; tags_s.len()];
    let mut clock = TickClock::new(tick_s, period_s, slot_s - period_s, walk_tolerance);
    let mut n = -1.0;
    for i in from..tags_s.len() {
        n += clock.step(tags_s[i]).slots?;
        slots[i] = n;
    }
    let mut clock = TickClock::new(tick_s, period_s, -slot_s, walk_tolerance);
    let mut n = 0.0;
    for i in (0..from).rev() {
        n -= clock.step(-tags_s[i] - tick_s).slots?;
        slots[i] = n;
    }
    let line = fitted_line(&tags_s, &slots, tick_s, 0.99, finer)?;
    if finer && let Some(loss) = regular_loss(lines, tick_s, line.period_s) {
        return Some(TickReading::LinesLost(loss));
    }
    Some(TickReading::Clock(TickFit {
        tick_s,
        period_s: line.period_s,
        first_slot_s: line.first_slot_s,
        tolerance: walk_tolerance.max(tolerance(line.spread_s, tick_s, line.period_s)),
    }))
}

/// What a log's first lines' tags read as ([`coarse_tick`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum TickReading {
    /// A coarse clock's ticks over regular slots.
    Clock(TickFit),
    /// Lines lost regularly at a period of the tick, as their velocity increments tell.
    LinesLost(TextRegularLoss),
}

/// A log whose steps of one period and of two came as regularly as a finer clock's
/// ticks, read as losing lines because its velocity increments span one step
/// (`ingest.json`'s `text_regular_loss`; [`crate::text_ticks`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TextRegularLoss {
    /// The samples' period: the step of one, s.
    pub period_s: f64,
    /// The period a clock ticking at the step would have had, the lines' slots fitted
    /// through the tags, s.
    pub clock_period_s: f64,
    /// What each line's velocity increments span, by gravity, s.
    pub increments_span_s: f64,
    /// Lines judged.
    pub lines: u64,
}

impl TextRegularLoss {
    /// One line lost in this many (the clock's period over what it is past the step's).
    pub fn one_in(&self) -> f64 {
        self.clock_period_s / (self.clock_period_s - self.period_s)
    }
}

/// The lines' regular loss when their velocity increments span the tick `tick_s`, not the
/// period `period_s` a clock ticking finer than it would give: the span (the size of
/// their sum over their count and gravity, a line repeating the one before left out)
/// within [`REGULAR_LOSS_SHARE`] of the way from the tick to the period.
fn regular_loss(lines: &[TextSample], tick_s: f64, period_s: f64) -> Option<TextRegularLoss> {
    let mut sum = [0.0f64; 3];
    let mut count = 0u64;
    for s in written(lines) {
        for (a, v) in sum.iter_mut().zip(s.dvel_mps) {
            *a += v;
        }
        count += 1;
    }
    let span_s = (sum[0].hypot(sum[1]).hypot(sum[2])) / (count as f64 * GRAVITY_MPS2);
    ((span_s - tick_s).abs() <= REGULAR_LOSS_SHARE * (period_s - tick_s)).then_some(
        TextRegularLoss {
            period_s: tick_s,
            clock_period_s: period_s,
            increments_span_s: span_s,
            lines: count,
        },
    )
}

/// The first stretch of `tags_s` with no line lost that fits a coarse clock of tick
/// `tick_s`: its first line, the period and that line's slot time, s. Stretches of
/// [`FIT_LINES`] are tried first, then of half as many, down to [`MIN_FIT_LINES`], each
/// length's half a stretch apart: a log that loses a line in a hundred has few of 512
/// lines without one. A tick `finer` than the period takes a stretch of half as many at
/// least (its steps of two ticks are a regular log's lines lost but for their
/// regularity, which long stretches show: lost at random, the lines' middles wander from
/// any line by the lost lines' count's own wandering, and the walk over
/// [`FINER_LINES`] or more parts them).
fn seed(tags_s: &[f64], tick_s: f64, finer: bool) -> Option<(usize, FittedLine)> {
    let mut len = FIT_LINES;
    let shortest = if finer { FIT_LINES / 2 } else { MIN_FIT_LINES };
    while len >= shortest {
        let len_here = len.min(tags_s.len());
        let mut from = 0;
        while from + len_here <= tags_s.len() {
            let stretch = &tags_s[from..from + len_here];
            let count: Vec<f64> = (0..len_here).map(|i| i as f64).collect();
            if let Some(line) = fitted_line(stretch, &count, tick_s, 1.0, finer) {
                return Some((from, line));
            }
            from += len_here / 2;
        }
        len /= 2;
    }
    None
}

/// The least-squares line through the ticks' middles of lines tagged `tags_s` against
/// their `slots`: the period and the first line's slot time, s, when the share `within`
/// of the middles lie within a tick and half a period of the line's others, and the
/// period is shorter than the tick by [`MIN_TICK_PERIODS`] (or, a tick `finer` than the
/// period, longer by as much and shorter than two ticks).
fn fitted_line(
    tags_s: &[f64],
    slots: &[f64],
    tick_s: f64,
    within: f64,
    finer: bool,
) -> Option<FittedLine> {
    let n = tags_s.len() as f64;
    let t0_s = tags_s[0];
    let at = |i: usize| tags_s[i] - t0_s + tick_s / 2.0;
    let mean_x = slots.iter().sum::<f64>() / n;
    let mean_t = (0..tags_s.len()).map(at).sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, &x) in slots.iter().enumerate() {
        sxy += (x - mean_x) * (at(i) - mean_t);
        sxx += (x - mean_x) * (x - mean_x);
    }
    let period_s = sxy / sxx;
    let mut offs: Vec<f64> = (slots.iter().enumerate())
        .map(|(i, &x)| at(i) - (mean_t + (x - mean_x) * period_s))
        .collect();
    offs.sort_by(f64::total_cmp);
    let out = ((1.0 - within) / 2.0 * n).floor() as usize;
    let spread_s = offs[offs.len() - 1 - out] - offs[out];
    let fits = spread_s <= tick_s + 2.0 * SLOT_TOLERANCE * period_s;
    let first_slot_s = t0_s + mean_t + (slots[0] - mean_x) * period_s;
    (period_s.is_finite()
        && period_s > 0.0
        && if finer {
            tick_s * MIN_TICK_PERIODS < period_s && period_s < 2.0 * tick_s
        } else {
            period_s * MIN_TICK_PERIODS < tick_s
        }
        && fits
        && first_slot_s.is_finite())
    .then_some(FittedLine {
        period_s,
        first_slot_s,
        spread_s,
    })
}

/// What a text log's coarse clock was (`ingest.json`'s `text_ticks`).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TextTicks {
    /// The clock's tick, s.
    pub tick_s: f64,
    /// The samples' period its first lines gave, s.
    pub period_s: f64,
    /// Lines given their slot's time.
    pub lines: u64,
    /// Lines whose tick ended before the slot after the line before's (a tag glitch, or
    /// the clock's own error): given that slot's time.
    pub early: u64,
    /// Lines the clock took afresh from their tick's middle: beyond 2^20 slots after the
    /// line before, or earlier than their slot by more than a tick and a period (the
    /// logger's clock set back, which the reader then takes out).
    pub restarts: u64,
}

/// Gives each line of a log stamped by a coarse clock its slot's time (the module's
/// doc); a line repeating the one before (its tag and values) takes that one's time,
/// and the reader sets it aside as sent again.
///
/// The clock takes each line at the first slot its tick allows, so that a line lost
/// shows where a tick allows no line's slot to be the one after the line before's: the
/// lines before may have been a slot later, and where among them the sample was lost
/// their ticks do not tell. The lines are held [`HELD_LINES`] before they are given out,
/// and on a line lost the gap is put halfway along the lines that could be a slot later
/// (those lines moved on a slot): Kingston stamped by a 156.25-ms clock with one line in
/// a hundred lost had 40 lines a period off with each gap put at its earliest.
#[derive(Debug)]
pub(crate) struct TickRetime {
    account: TextTicks,
    /// Lines read ahead before the layer began (the log's first), given out first.
    unread: VecDeque<TextSample>,
    clock: TickClock,
    /// Lines given their slot's time, not yet given out: each with its tag as written
    /// and whether it repeats the line before.
    held: VecDeque<Held>,
    /// The last line as written.
    last: Option<TextSample>,
    /// The time of the last line given out, s.
    given_s: Option<f64>,
    /// No more lines to read.
    ended: bool,
    /// An error met reading, returned once the lines held before it are given out.
    failed: Option<FormatError>,
}

/// Lines [`TickRetime`] holds before giving them out: the lines a gap could be put
/// among.
const HELD_LINES: usize = 16;

/// A line [`TickRetime`] holds.
#[derive(Debug, Clone, Copy)]
struct Held {
    sample: TextSample,
    tag_s: f64,
    repeat: bool,
}

impl TickRetime {
    /// Retimes the lines of a log whose first lines gave `fit`, the lines read so far
    /// (`unread`, from the log's first) first.
    pub(crate) fn new(fit: TickFit, unread: VecDeque<TextSample>) -> Self {
        Self {
            account: TextTicks {
                tick_s: fit.tick_s,
                period_s: fit.period_s,
                ..TextTicks::default()
            },
            unread,
            clock: TickClock::new(
                fit.tick_s,
                fit.period_s,
                fit.first_slot_s - fit.period_s,
                fit.tolerance,
            ),
            held: VecDeque::with_capacity(HELD_LINES + 1),
            last: None,
            given_s: None,
            ended: false,
            failed: None,
        }
    }

    /// The account so far.
    pub(crate) fn account(&self) -> TextTicks {
        self.account
    }

    /// The next line with its slot's time, or `None` at the end; `read` gives the lines
    /// as written.
    pub(crate) fn next(
        &mut self,
        mut read: impl FnMut() -> Result<Option<TextSample>, FormatError>,
    ) -> Result<Option<TextSample>, FormatError> {
        while !self.ended && self.failed.is_none() && self.held.len() <= HELD_LINES {
            let s = match self.unread.pop_front() {
                Some(s) => Ok(Some(s)),
                None => read(),
            };
            match s {
                Ok(Some(s)) => self.take(s),
                Ok(None) => self.ended = true,
                Err(e) => self.failed = Some(e),
            }
        }
        match (self.held.pop_front(), self.failed.take()) {
            (Some(h), failed) => {
                self.failed = failed;
                self.given_s = Some(h.sample.t_s);
                Ok(Some(h.sample))
            }
            (None, Some(e)) => Err(e),
            (None, None) => Ok(None),
        }
    }

    /// Gives line `s` its slot's time and holds it.
    fn take(&mut self, mut s: TextSample) {
        let tag_s = s.t_s;
        let repeat = self
            .last
            .is_some_and(|last| last.t_s == tag_s && repeats(&last, &s));
        self.last = Some(s);
        if repeat {
            // The line before's time: held, or given out (the held lines given out before
            // an error).
            s.t_s = (self.held.back().map(|h| h.sample.t_s))
                .or(self.given_s)
                .unwrap_or(s.t_s);
            self.held.push_back(Held {
                sample: s,
                tag_s,
                repeat,
            });
            return;
        }
        let step = self.clock.step(tag_s);
        s.t_s = step.slot_s;
        let a = &mut self.account;
        a.lines += 1;
        a.early += u64::from(step.early);
        a.restarts += u64::from(step.slots.is_none());
        if let Some(slots) = step.slots {
            for _ in 1..(slots as usize).min(HELD_LINES) {
                self.put_gap_halfway();
            }
        }
        self.held.push_back(Held {
            sample: s,
            tag_s,
            repeat,
        });
    }

    /// Moves the later half of the held lines that could each be a slot later (the last
    /// held and those before it whose ticks allow it) on by a slot: a gap the line being
    /// taken showed, put halfway along the lines it could lie after.
    fn put_gap_halfway(&mut self) {
        let (p, tick_s) = (self.clock.period_s, self.clock.tick_s);
        let tolerance_s = self.clock.tolerance * p;
        let later_fits = |h: &Held| h.sample.t_s + p < h.tag_s + tick_s + tolerance_s;
        let mut from = self.held.len();
        while from > 0 && (self.held[from - 1].repeat || later_fits(&self.held[from - 1])) {
            from -= 1;
        }
        // The gap may lie after any of the lines from `from − 1` on (before the first
        // held, if `from` is 0): halfway along them, a line sent again beside its original.
        let mut at = from + (self.held.len() - from).div_ceil(2);
        while at < self.held.len() && self.held[at].repeat {
            at += 1;
        }
        for h in self.held.range_mut(at..) {
            h.sample.t_s += p;
        }
    }
}

/// Where a line fell on a [`TickClock`].
#[derive(Debug, Clone, Copy)]
struct TickStep {
    /// The slots it moved on from the last line's (`None`: the clock taken afresh from
    /// its tick's middle).
    slots: Option<f64>,
    /// Its slot's time as the clock puts it, s.
    slot_s: f64,
    /// Its tick ended before the slot after the last line's (given that slot).
    early: bool,
}

/// A clock of the slots of lines a coarse clock stamped, following their ticks.
#[derive(Debug, Clone, Copy)]
struct TickClock {
    tick_s: f64,
    /// How far beyond its tick a line's slot may lie, of a period.
    tolerance: f64,
    /// The period fitted, and the clock's now, s.
    fitted_period_s: f64,
    period_s: f64,
    /// The last line's slot time as the clock put it, s.
    slot_s: f64,
}

impl TickClock {
    /// A clock of ticks `tick_s` and slots `period_s` apart, its last slot at `slot_s`.
    fn new(tick_s: f64, period_s: f64, slot_s: f64, tolerance: f64) -> Self {
        Self {
            tick_s,
            tolerance,
            fitted_period_s: period_s,
            period_s,
            slot_s,
        }
    }

    /// Moves on to a line of the tick from `t_s` on: the first slot after the last
    /// line's within the tick (to [`Self::tolerance`] of a period either side; slots
    /// passed over are lines lost), or the next slot when the tick ended before it by up
    /// to a tick and a period; then the clock's phase and period toward the tick's
    /// middle. Taken afresh from it beyond.
    fn step(&mut self, t_s: f64) -> TickStep {
        let (p, tick_s) = (self.period_s, self.tick_s);
        let middle_s = t_s + tick_s / 2.0;
        let (from_s, to_s) = (t_s - self.tolerance * p, t_s + tick_s + self.tolerance * p);
        let next_s = self.slot_s + p;
        let early = next_s >= to_s && next_s - to_s <= tick_s + p;
        let slots = if next_s < from_s {
            ((from_s - self.slot_s) / p).ceil()
        } else if next_s < to_s || early {
            1.0
        } else {
            f64::INFINITY
        };
        if slots.is_nan() || slots > MAX_FOLLOWED_SLOTS {
            self.slot_s = middle_s;
            return TickStep {
                slots: None,
                slot_s: middle_s,
                early: false,
            };
        }
        let slot_s = self.slot_s + slots * p;
        let off_s = middle_s - slot_s;
        let limit_s = MAX_PERIOD_CHANGE * self.fitted_period_s;
        self.period_s = (self.period_s + PERIOD_GAIN * off_s / slots).clamp(
            self.fitted_period_s - limit_s,
            self.fitted_period_s + limit_s,
        );
        self.slot_s = slot_s + PHASE_GAIN * off_s;
        TickStep {
            slots: Some(slots),
            slot_s: self.slot_s,
            early,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kfgins::tests::read_all;
    use crate::report::IngestReport;
    use crate::text_bursts::tests::unit;

    /// A 7-column log of samples `(k, tag_s)`, sample `k`'s first value `k`, its tag
    /// written `tag`.
    fn log_of(lines: &[(u64, f64)], tag: impl Fn(f64) -> String) -> String {
        (lines.iter())
            .map(|&(k, t)| format!("{} {k} 2 3 4 5 6\n", tag(t)))
            .collect()
    }

    /// Samples `0..n` made `period_s` apart from `start_s`, each from the tenth lost at
    /// `rate` (draws `unit(k + salt)`), and how many were lost.
    fn losing(n: u64, start_s: f64, period_s: f64, rate: f64, salt: u64) -> (Vec<(u64, f64)>, u64) {
        let kept: Vec<(u64, f64)> = (0..n)
            .filter(|&k| k < 10 || unit(k + salt) >= rate)
            .map(|k| (k, start_s + k as f64 * period_s))
            .collect();
        let lost = n - kept.len() as u64;
        (kept, lost)
    }

    /// The samples `text` gives, each with its sample's number, and the account.
    fn read(text: &str) -> (Vec<(u64, TextSample)>, IngestReport) {
        let (v, report, _) = read_all(text);
        (
            v.into_iter().map(|s| (s.dtheta_rad[0] as u64, s)).collect(),
            report,
        )
    }

    /// Each sample's time less its true time (`period_s` times its number), less their
    /// median, s.
    fn time_errors_s(v: &[(u64, TextSample)], period_s: f64) -> Vec<f64> {
        let mut e: Vec<f64> = v
            .iter()
            .map(|(k, s)| s.t_s - *k as f64 * period_s)
            .collect();
        let mut sorted = e.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        e.iter_mut().for_each(|x| *x -= median);
        e
    }

    /// A 100-Hz log a PC stamped with its 15.625-ms timer, each tag its line's time down
    /// to the tick, written in whole milliseconds (steps of 15 and 16 ms, and of none
    /// where two lines share a tick). Read as written, the tick was the period and each
    /// shared tag the clock set back. Now the tick and the period are found, every line
    /// is its sample's slot, its time within 0.06 of a period of the sample's (less their
    /// common offset), and no line is lost or stepped.
    #[test]
    fn a_100_hz_log_on_a_pc_timer_takes_its_slots() {
        let (period_s, tick_s) = (0.01, 0.015625);
        let lines: Vec<(u64, f64)> = (0..30_000)
            .map(|k| (k, 1000.0 + k as f64 * period_s))
            .collect();
        let text = log_of(&lines, |t| format!("{:.3}", (t / tick_s).floor() * tick_s));
        let (v, rep) = read(&text);
        let ticks = rep.text_ticks.expect("a coarse clock");
        assert!((ticks.tick_s - tick_s).abs() < 1e-4, "{ticks:?}");
        assert!((ticks.period_s - period_s).abs() < 1e-7, "{ticks:?}");
        assert_eq!((ticks.lines, ticks.early, ticks.restarts), (30_000, 0, 0));
        assert_eq!(v.len(), 30_000);
        assert!(v.iter().all(|(k, s)| s.slot == *k));
        let counted = (
            rep.lost_samples,
            rep.text_clock_steps_back,
            rep.lines_off_slot,
        );
        assert_eq!(counted, (0, 0, 0), "{rep:?}");
        let worst = time_errors_s(&v, period_s)
            .iter()
            .fold(0f64, |m, e| m.max(e.abs()));
        assert!(worst < 0.06 * period_s, "{worst}");
    }

    /// The same log's lines stamped as they came, 1 ms early to 3 ms late (0.4 of a
    /// period of jitter), before the timer's tick: every line is still its sample's slot
    /// (with the slots' tolerance at a quarter of a period, 4058 of 240 000 such lines
    /// read as lost), its time within 0.2 of a period of the sample's: the clock follows
    /// the samples, not the logger's jitter.
    #[test]
    fn a_jittering_log_on_a_pc_timer_takes_its_slots() {
        let (period_s, tick_s) = (0.01, 0.015625);
        let lines: Vec<(u64, f64)> = (0..60_000)
            .map(|k| {
                (
                    k,
                    152_143.089 + k as f64 * period_s + 0.004 * unit(k) - 0.001,
                )
            })
            .collect();
        let text = log_of(&lines, |t| format!("{:.3}", (t / tick_s).floor() * tick_s));
        let (v, rep) = read(&text);
        let ticks = rep.text_ticks.expect("a coarse clock");
        assert_eq!((ticks.lines, ticks.restarts), (60_000, 0));
        assert!(v.iter().all(|(k, s)| s.slot == *k));
        assert_eq!(
            (rep.lost_samples, rep.text_clock_steps_back),
            (0, 0),
            "{rep:?}"
        );
        let worst = time_errors_s(&v, period_s)
            .iter()
            .fold(0f64, |m, e| m.max(e.abs()));
        assert!(worst < 0.2 * period_s, "{worst}");
    }

    /// A log `(sample, tag)` of 100 Hz tags in 10-ms steps with a step of 20 ms after
    /// every ninth line, each line's velocity increments `span_s` of gravity.
    fn ninths_skipping(span_s: f64) -> String {
        (0..6000u64)
            .map(|j| {
                let slot = j + j / 9;
                let tag_s = 2000.0 + slot as f64 * 0.01;
                format!(
                    "{tag_s:.3} {j} 0 0 0.0002 -0.0003 {:.9}\n",
                    -GRAVITY_MPS2 * span_s
                )
            })
            .collect()
    }

    /// Tags in steps of one tick and of two, one of two after every ninth line, are what
    /// a logger losing every tenth line of a 100-Hz IMU writes, and what a 10-ms clock
    /// stamping a 90-Hz IMU writes (its samples 11.1 ms apart): the tags cannot tell the
    /// two apart, the velocity increments can. Spanning 10 ms each (by gravity), the
    /// lines are read as losing one in ten, each on its slot (666 lost, none off); read
    /// as the finer clock before, they were given times 11.1 ms apart and the derive
    /// took them for a 90-Hz IMU (Kingston losing every tenth line: the joint fit left
    /// its bounds). Spanning 11.1 ms, they are that clock's.
    #[test]
    fn lines_lost_regularly_are_told_from_a_finer_clock_by_their_increments() {
        let (v, rep) = read(&ninths_skipping(0.01));
        let loss = rep.text_regular_loss.unwrap_or_else(|| panic!("{rep:?}"));
        assert!(rep.text_ticks.is_none(), "{rep:?}");
        assert!((loss.period_s - 0.01).abs() < 1e-6, "{loss:?}");
        assert!((loss.one_in() - 10.0).abs() < 0.05, "{loss:?}");
        assert!((loss.increments_span_s - 0.01).abs() < 1e-6, "{loss:?}");
        assert_eq!(rep.lost_samples, 666, "{rep:?}");
        assert_eq!(v.len(), 6000);
        assert!(
            v.iter().all(|(j, s)| s.slot == j + j / 9),
            "a line off its slot"
        );
        assert!(
            v.iter()
                .all(|(j, s)| (s.t_s - (2000.0 + (j + j / 9) as f64 * 0.01)).abs() < 1e-6),
            "a line off its sample's time"
        );
        let said = rep.text_regular_loss_said().unwrap();
        assert!(said.contains("losing one line in 10.0"), "{said}");

        let (v, rep) = read(&ninths_skipping(0.01 / 0.9));
        assert!(rep.text_regular_loss.is_none(), "{rep:?}");
        let ticks = rep.text_ticks.expect("the finer clock's");
        assert!((ticks.period_s - 0.01 / 0.9).abs() < 1e-5, "{ticks:?}");
        assert_eq!(rep.lost_samples, 0, "{rep:?}");
        assert!(v.iter().all(|(j, s)| s.slot == *j));
    }

    /// A 50-Hz log a PC stamped with its 15.625-ms timer (0.78 of a period: steps of one
    /// tick and of two, no tag shared), one line in a hundred lost. Read as written, the
    /// tick was the period and every second step a sample lost (Kingston on a 78-ms clock
    /// failed the derive; on a 90-ms one, 974 samples "lost" were filled in and OEPI went
    /// 3.7° off). Now every line lost is counted, and every line is its sample's slot,
    /// its time within 0.06 of a period of its sample's, but a line beside a gap the
    /// ticks (to the slots' tolerance) cannot place, a slot off (11 of 29 700 lines; the
    /// test allows one in a thousand).
    #[test]
    fn a_50_hz_log_on_a_pc_timer_takes_its_slots() {
        let (period_s, tick_s) = (0.02, 0.015625);
        let (lines, lost) = losing(30_000, 3000.0, period_s, 0.01, 5);
        let text = log_of(&lines, |t| format!("{:.3}", (t / tick_s).floor() * tick_s));
        let (v, rep) = read(&text);
        let ticks = rep.text_ticks.expect("a clock's ticks");
        assert!((ticks.tick_s - tick_s).abs() < 1e-4, "{ticks:?}");
        assert!((ticks.period_s - period_s).abs() < 1e-6, "{ticks:?}");
        assert_eq!(rep.lost_samples, lost, "{rep:?}");
        let off_slot = v.iter().filter(|(k, s)| s.slot != *k).count();
        assert!(v.iter().all(|(k, s)| s.slot.abs_diff(*k) <= 1));
        assert!(
            off_slot * 1000 <= v.len(),
            "{off_slot} lines off their slot"
        );
        let e = time_errors_s(&v, period_s);
        let near = e.iter().filter(|e| e.abs() < 0.06 * period_s).count();
        assert!(e.iter().all(|e| e.abs() < 1.06 * period_s));
        assert_eq!(near + off_slot, v.len());
    }

    /// A log on a PC timer whose reading fails at its end (the disk): every line read
    /// before the error is given out before it, retimed, the error after them.
    #[test]
    fn an_error_reading_a_ticked_log_comes_after_its_lines() {
        use crate::kfgins::tests::FailsAtEnd;
        let (period_s, tick_s) = (0.01, 0.015625);
        for n in [1500, 3000] {
            let lines: Vec<(u64, f64)> = (0..n).map(|k| (k, 20.0 + k as f64 * period_s)).collect();
            let text = log_of(&lines, |t| format!("{:.3}", (t / tick_s).floor() * tick_s));
            let src = FailsAtEnd(std::io::Cursor::new(text.into_bytes()));
            let mut r = crate::kfgins::KfGinsReader::new(std::io::BufReader::new(src));
            let mut slots = Vec::new();
            let err = loop {
                match r.next_sample() {
                    Ok(Some(s)) => slots.push(s.slot),
                    Ok(None) => panic!("the error was lost"),
                    Err(e) => break e,
                }
            };
            assert!(err.to_string().contains("the disk failed"), "{err}");
            assert!(r.report().text_ticks.is_some(), "{n} lines");
            assert_eq!(slots, (0..n).collect::<Vec<u64>>(), "{n} lines");
        }
    }

    /// A 125-Hz log stamped to the hundredth of a second (rounded: 1.25 periods), the
    /// logger's clock 80 ppm fast, 2 % of its lines lost. Every line lost is counted; a
    /// line's slot is its sample's or, beside a gap its ticks cannot place, one off (the
    /// gap put halfway along the lines it could follow), for under 0.8 % of the lines
    /// (0.39 % measured; 1.14 % with each gap put at its earliest). Every time is within a period and a quarter of its sample's, 99 % within
    /// a quarter: five ticks to four periods, the ticks tell the samples' phase only to a
    /// fifth of a tick (the clock wanders within it as the drift moves the phase; 80 %
    /// within a tenth of a period, 99 % within 0.19, measured).
    #[test]
    fn lines_lost_under_a_coarse_clock_are_counted_and_put_halfway() {
        let (period_s, tick_s) = (0.008, 0.01);
        let (lines, lost) = losing(40_000, 500.0, period_s * (1.0 + 80e-6), 0.02, 0);
        let text = log_of(&lines, |t| format!("{:.2}", (t / tick_s).round() * tick_s));
        let (v, rep) = read(&text);
        let ticks = rep.text_ticks.expect("a coarse clock");
        assert!((ticks.tick_s - tick_s).abs() < 1e-6, "{ticks:?}");
        assert_eq!(ticks.restarts, 0);
        assert_eq!(v.len(), lines.len());
        assert_eq!(rep.lost_samples, lost, "{rep:?}");
        assert_eq!(
            (rep.text_clock_steps_back, rep.text_clock_steps_forward),
            (0, 0)
        );
        let first = v[0].1.slot;
        let off: Vec<i64> = (v.iter())
            .map(|(k, s)| (s.slot - first) as i64 - *k as i64)
            .collect();
        let off_slot = off.iter().filter(|&&o| o != 0).count();
        assert!(off.iter().all(|o| o.abs() <= 1), "{off:?}");
        assert!(
            off_slot * 1000 < 8 * v.len(),
            "{off_slot} of {} off their slot",
            v.len()
        );
        let e = time_errors_s(&v, period_s * (1.0 + 80e-6));
        let near = e.iter().filter(|x| x.abs() < 0.25 * period_s).count();
        assert!(e.iter().all(|x| x.abs() < 1.25 * period_s));
        assert!(near * 100 >= 99 * e.len(), "{near} of {}", e.len());
    }

    /// A line sent twice (its tag and values) under a coarse clock takes its original's
    /// time and is set aside as sent again; the lines keep their slots.
    #[test]
    fn a_line_sent_twice_under_a_coarse_clock_is_set_aside() {
        let (period_s, tick_s) = (0.01, 0.015625);
        let lines: Vec<(u64, f64)> = (0..5000)
            .flat_map(|k| {
                let t = 10.0 + k as f64 * period_s;
                let twice = if k % 50 == 7 { 2 } else { 1 };
                std::iter::repeat_n((k, t), twice)
            })
            .collect();
        let text = log_of(&lines, |t| format!("{:.3}", (t / tick_s).floor() * tick_s));
        let (v, rep) = read(&text);
        assert!(rep.text_ticks.is_some());
        assert_eq!(rep.rejected.duplicate_seq, 100);
        assert_eq!(v.len(), 5000);
        assert!(v.iter().all(|(k, s)| s.slot == *k));
    }

    /// Logs whose lines share tags but that no coarse clock stamped are read as before:
    /// a regular log whose tags glitched (a line's repeating the one before's), one
    /// whose clock stood for five lines now and then, one jittering by 0.3 of a period
    /// with tags repeated, one losing lines with tags repeated, and three losing one line
    /// in fifty, ten or four at random (their steps of one period and two, as a tick
    /// shorter than the period gives, not in its regular proportion).
    #[test]
    fn lines_sharing_tags_with_no_coarse_clock_are_read_as_before() {
        let period_s = 0.01;
        let tags = |edit: &dyn Fn(usize, f64, &[f64]) -> f64| -> String {
            let mut t: Vec<f64> = Vec::new();
            for k in 0..5000 {
                let v = edit(k, 100.0 + k as f64 * period_s, &t);
                t.push(v);
            }
            let lines: Vec<(u64, f64)> =
                t.iter().enumerate().map(|(k, &t)| (k as u64, t)).collect();
            log_of(&lines, |t| format!("{t:.4}"))
        };
        let glitched = tags(&|k, t, before| {
            if [20, 60, 90, 700].contains(&k) {
                before[k - 1]
            } else {
                t
            }
        });
        let standing = tags(&|k, t, before| if k % 300 > 295 { before[k - 1] } else { t });
        let jittered = tags(&|k, t, before| {
            if k % 40 == 39 {
                before[k - 1]
            } else {
                t + 0.3 * period_s * (2.0 * unit(k as u64) - 1.0)
            }
        });
        // Lines lost (a step of two periods) one in 30, tags repeated one in 70.
        let lossy = tags(&|k, t, before| match k {
            _ if k % 70 == 69 => before[k - 1],
            _ if k > 0 && unit(k as u64) < 1.0 / 30.0 => before[k - 1] + 2.0 * period_s,
            _ => t.max(before.last().map_or(t, |b| b + period_s)),
        });
        // Lines lost at random, one in ten and one in four (steps of one period and of
        // two or more, as a tick shorter than the period gives, but not regularly).
        let losing = |rate: f64| {
            tags(&|k, t, before| match before.last() {
                Some(b) if unit(k as u64 + 99) < rate => b + 2.0 * period_s,
                Some(b) => b + period_s,
                None => t,
            })
        };
        for (what, text) in [
            ("glitched", glitched),
            ("standing", standing),
            ("jittered", jittered),
            ("lossy", lossy),
            ("losing one in fifty", losing(0.02)),
            ("losing one in ten", losing(0.1)),
            ("losing one in four", losing(0.25)),
        ] {
            let (_, rep) = read(&text);
            assert_eq!(rep.text_ticks, None, "{what}");
        }
    }
}
