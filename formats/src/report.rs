//! The ingest's reports: the exact accounting of §1.4 of the raw-format spec
//! (`ingest.json`) and the faults it located (`ingest_events.json`).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::kfgins::LineFault;
use crate::raw::FaultEvent;

/// Records read but not kept, by reason.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rejected {
    /// Framed records whose CRC did not match.
    pub bad_crc: u64,
    /// IMU records repeating the `seq` of the record before (retransmissions).
    pub duplicate_seq: u64,
    /// Records of a reserved type, or of a known type with a wrong length.
    pub unknown_type: u64,
    /// The final record, cut short by the end of the file (0 or 1).
    pub truncated: u64,
    /// Text logs only: lines that are not a record (bad number, wrong column count).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub malformed_line: Option<u64>,
}

/// Accounting of one raw log (`ingest.json`).
///
/// Invariant: `records_read == records_accepted + Σ rejected` and
/// `records_accepted == imu_accepted + marks_accepted`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IngestReport {
    /// Framed records the reader classified, the truncated final one included.
    pub records_read: u64,
    /// IMU plus mark records kept.
    pub records_accepted: u64,
    /// IMU records kept.
    pub imu_accepted: u64,
    /// Control-point marks kept.
    pub marks_accepted: u64,
    /// Records read but not kept, by reason.
    pub rejected: Rejected,
    /// Bytes discarded while resynchronising: whole bad-CRC records and garbage.
    pub bytes_skipped: u64,
    /// Bytes of the truncated final record.
    pub truncated_bytes: u64,
    /// Times the reader lost framing and found it again.
    pub resync_events: u64,
    /// Jumps in `seq` between consecutive accepted IMU records.
    pub seq_gaps: u64,
    /// Samples missing in those jumps.
    pub lost_samples: u64,
    /// `lost_samples` × the nominal sample period, s.
    pub lost_duration_s: f64,
    /// Accepted IMU records whose `t_us` is not after the previous one's.
    pub t_non_increasing: u64,
    /// Binary logs: times the recorder's clock leapt (forward or back, beyond half a
    /// sample period, or beyond the recorder's jitter times
    /// [`crate::raw::JITTER_TOLERANCE`] up to [`crate::raw::MAX_TOLERANCE_PERIODS`]
    /// periods) while `seq` ran on: taken out of the time base, each listed in
    /// `ingest_events.json` (`clock_ahead`, `clock_back`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub clock_steps: u64,
    /// Binary logs: what the clock steps add to the tags after the last one, s (negative
    /// when the clock leapt forward).
    #[serde(default, skip_serializing_if = "is_zero_f64")]
    pub clock_shift_s: f64,
    /// Binary logs: IMU records whose tag alone was off its `seq`'s time beyond the same
    /// tolerance (its neighbours agreeing), given their `seq`'s time (`lone_tag_off`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub lone_tags_off: u64,
    /// Text logs: times the logger's clock was set back while it logged (a line before
    /// the one before it, or less than half a period after it, while the next goes on
    /// from it at a period): the line taken one period after the one before, and every
    /// later tag moved by as much.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub text_clock_steps_back: u64,
    /// Text logs: times the logger's clock was set forward while it logged (a gap the run
    /// bridges after which the lines' slots are more than a quarter of a period off the
    /// ones before): the line taken its whole periods and phase back, no line lost, and
    /// every later tag moved by as much.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub text_clock_steps_forward: u64,
    /// Text logs: what the steps back and forward add to the tags after the last one, s.
    #[serde(default, skip_serializing_if = "is_zero_f64")]
    pub text_clock_shift_s: f64,
    /// Text logs: the first [`TextClockStep::KEPT`] steps, back or forward, each at its
    /// line.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub text_clock_steps: Vec<TextClockStep>,
    /// Text logs: lines written late or early alone, off their slot by more than half a
    /// period between neighbours a slot either side, given the middle of their times
    /// (read as written, a late one closed a gap of a sample lost).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub lines_off_slot: u64,
    /// Text logs whose lines came in bursts (a logger stamping them as it received
    /// them, several at once): the period their bursts agree on and what was spread over
    /// them, each burst's lines ending at its first tag a period apart
    /// ([`crate::text_bursts`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub text_bursts: Option<crate::text_bursts::TextBursts>,
    /// Text logs stamped by a clock whose tick is about their period, coarser (several
    /// lines to a tag) or finer (steps of one tick and two, no tag shared): its tick, the
    /// period its first lines gave, and the lines given their slot's time on a clock
    /// following the tags ([`crate::text_ticks`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub text_ticks: Option<crate::text_ticks::TextTicks>,
    /// Text logs whose steps of one period and of two came as regularly as a clock's
    /// ticking finer than the period would, read as losing lines (one in so many)
    /// because the lines' velocity increments span one step ([`crate::text_ticks`]).
    /// The lines lost are counted in `lost_samples`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub text_regular_loss: Option<crate::text_ticks::TextRegularLoss>,
    /// Text logs: the first line stands apart from the others, across an interval longer
    /// than the longest gap a run bridges (the derive's `max_gap_s`) while the next is
    /// not: a line a logger wrote before it began. The interval, s, is not counted in
    /// `lost_samples`; the derive places the line beside the second.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_line_apart_s: Option<f64>,
    /// Text logs: the same of the last line, across the interval before it (a log of three
    /// lines or more): a line written after the logger stopped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_line_apart_s: Option<f64>,
    /// Text logs: times the time tags rolled over from the end of a GPS week to its start
    /// (seconds of week: [`crate::kfgins::GPS_WEEK_S`]), the week added to the tags after.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub week_rollovers: u64,
    /// Text logs: times the time tags rolled over from a day's end to its start (seconds
    /// of day: [`crate::kfgins::DAY_S`]), the day added to the tags after.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub day_rollovers: u64,
    /// Odometer steps beyond a land vehicle's speed (a corrupt count or reading), replaced
    /// by the speed before them; a run fails above 1 % of its odometer's samples.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub odometer_out_of_range: u64,
    /// Text logs with a separate odometer file (`[odometer] file`): its lines' account.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub odometer_file: Option<OdometerFileReport>,
    /// Binary logs whose status flags the odometer failed (bit 1) on some samples, or
    /// whose count stood while the vehicle moved: its failures, bridged in
    /// `odometer.parquet` or not.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub odometer_failures: Option<OdometerFailures>,
    /// A speed odometer read with a floor (`[odometer] speed_floor_mps`): the readings
    /// below it read as 0, and the distance they would have added.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_floor: Option<crate::speed_floor::SpeedFloorReport>,
    /// Text logs with an 8th column whose manifest names an odometer file: the file is
    /// the odometer, the column left unread.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub speed_column_unread: bool,
}

/// A text log's clock set back or forward while it logged
/// ([`IngestReport::text_clock_steps`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TextClockStep {
    /// The 1-based line of the first tag after the step.
    pub line: u64,
    /// What the step adds to the tags from that line on, s (negative: the clock was set
    /// forward).
    pub step_s: f64,
    /// The line's tag as written, s (its rollovers added).
    pub tag_s: f64,
    /// The tag of the line given out before it, as written, s.
    pub tag_before_s: f64,
}

impl TextClockStep {
    /// Steps listed in a report, at most (the rest are counted).
    pub const KEPT: usize = 100;
}

impl IngestReport {
    /// What the run's log and its row of the campaign summary say of the recorder's clock
    /// leaping while `seq` ran on, and of lone tags off (`None`: neither happened).
    pub fn clock_said(&self) -> Option<String> {
        let mut parts = Vec::new();
        if self.clock_steps > 0 {
            parts.push(format!(
                "the recorder's clock leapt {} while its seq ran on, taken out of the time \
                 base (the tags after the last moved by {:+.6} s)",
                times(self.clock_steps),
                self.clock_shift_s
            ));
        }
        if self.lone_tags_off > 0 {
            parts.push(format!(
                "{} IMU record{} tagged off alone, given {} seq's time",
                self.lone_tags_off,
                if self.lone_tags_off == 1 { "" } else { "s" },
                if self.lone_tags_off == 1 {
                    "its"
                } else {
                    "their"
                },
            ));
        }
        (!parts.is_empty()).then(|| {
            format!(
                "{} (each at its byte offset in ingest_events.json; a manifest's t_s is on \
                 this time base)",
                parts.join("; ")
            )
        })
    }

    /// What the run's log says of a first or last line apart from the others (`None`:
    /// neither was).
    pub fn lines_apart_said(&self) -> Option<String> {
        let said = |which: &str, gap_s: f64, neighbour: &str, when: &str| {
            format!(
                "the {which} line stands {gap_s:.3} s apart from the {neighbour} (a line \
                 written {when}): its interval is not counted as lost samples, and the \
                 derive places it beside that line"
            )
        };
        let parts: Vec<String> = [
            self.first_line_apart_s
                .map(|g| said("first", g, "second", "before the log began")),
            self.last_line_apart_s
                .map(|g| said("last", g, "one before it", "after the log stopped")),
        ]
        .into_iter()
        .flatten()
        .collect();
        (!parts.is_empty()).then(|| parts.join("; "))
    }

    /// What the run's log and its row of the campaign summary say of the log's time base:
    /// a binary log's clock leaping ([`Self::clock_said`]), a text log's lines in bursts
    /// ([`Self::text_bursts_said`]), on a coarse clock ([`Self::text_ticks_said`]), lost
    /// regularly ([`Self::text_regular_loss_said`]), off their slot
    /// ([`Self::lines_off_slot_said`]) and clock set back ([`Self::text_clock_said`]).
    pub fn time_base_said(&self) -> impl Iterator<Item = String> {
        [
            self.clock_said(),
            self.text_bursts_said(),
            self.text_ticks_said(),
            self.text_regular_loss_said(),
            self.lines_off_slot_said(),
            self.text_clock_said(),
        ]
        .into_iter()
        .flatten()
    }

    /// What the run's log and its row of the campaign summary say of a text log's clock
    /// set back or forward while it logged (`None`: it was not).
    pub fn text_clock_said(&self) -> Option<String> {
        let (back, forward) = (self.text_clock_steps_back, self.text_clock_steps_forward);
        let how = match (back, forward) {
            (0, 0) => return None,
            (back, 0) => format!("set back {}", times(back)),
            (0, forward) => format!("set forward {}", times(forward)),
            (back, forward) => format!("set back {} and forward {}", times(back), times(forward)),
        };
        let file = self.odometer_file.as_ref();
        let odometer = match file.map(|f| (f.clock_steps_followed, f.clock_steps_not_shown)) {
            Some((followed, not_shown)) => format!(
                "the odometer file's tags showed {followed} of the steps and were moved by \
                 them{}; the manifest's t_s are taken on the log's clock at its start",
                if not_shown > 0 {
                    format!(
                        ", {not_shown} not (left as written: a clock of its own, a step \
                         longer than {} s, or more steps than are listed)",
                        crate::followed_steps::MAX_FOLLOWED_STEP_S
                    )
                } else {
                    String::new()
                }
            ),
            None => "the manifest's t_s are taken on the log's clock at its start".to_owned(),
        };
        Some(format!(
            "the log's clock was {how} while it logged ({}), taken out of the time base (the \
             tags after the last moved by {:+.6} s); {odometer}",
            self.text_clock_steps_listed(),
            self.text_clock_shift_s
        ))
    }

    /// A text log's first five clock steps, each at its line, and where the rest are
    /// listed: "line 3001 +1.500 s, …; every step in ingest.json" (or the first
    /// [`TextClockStep::KEPT`], when there were more).
    pub fn text_clock_steps_listed(&self) -> String {
        let steps = self.text_clock_steps_back + self.text_clock_steps_forward;
        let listed: Vec<String> = (self.text_clock_steps.iter().take(5))
            .map(|s| format!("line {} {:+.3} s", s.line, s.step_s))
            .collect();
        let more = if steps > listed.len() as u64 {
            ", …"
        } else {
            ""
        };
        let kept = if steps > TextClockStep::KEPT as u64 {
            format!("the first {}", TextClockStep::KEPT)
        } else {
            "every step".to_owned()
        };
        format!("{}{more}; {kept} in ingest.json", listed.join(", "))
    }

    /// What the run's log and its row of the campaign summary say of a text log stamped
    /// by a coarse clock (`None`: it was not).
    pub fn text_ticks_said(&self) -> Option<String> {
        let t = self.text_ticks?;
        let mut odd = Vec::new();
        if t.early > 0 {
            odd.push(format!(
                "{} tagged before their slot could be",
                lines_count(t.early)
            ));
        }
        if t.restarts > 0 {
            odd.push(format!(
                "the clock taken afresh at {} (a long gap, or the clock set back)",
                lines_count(t.restarts)
            ));
        }
        let odd = if odd.is_empty() {
            String::new()
        } else {
            format!("; {}", odd.join(", "))
        };
        let (how, misread) = if t.tick_s > t.period_s {
            (
                "several lines to a tag",
                "the clock set back and lines lost",
            )
        } else {
            ("steps of one tick and of two", "lines lost")
        };
        Some(format!(
            "the log's time tags are a clock's of {:.3}-ms ticks, {:.2} periods of {:.3} ms \
             ({how}): each of its {} lines given its slot's time on a clock following the \
             ticks' middles, not read as {misread}{odd}",
            t.tick_s * 1e3,
            t.tick_s / t.period_s,
            t.period_s * 1e3,
            t.lines
        ))
    }

    /// What the run's log and its row of the campaign summary say of a text log read as
    /// losing lines regularly (`None`: it was not).
    pub fn text_regular_loss_said(&self) -> Option<String> {
        let l = self.text_regular_loss?;
        Some(format!(
            "the log's time tags step by one period of {:.3} ms and by two as regularly as \
             a clock ticking every {:.3} ms would stamp samples {:.3} ms apart, but its \
             lines' velocity increments span {:.3} ms each (by gravity, over its first {} \
             lines): read as losing one line in {:.1} regularly, not as such a clock",
            l.period_s * 1e3,
            l.period_s * 1e3,
            l.clock_period_s * 1e3,
            l.increments_span_s * 1e3,
            l.lines,
            l.one_in()
        ))
    }

    /// What the run's log and its row of the campaign summary say of a text log's lines
    /// that came in bursts (`None`: none did).
    pub fn text_bursts_said(&self) -> Option<String> {
        let b = self.text_bursts?;
        let how = if b.whole_log {
            format!(
                "the log's lines came in bursts (a logger stamping them as it received them, \
                 several at once: {} bursts of up to {} lines)",
                b.bursts, b.longest_lines
            )
        } else {
            format!(
                "{} line{} came in {} burst{} of {} lines or more (a logger stalled, then \
                 stamping its lines as it received them; up to {} in one)",
                b.lines,
                if b.lines == 1 { "" } else { "s" },
                b.bursts,
                if b.bursts == 1 { "" } else { "s" },
                crate::text_bursts::MIN_STALL_LINES,
                b.longest_lines
            )
        };
        Some(format!(
            "{how}: each burst's lines taken {:.3} ms apart, the last at the burst's first \
             tag, not read as the clock set back and lines lost",
            b.period_s * 1e3
        ))
    }

    /// What the run's log and its row of the campaign summary say of a text log's lines
    /// written late or early alone (`None`: none was).
    pub fn lines_off_slot_said(&self) -> Option<String> {
        let n = self.lines_off_slot;
        let (s, its) = if n == 1 { ("", "its") } else { ("s", "their") };
        (n > 0).then(|| {
            format!(
                "{n} line{s} written late or early alone (more than half a period off {its} \
                 slot, {its} neighbours a slot either side): given the middle of {its} \
                 neighbours' times, not read as a gap of lost samples"
            )
        })
    }

    /// What the run's log and its row of the campaign summary say of an 8th column left
    /// unread (`None`: none was).
    pub fn speed_column_unread_said(&self) -> Option<String> {
        self.speed_column_unread.then(|| {
            "the manifest's [odometer] file is the odometer: the log's 8th column is left \
             unread (leave the file out of the manifest to read the column as the speed)"
                .to_owned()
        })
    }
}

/// The odometer's failures in a binary log: flagged (status bit 1), or found from a count
/// that stood while the vehicle moved. A failure is a run of failed samples (a
/// working stretch shorter than a second inside one is taken into it); their counts are
/// never read. Bridged, the route's distance over it is the inertial along-track speed's,
/// fitted to the odometer's readings around it (`unz_stages::odo_bridge`); not bridged,
/// the route has no distance over its failed samples.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OdometerFailures {
    /// Failures bridged.
    pub bridged: u64,
    /// Samples failed in them.
    pub bridged_samples: u64,
    /// Of the bridged, those with readings before them only (the log ends in them):
    /// their distance drifts faster (measured: 0.23 m at most over 10 s, tens of metres
    /// over 30 s).
    pub one_ended: u64,
    /// The longest bridged, s: from its first failed sample to the first working one
    /// after it (or its last sample).
    pub longest_bridged_s: f64,
    /// Distance the bridges give the route across them, m.
    pub bridged_distance_m: f64,
    /// The largest root-mean-square residual of a bridge's fit to the odometer's readings
    /// around it, m: about a pulse's quantisation (a 12.5-mm pulse: 4 mm) when the
    /// inertial speed and the odometer agree.
    pub worst_residual_m: f64,
    /// Failures not bridged (longer than the longest bridged, or without readings
    /// around them): the route has no distance over their failed samples.
    pub not_bridged: u64,
    /// Samples failed in them.
    pub not_bridged_samples: u64,
    /// Of the failures, those the log does not flag: a count, or a speed file's or
    /// column's distance, that stood while the vehicle moved (`unz::odometer_stuck`,
    /// `unz::odometer_gaps`; a stand may hold two: into a stop and out of it), bridged
    /// or not like the flagged ones.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub stuck: u64,
    /// Samples of theirs (counted in `bridged_samples` or `not_bridged_samples` too).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub stuck_samples: u64,
    /// A text log's odometer file: its gaps without readings (`unz::odometer_gaps`), each a
    /// failure bridged or not like a binary log's (its samples the IMU's across it). One
    /// not bridged keeps the trapezoid of the speeds at its ends.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub file_gaps: u64,
    /// A text log's speeds (its odometer file's or 8th column's) left out as spikes: a
    /// reading, or a burst of them, that jumped from the speed faster than a land vehicle
    /// can change it and came back (`unz_formats::speed_spikes`). The trapezoid spans
    /// them; a burst of 3 s or more leaves a gap, bridged like the others.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub spikes: u64,
    /// Jumps of a text log's speed faster than a land vehicle's whose speed did not come
    /// back within a minute: kept, as the speed alone cannot say which side is wrong.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub jumps_kept: u64,
}

/// Accounting of a separate odometer file: `lines_read == lines_accepted +
/// lines_rejected`. Blank and comment lines are not read as records.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OdometerFileReport {
    /// Lines that are neither blank nor a comment.
    pub lines_read: u64,
    /// Lines kept as odometer samples.
    pub lines_accepted: u64,
    /// Lines not kept: not two finite numbers, time not advancing, a speed beyond a land
    /// vehicle's, a spike (their numbers and reasons are in `ingest_events.json`).
    pub lines_rejected: u64,
    /// Times its time tags rolled over from the end of a GPS week to its start (seconds of
    /// week: [`crate::kfgins::GPS_WEEK_S`]), the week added to the tags after.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub week_rollovers: u64,
    /// Times its time tags rolled over from a day's end to its start (seconds of day:
    /// [`crate::kfgins::DAY_S`]), the day added to the tags after.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub day_rollovers: u64,
    /// Steps of the log's clock (a text log's, set back or forward while it logged) that
    /// the file's tags showed too (one logger stamping both files): its tags after each
    /// moved by it ([`crate::followed_steps`]).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub clock_steps_followed: u64,
    /// Steps of the log's clock the file's tags did not show (a clock of its own), or
    /// that were longer than [`crate::followed_steps::MAX_FOLLOWED_STEP_S`]: its tags left
    /// as written across them.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub clock_steps_not_shown: u64,
}

/// The first faults of one raw log, located (`ingest_events.json`): the counts are in
/// [`IngestReport`], the places here.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IngestEvents {
    /// The raw log, as the manifest names it (relative to the manifest's folder), so the
    /// file does not depend on where the campaign lies or where it was run from.
    pub raw: PathBuf,
    /// Binary logs: every fault event, of which the first 1000 are in `events`.
    pub events_total: u64,
    /// Binary logs: the first faults, by byte offset.
    pub events: Vec<FaultEvent>,
    /// Text logs: the log's first 1000 rejected lines (their total is `events_total`).
    pub line_faults: Vec<LineFault>,
    /// The odometer file's first 1000 line faults (their total is `ingest.json`'s
    /// `odometer_file.lines_rejected`).
    pub odometer_file_faults: Vec<LineFault>,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// "once", "twice", "N times".
fn times(n: u64) -> String {
    match n {
        1 => "once".to_owned(),
        2 => "twice".to_owned(),
        n => format!("{n} times"),
    }
}

fn is_zero_f64(v: &f64) -> bool {
    *v == 0.0
}

impl IngestReport {
    /// Σ of the raw log's rejected counts.
    pub fn rejected_total(&self) -> u64 {
        let r = &self.rejected;
        r.bad_crc + r.duplicate_seq + r.unknown_type + r.truncated + r.malformed_line.unwrap_or(0)
    }

    /// Records and lines rejected, every file of the run (the raw log and its odometer
    /// file).
    pub fn rejected_all_files(&self) -> u64 {
        self.rejected_total() + self.odometer_file.as_ref().map_or(0, |o| o.lines_rejected)
    }

    /// Whether the identities of §1.4 hold, and the odometer file's.
    pub fn is_consistent(&self) -> bool {
        self.records_read == self.records_accepted + self.rejected_total()
            && self.records_accepted == self.imu_accepted + self.marks_accepted
            && self
                .odometer_file
                .as_ref()
                .is_none_or(|o| o.lines_read == o.lines_accepted + o.lines_rejected)
    }
}

/// "1 line", "n lines".
fn lines_count(n: u64) -> String {
    format!("{n} line{}", if n == 1 { "" } else { "s" })
}
