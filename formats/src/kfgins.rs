//! KF-GINS IMU text logs and separate odometer files (§3 of the raw-format spec).
//!
//! IMU lines: `t_s dtheta_x dtheta_y dtheta_z dvel_x dvel_y dvel_z [speed_mps]` —
//! seconds at the end of each interval, rad and m/s increments, body FRD. The file's
//! columns count is fixed by its first record line; blank lines and lines starting with
//! `#` or `%` are skipped. A line that is not a record is counted
//! (`rejected.malformed_line`) and reported with its number; the rest is kept.

use std::io::BufRead;

use crate::error::FormatError;
use crate::followed_steps::FollowedSteps;
use crate::lines_apart::GapAccount;
use crate::manifest::OdometerKind;
use crate::report::{IngestReport, OdometerFileReport, TextClockStep};
use crate::resent::RecentRecords;
use crate::slot_clock::SlotClock;
use crate::speed_floor::{SpeedFloor, SpeedFloorReport};
use crate::speed_spikes::{MAX_ACCEL_MPS2, MAX_BRAKING_MPS2, SpeedSpikes, Verdict};
use crate::text_bursts::{BURST_WINDOW, BurstSpread, burst_period_s, mostly_close};
use crate::text_ticks::{TickReading, TickRetime, coarse_tick, may_be_ticked};

/// Longest line accepted; longer lines are malformed (and never buffered whole).
pub const MAX_LINE_BYTES: usize = 4096;
/// Why a file that opens with UTF-16's byte-order mark is refused.
pub(crate) const UTF16_TEXT: &str =
    "UTF-16 text (its byte-order mark): the file must be UTF-8 or ASCII";

/// Largest time tag accepted, ±s (285 years): the pipeline keeps times as i64
/// nanoseconds (±9.22e9 s), with room to spare for the windows reaching past a tag. A
/// file whose times are in milliseconds, microseconds or nanoseconds since an epoch
/// (1.7e12, 1.7e15, 1.7e18) goes far beyond it; a larger tag would saturate and stand.
pub const MAX_TAG_S: f64 = 9.0e9;

/// Why time tag `t_s` is refused, if it is beyond [`MAX_TAG_S`]: named as Unix time in
/// milliseconds, microseconds or nanoseconds when one of them dates it between 1980 and
/// 2100 (an OBD-II or phone logger's clock), else asked.
fn tag_beyond_range(t_s: f64) -> Option<String> {
    (t_s.abs() > MAX_TAG_S).then(|| {
        let beyond = format!(
            "time {t_s:e} s is beyond ±{MAX_TAG_S:e} s (285 years), the span the pipeline \
             times to the nanosecond"
        );
        match unix_time_in(t_s) {
            Some((unit, date)) => {
                format!("{beyond}: Unix time in {unit} ({date})? Write the file's times in seconds")
            }
            None => format!("{beyond}: are the file's times in ms, µs or ns?"),
        }
    })
}

/// The unit of Unix time (`milliseconds`, `microseconds`, `nanoseconds`) in which `t`
/// dates a moment between 1980 and 2100, with that date (UTC, "18 May 2008").
fn unix_time_in(t: f64) -> Option<(&'static str, String)> {
    /// 1 January 1980 and 1 January 2100, Unix seconds.
    const SPAN_S: std::ops::Range<f64> = 315_532_800.0..4_102_444_800.0;
    [
        ("milliseconds", 1e3),
        ("microseconds", 1e6),
        ("nanoseconds", 1e9),
    ]
    .into_iter()
    .find(|(_, per_s)| SPAN_S.contains(&(t / per_s)))
    .and_then(|(unit, per_s)| Some((unit, unix_date(t / per_s)?)))
}

/// The UTC date of Unix time `unix_s`, "19 May 2008" (`None` beyond chrono's range).
pub fn unix_date(unix_s: f64) -> Option<String> {
    let date = chrono::DateTime::from_timestamp(unix_s.floor() as i64, 0)?;
    Some(date.format("%-d %B %Y").to_string())
}

/// Seconds in a GPS week. A text log's time column is often GPS seconds of week (KF-GINS
/// writes it so), which rolls over to 0 at the week's end, Saturday to Sunday midnight.
pub const GPS_WEEK_S: f64 = 604_800.0;

/// Seconds in a day. A logger that writes UTC seconds of day (an NMEA fix's time, as
/// many GNSS-timed loggers do) rolls over to 0 at midnight.
pub const DAY_S: f64 = 86_400.0;

/// How near the week's (or the day's) end a tag, and how near its start the tag after
/// it, must be for the step between them to be the rollover, s: an hour, a logger's gap
/// with room.
pub const WEEK_ROLLOVER_WINDOW_S: f64 = 3600.0;

/// A text file's time tags unwrapped over rollovers: a tag within
/// [`WEEK_ROLLOVER_WINDOW_S`] of the start after one within it of a GPS week's end is the
/// next week's, and after one within it of a day's end (seconds of day) the next day's;
/// every tag from it on has the week or the day added. Without it, a log running over
/// Sunday midnight (GPS time) kept its tags up to the rollover: the IMU's after it were
/// repaired one interval apart, and the odometer file's rejected as not after the one
/// before; and so did one in seconds of day over midnight. A log in seconds of week runs
/// through a day's end without a step back, so the two are not confused.
#[derive(Debug, Default, Clone, Copy)]
struct TagUnwrap {
    /// Seconds added to the tags: the weeks and days rolled over.
    added_s: f64,
    /// The last tag read, as written.
    last_s: Option<f64>,
    /// Weeks rolled over so far.
    weeks: u64,
    /// Days rolled over so far.
    days: u64,
    /// For a separate file (an odometer's): the log's first tag as written, which its
    /// first tag is taken beside (`None` once it is).
    log_first_s: Option<f64>,
    /// The first tag read, as written.
    first_s: Option<f64>,
}

impl TagUnwrap {
    /// Tag `t_s`, as written, in the file's time base unwrapped.
    fn unwrap(&mut self, t_s: f64) -> f64 {
        let ends =
            |period_s: f64, t_s: f64| (period_s - WEEK_ROLLOVER_WINDOW_S..period_s).contains(&t_s);
        let starts = |t_s: f64| (0.0..WEEK_ROLLOVER_WINDOW_S).contains(&t_s);
        self.first_s.get_or_insert(t_s);
        // The week first: seconds of week 0–3600 are also a day's first hour.
        let periods = [(GPS_WEEK_S, &mut self.weeks), (DAY_S, &mut self.days)];
        // A separate file begun across the week's or the day's end from the log: on the
        // log's side of it. After the log's first tag, the file's first is the next
        // period's (counted: the period is added to its tags); before it, the period
        // before's (its own rollover then counts). Then, as for every file, a tag in a
        // period's first hour after one in its last is the next period's.
        let log_s = self.log_first_s.take();
        for (period_s, count) in periods {
            let after_end = |before_s: f64| ends(period_s, before_s) && starts(t_s);
            if log_s.is_some_and(|l| starts(l) && ends(period_s, t_s)) {
                self.added_s -= period_s;
                break;
            }
            if log_s.or(self.last_s).is_some_and(after_end) {
                self.added_s += period_s;
                *count += 1;
                break;
            }
        }
        self.last_s = Some(t_s);
        t_s + self.added_s
    }

    /// Into a report's counts.
    fn count(&self, weeks: &mut u64, days: &mut u64) {
        (*weeks, *days) = (self.weeks, self.days);
    }
}

/// Number of leading samples whose median interval is the nominal sample period.
const PERIOD_WINDOW: usize = 101;

/// One IMU record of a text log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextSample {
    /// 1-based line number in the file.
    pub line: u64,
    /// Time tag, s (end of the interval).
    pub t_s: f64,
    /// Angle increments, rad, body FRD.
    pub dtheta_rad: [f64; 3],
    /// Velocity increments, m/s, body FRD.
    pub dvel_mps: [f64; 3],
    /// Optional 8th column: odometer speed, m/s.
    pub speed_mps: Option<f64>,
    /// The sample's slot of the period, counted from the first sample's (0): one more
    /// than the last sample's, and more after lines lost ([`SlotClock`]). What a
    /// recorder's sequence number is to a binary log.
    pub slot: u64,
}

/// A line that could not be used.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LineFault {
    /// 1-based line number.
    pub line: u64,
    /// Why it was rejected.
    pub reason: String,
}

/// Line faults kept for the events file: the first [`FaultLog::KEPT`] and their total.
#[derive(Debug, Default)]
struct FaultLog {
    kept: Vec<LineFault>,
    total: u64,
}

impl FaultLog {
    /// Faults kept with their line and reason; the rest are only counted.
    const KEPT: usize = 1000;

    fn push(&mut self, line: u64, reason: String) {
        self.push_with(line, || reason);
    }

    /// As [`FaultLog::push`], the reason written only when it is kept. Kept in the
    /// lines' order: a line judged after the lines behind it (a time tag that leapt
    /// forward, judged by the next line's) takes its place among them.
    fn push_with(&mut self, line: u64, reason: impl FnOnce() -> String) {
        self.total += 1;
        if self.kept.len() < Self::KEPT {
            let at = self.kept.len()
                - self
                    .kept
                    .iter()
                    .rev()
                    .take_while(|fault| fault.line > line)
                    .count();
            self.kept.insert(
                at,
                LineFault {
                    line,
                    reason: reason(),
                },
            );
        }
    }
}

/// Lines of a text file, read through a bounded buffer: a line longer than
/// [`MAX_LINE_BYTES`] is consumed but never held whole, however long it is.
struct LineReader<R: BufRead> {
    src: R,
    /// 1-based number of the line last read.
    line_no: u64,
    buf: Vec<u8>,
}

/// One line as read.
enum Line<'a> {
    /// Longer than [`MAX_LINE_BYTES`]; whether its first bytes hold a carriage return (a
    /// file whose lines end in CR alone reads as one line).
    Overlong { cr: bool },
    /// Not UTF-8.
    NotText,
    /// The first line, opening with UTF-16's byte-order mark.
    Utf16,
    /// Blank, or a comment (`#`, `%`).
    Skipped,
    /// A line to parse, trimmed.
    Text(&'a str),
}

impl Line<'_> {
    /// The record a line holds: none for a blank or comment line, else its text or why it
    /// cannot be one.
    fn record(&self) -> Option<Result<&str, String>> {
        match self {
            Line::Skipped => None,
            Line::Text(text) => Some(Ok(text)),
            Line::Overlong { cr: false } => {
                Some(Err(format!("line longer than {MAX_LINE_BYTES} bytes")))
            }
            Line::Overlong { cr: true } => Some(Err(format!(
                "line longer than {MAX_LINE_BYTES} bytes, with carriage returns in it: lines \
                 that end in CR alone? (lines end in LF or CR LF)"
            ))),
            Line::NotText => Some(Err("not UTF-8 text".into())),
            Line::Utf16 => Some(Err(UTF16_TEXT.into())),
        }
    }
}

impl<R: BufRead> LineReader<R> {
    fn new(src: R) -> Self {
        Self {
            src,
            line_no: 0,
            buf: Vec::with_capacity(256),
        }
    }

    /// The next line, or `None` at the end of the file.
    fn next_line(&mut self) -> Result<Option<Line<'_>>, FormatError> {
        self.buf.clear();
        let mut overlong = false;
        loop {
            let chunk = self
                .src
                .fill_buf()
                .map_err(|source| FormatError::Io { offset: 0, source })?;
            if chunk.is_empty() {
                if self.buf.is_empty() && !overlong {
                    return Ok(None);
                }
                break;
            }
            let (take, done) = match chunk.iter().position(|&b| b == b'\n') {
                Some(k) => (k + 1, true),
                None => (chunk.len(), false),
            };
            let room = MAX_LINE_BYTES.saturating_sub(self.buf.len());
            self.buf.extend_from_slice(&chunk[..take.min(room)]);
            overlong |= take > room;
            self.src.consume(take);
            if done {
                break;
            }
        }
        self.line_no += 1;
        if overlong {
            let cr = self.buf.contains(&b'\r');
            return Ok(Some(Line::Overlong { cr }));
        }
        if self.line_no == 1
            && (self.buf.starts_with(&[0xFF, 0xFE]) || self.buf.starts_with(&[0xFE, 0xFF]))
        {
            return Ok(Some(Line::Utf16));
        }
        let Ok(mut text) = std::str::from_utf8(&self.buf) else {
            // A comment in another encoding (a crew's note in Latin-1) is a comment.
            let first = self.buf.iter().find(|b| !b.is_ascii_whitespace());
            return Ok(Some(match first {
                Some(b'#' | b'%') => Line::Skipped,
                _ => Line::NotText,
            }));
        };
        // A byte-order mark (a Windows editor's or spreadsheet's export) opens the file
        // and is no part of its first line.
        if self.line_no == 1 {
            text = text.strip_prefix('\u{feff}').unwrap_or(text);
        }
        let text = text.trim();
        Ok(Some(
            if text.is_empty() || text.starts_with('#') || text.starts_with('%') {
                Line::Skipped
            } else {
                Line::Text(text)
            },
        ))
    }
}

/// What a rejected line's reason adds when its numbers look written with decimal commas.
const DECIMAL_COMMA_HINT: &str =
    " (decimal commas? numbers take a decimal point; a comma separates columns)";

/// Whether a line's numbers look written with decimal commas (a comma between digits, and
/// no point), which split into columns.
fn has_decimal_commas(text: &str) -> bool {
    !text.contains('.')
        && (text.as_bytes().windows(3))
            .any(|w| w[1] == b',' && w[0].is_ascii_digit() && w[2].is_ascii_digit())
}

/// The 1-based line of the first sample the reader accepts for which `wanted(row, sample)`
/// holds (`row`: 0-based among the accepted samples, the row of the ingest's IMU table it
/// became), or `None` when none does. The log is read up to it, a line at a time.
pub fn find_sample_line<R: BufRead>(
    src: R,
    mut wanted: impl FnMut(u64, &TextSample) -> bool,
) -> Result<Option<u64>, FormatError> {
    let mut reader = KfGinsReader::new(src);
    let mut row = 0u64;
    while let Some(s) = reader.next_sample()? {
        if wanted(row, &s) {
            return Ok(Some(s.line));
        }
        row += 1;
    }
    Ok(None)
}

/// Streaming reader of a KF-GINS IMU text log with accounting.
pub struct KfGinsReader<R: BufRead> {
    lines: LineReader<R>,
    columns: Option<usize>,
    report: IngestReport,
    faults: FaultLog,
    /// Samples read ahead to estimate the sample period.
    ahead: std::collections::VecDeque<TextSample>,
    period_s: Option<f64>,
    prev: Option<TextSample>,
    /// The next accepted sample, read before the one before it is given out: with the
    /// one before, it tells whether that one was written off its slot alone.
    held: Option<TextSample>,
    /// An error met reading [`Self::held`], returned after the sample before it.
    failed: Option<FormatError>,
    /// An error met reading lines ahead ([`Self::tags_ahead_s`]), returned once the lines
    /// read before it are.
    read_failed: Option<FormatError>,
    /// The time of the last sample given out, s (its slot's, when it was off it).
    given_t_s: Option<f64>,
    /// The slots that sample moved on from the one before it (0 for the first).
    given_slots: u64,
    /// The times of the last [`STEP_PHASE_LINES`] samples given out, s: the slots they
    /// agree on, against the lines' after a gap ([`clock_step_forward_s`]).
    given_tags_s: std::collections::VecDeque<f64>,
    /// That sample's slot.
    slot: u64,
    /// The slots of the samples given out, following their tags, once the period is
    /// known: started from the period and phase the first lines' tags agree on best
    /// ([`first_slots`]).
    clock: Option<SlotClock>,
    eof: bool,
    /// The layer every line passes through once the log's first lines are judged
    /// ([`TimingLayer`]): none, or one. Boxed: it is taken out and put back at each line
    /// (the reader is borrowed to read the lines it takes), and held inline each line
    /// moved its hundreds of bytes twice.
    layer: Option<Box<TimingLayer>>,
    /// The time tags over GPS-week and day rollovers.
    tags: TagUnwrap,
    /// The first sample's time, s: a sample's place is its intervals from it.
    first_t_s: Option<f64>,
    /// The samples accepted lately, their time and values bit for bit: a line repeating
    /// one of them (a block sent again, logs joined over their overlap) is a duplicate.
    recent: RecentRecords<[u64; 7], u64>,
    /// The gaps of lost samples, a first or last line apart left out.
    gaps: GapAccount,
}

/// The layer a text log's lines pass through between their parsing and the reader's
/// slots, once its first lines are judged.
#[derive(Debug)]
enum TimingLayer {
    /// Bursts spread over the periods before them ([`BurstSpread`]): every burst of a log
    /// wholly in bursts (its first lines show it: [`burst_period_s`]), or a stall's in any
    /// other.
    Bursts(BurstSpread),
    /// Each line given its slot's time on a clock following a coarse clock's ticks
    /// ([`TickRetime`]), when the log's first lines were stamped by one
    /// ([`coarse_tick`]).
    Ticks(TickRetime),
}

impl TimingLayer {
    /// The next line through the layer; `read` gives the lines as written.
    fn next(
        &mut self,
        read: impl FnMut() -> Result<Option<TextSample>, FormatError>,
    ) -> Result<Option<TextSample>, FormatError> {
        match self {
            Self::Bursts(b) => b.next(read),
            Self::Ticks(t) => t.next(read),
        }
    }
}

impl<R: BufRead> KfGinsReader<R> {
    /// Wraps a buffered source.
    pub fn new(src: R) -> Self {
        Self {
            lines: LineReader::new(src),
            columns: None,
            report: IngestReport {
                rejected: crate::report::Rejected {
                    malformed_line: Some(0),
                    ..Default::default()
                },
                ..Default::default()
            },
            faults: FaultLog::default(),
            ahead: std::collections::VecDeque::new(),
            period_s: None,
            prev: None,
            held: None,
            failed: None,
            read_failed: None,
            given_t_s: None,
            given_slots: 0,
            given_tags_s: std::collections::VecDeque::with_capacity(STEP_PHASE_LINES),
            slot: 0,
            clock: None,
            eof: false,
            layer: None,
            tags: TagUnwrap::default(),
            first_t_s: None,
            recent: RecentRecords::default(),
            gaps: GapAccount::new(f64::INFINITY),
        }
    }

    /// Reports a first or last line apart from the others across an interval longer
    /// than `max_gap_s` (the derive's: the longest gap a run bridges) instead of counting
    /// it as lost samples ([`IngestReport::first_line_apart_s`]). Without it, every gap
    /// is lost samples.
    pub fn with_max_gap_s(mut self, max_gap_s: f64) -> Self {
        self.gaps = GapAccount::new(max_gap_s);
        self
    }

    /// The accounting so far (final after the last sample).
    pub fn report(&self) -> &IngestReport {
        &self.report
    }

    /// The first 1000 line faults and their total count.
    pub fn faults(&self) -> (&[LineFault], u64) {
        (&self.faults.kept, self.faults.total)
    }

    /// The log's first time tag as written (before any rollover), once a sample is read
    /// ([`Self::period_s`] reads ahead): what a separate odometer file's first tag is
    /// taken beside ([`OdometerFileReader::beside_log_from`]).
    pub fn first_tag_s(&self) -> Option<f64> {
        self.tags.first_s
    }

    /// Number of columns of this file (7 or 8), once known.
    pub fn columns(&self) -> Option<usize> {
        self.columns
    }

    /// Nominal sample period (median interval of the first samples), once known.
    pub fn period_s(&mut self) -> Result<Option<f64>, FormatError> {
        self.prime()?;
        Ok(self.period_s)
    }

    fn fault(&mut self, reason: String) {
        self.report.records_read += 1;
        *self.report.rejected.malformed_line.get_or_insert(0) += 1;
        self.faults.push(self.lines.line_no, reason);
    }

    /// The next record, or `None` at the end: its time spread over its burst when the log
    /// comes in bursts, or its slot's when a coarse clock stamped it ([`Self::layer`]).
    /// An error kept from reading ahead ([`Self::read_failed`]) comes where the lines
    /// would: after those a layer holds.
    fn next_raw(&mut self) -> Result<Option<TextSample>, FormatError> {
        let next = match self.layer.take() {
            Some(mut layer) => {
                let next = layer.next(|| self.next_read());
                match &*layer {
                    TimingLayer::Bursts(b) => self.report.text_bursts = b.account(),
                    TimingLayer::Ticks(t) => self.report.text_ticks = Some(t.account()),
                }
                self.layer = Some(layer);
                next
            }
            None => self.next_read(),
        };
        if let Ok(None) = next {
            self.eof = true;
        }
        next
    }

    /// The error kept from reading ahead, if any, else the next record parsed.
    fn next_read(&mut self) -> Result<Option<TextSample>, FormatError> {
        match self.read_failed.take() {
            Some(e) => Err(e),
            None => self.next_parsed(),
        }
    }

    /// Parses lines until one record is found.
    fn next_parsed(&mut self) -> Result<Option<TextSample>, FormatError> {
        while let Some(line) = self.lines.next_line()? {
            let text = match line.record() {
                None => continue,
                Some(Ok(text)) => text,
                Some(Err(reason)) => {
                    self.fault(reason);
                    continue;
                }
            };
            let mut values = [0f64; 8];
            let mut n = 0;
            let mut bad = None;
            for field in text
                .split(|c: char| c.is_whitespace() || c == ',')
                .filter(|f| !f.is_empty())
            {
                if n == 8 {
                    n += 1;
                    break;
                }
                match field.parse::<f64>() {
                    Ok(v) if v.is_finite() => values[n] = v,
                    _ => {
                        bad = Some(format!(
                            "column {} is not a finite number: {field:?}",
                            n + 1
                        ));
                        break;
                    }
                }
                n += 1;
            }
            if let Some(reason) = bad {
                self.fault(reason);
                continue;
            }
            // A log's lines hold 7 or 8 columns: the 8th, the odometer's speed, may be left
            // blank (a logger's line without a fresh reading, or a CSV's empty last field),
            // and the log is of 8 columns once a line has them. Before, a log's columns were
            // its first line's, and every line of the other count was rejected: an 8-column
            // log lost the IMU samples of its lines without a speed (Kingston with one in
            // ten: 876 samples, OWPI's route 536 m off).
            if (7..=8).contains(&n) {
                self.columns = Some(self.columns.map_or(n, |c| c.max(n)));
            } else {
                let got = if n > 8 {
                    "more than 8".to_owned()
                } else {
                    n.to_string()
                };
                let hint = if has_decimal_commas(text) {
                    DECIMAL_COMMA_HINT
                } else {
                    ""
                };
                self.fault(format!("{got} columns, expected 7 or 8{hint}"));
                continue;
            }
            if let Some(reason) = tag_beyond_range(values[0]) {
                self.fault(reason);
                continue;
            }
            let t_s = self.tags.unwrap(values[0]);
            let r = &mut self.report;
            self.tags.count(&mut r.week_rollovers, &mut r.day_rollovers);
            // Rollovers without end (a file of tags at a week's end and start by turns)
            // add weeks past the span too.
            if let Some(reason) = tag_beyond_range(t_s) {
                self.fault(reason);
                continue;
            }
            return Ok(Some(TextSample {
                line: self.lines.line_no,
                t_s,
                dtheta_rad: [values[1], values[2], values[3]],
                dvel_mps: [values[4], values[5], values[6]],
                speed_mps: (n == 8).then_some(values[7]),
                slot: 0,
            }));
        }
        Ok(None)
    }

    /// Reads ahead to estimate the sample period.
    fn prime(&mut self) -> Result<(), FormatError> {
        if self.period_s.is_some() || self.eof {
            return Ok(());
        }
        self.read_window(PERIOD_WINDOW);
        if mostly_close(self.ahead.make_contiguous()) {
            self.read_window(BURST_WINDOW);
            if let Some(period_s) = burst_period_s(self.ahead.make_contiguous()) {
                self.spread_bursts(period_s, true);
            }
        }
        // A log losing lines regularly: its period the step of one, which need not be
        // the median step (one line in three lost steps by one and two alike).
        let mut lost_at_s = None;
        if self.layer.is_none() && may_be_ticked(self.ahead.make_contiguous()) {
            self.read_window(BURST_WINDOW);
            match coarse_tick(self.ahead.make_contiguous()) {
                Some(TickReading::Clock(fit)) => {
                    let read = std::mem::take(&mut self.ahead);
                    self.layer = Some(Box::new(TimingLayer::Ticks(TickRetime::new(fit, read))));
                    self.eof = false;
                    self.read_window(PERIOD_WINDOW);
                }
                Some(TickReading::LinesLost(loss)) => {
                    lost_at_s = Some(loss.period_s);
                    self.report.text_regular_loss = Some(loss);
                }
                None => {}
            }
        }
        let window = || self.ahead.iter().take(PERIOD_WINDOW);
        let mut dts: Vec<f64> = window()
            .zip(window().skip(1))
            .map(|(a, b)| b.t_s - a.t_s)
            .filter(|dt| *dt > 0.0)
            .collect();
        dts.sort_by(f64::total_cmp);
        self.period_s = lost_at_s.or_else(|| dts.get(dts.len() / 2).copied());
        if let Some(median_s) = self.period_s {
            let tags_s: Vec<f64> = window().map(|s| s.t_s).collect();
            let (period_s, first_late_s) = first_slots(&tags_s, median_s, lost_at_s.is_some());
            self.clock = Some(SlotClock::new(period_s, first_late_s));
            if self.layer.is_none() {
                self.spread_bursts(period_s, false);
            }
        }
        Ok(())
    }

    /// Spreads the lines of each burst over the periods before it from here on, the
    /// lines read ahead included, at `period_s` ([`BurstSpread`]): every burst when the
    /// log is `whole_log` in bursts, else a stall's of three lines or more.
    fn spread_bursts(&mut self, period_s: f64, whole_log: bool) {
        let read = std::mem::take(&mut self.ahead);
        let spread = BurstSpread::new(period_s, whole_log, read);
        self.layer = Some(Box::new(TimingLayer::Bursts(spread)));
        self.eof = false;
        self.read_window(PERIOD_WINDOW);
    }

    /// Reads ahead until `lines` records are (fewer in a shorter log). An error reading
    /// is kept ([`Self::read_failed`]) for when the lines before it are given out: a
    /// layer begun on the lines read gives them out first ([`Self::next_raw`]). Before,
    /// a log of fewer lines than its first window whose reading failed at its end lost
    /// them all to the error.
    fn read_window(&mut self, lines: usize) {
        while self.ahead.len() < lines {
            match self.next_raw() {
                Ok(Some(s)) => self.ahead.push_back(s),
                Ok(None) => break,
                Err(e) => {
                    self.read_failed = Some(e);
                    break;
                }
            }
        }
    }

    /// Returns the next accepted sample, or `None` at the end, with its slot
    /// ([`TextSample::slot`]). A line written late or early alone, more than half a
    /// period off its slot while the next line is on the slot after, takes the middle of
    /// its neighbours' times ([`IngestReport::lines_off_slot`]); the sample after it is
    /// accepted first (the report counts it) to tell.
    pub fn next_sample(&mut self) -> Result<Option<TextSample>, FormatError> {
        if let Some(e) = self.failed.take() {
            return Err(e);
        }
        if self.given_t_s.is_none() && self.held.is_none() {
            self.held = self.next_accepted()?;
        }
        let Some(mut s) = self.held.take() else {
            self.gaps.end(&mut self.report);
            return Ok(None);
        };
        self.held = self.next_accepted().unwrap_or_else(|e| {
            self.failed = Some(e);
            None
        });
        s.t_s += self.report.text_clock_shift_s;
        if let Some(prev_t_s) = self.given_t_s {
            self.retime(&mut s, prev_t_s);
            self.count_interval(s.t_s - prev_t_s);
            s.slot = self.slot;
        }
        self.given_t_s = Some(s.t_s);
        if self.given_tags_s.len() == STEP_PHASE_LINES {
            self.given_tags_s.pop_front();
        }
        self.given_tags_s.push_back(s.t_s);
        Ok(Some(s))
    }

    /// Gives `s` (its time on the log's clock at its start so far, the line before it
    /// given out at `prev_t_s`) the middle of its neighbours' times when it was written
    /// off its slot alone ([`slot_time`]), or takes a step back of the log's clock out at it
    /// ([`clock_step_back_s`]), telling by the line after it ([`Self::held`]) and by
    /// where the slot clock puts the last line's slot.
    fn retime(&mut self, s: &mut TextSample, prev_t_s: f64) {
        let (Some(next), Some(clock)) = (self.held, self.clock) else {
            return;
        };
        let p = clock.period_s();
        let shift_s = self.report.text_clock_shift_s;
        let next_t_s = next.t_s + shift_s;
        let prev_slot_s = clock.slot_of(prev_t_s);
        if let Some(t_s) = slot_time(prev_slot_s, prev_t_s, s.t_s, next_t_s, p) {
            s.t_s = t_s;
            self.report.lines_off_slot += 1;
        } else if let Some(step_s) =
            clock_step_back_s(self.given_slots, prev_slot_s, s.t_s, next_t_s, p)
                .filter(|step_s| shift_s + step_s <= MAX_CLOCK_SHIFT_S)
        {
            self.take_clock_step(s, prev_t_s, step_s);
            self.report.text_clock_steps_back += 1;
        } else if s.t_s - prev_slot_s > 1.5 * p && s.t_s - prev_t_s <= self.gaps.max_gap_s() {
            // A gap the run bridges: lines lost, or the clock set forward (its slots'
            // phase moved).
            let mut after_s = vec![s.t_s];
            after_s.extend(
                self.tags_ahead_s(STEP_PHASE_LINES - 1)
                    .map(|t_s| t_s + shift_s),
            );
            let before_s = self.given_tags_s.make_contiguous();
            if let Some(step_s) = clock_step_forward_s(prev_slot_s, before_s, &after_s, p)
                .map(|forward_s| -forward_s)
                .filter(|step_s| shift_s + step_s >= -MAX_CLOCK_SHIFT_S)
            {
                self.take_clock_step(s, prev_t_s, step_s);
                self.report.text_clock_steps_forward += 1;
            }
        }
    }

    /// Takes a step of the log's clock out at `s` (the line given out before it at
    /// `prev_t_s`, both on the clock at its start so far): `step_s` added to its tag and
    /// every later one ([`IngestReport::text_clock_steps`]).
    fn take_clock_step(&mut self, s: &mut TextSample, prev_t_s: f64, step_s: f64) {
        let r = &mut self.report;
        if r.text_clock_steps.len() < TextClockStep::KEPT {
            r.text_clock_steps.push(TextClockStep {
                line: s.line,
                step_s,
                tag_s: s.t_s - r.text_clock_shift_s,
                tag_before_s: prev_t_s - r.text_clock_shift_s,
            });
        }
        r.text_clock_shift_s += step_s;
        s.t_s += step_s;
    }

    /// The tags of the next accepted sample ([`Self::held`]) and of up to `n − 1` lines
    /// read after it, as written (a line the reader will reject among them: a repeated
    /// one has its original's tag). Reads ahead as [`Self::prime`] does; an error reading
    /// is kept for when the lines before it are given out.
    fn tags_ahead_s(&mut self, n: usize) -> impl Iterator<Item = f64> + '_ {
        while self.held.is_some()
            && self.ahead.len() + 1 < n
            && !self.eof
            && self.read_failed.is_none()
        {
            match self.next_raw() {
                Ok(Some(s)) => self.ahead.push_back(s),
                Ok(None) => break,
                Err(e) => self.read_failed = Some(e),
            }
        }
        let ahead = self.ahead.iter().take(n.saturating_sub(1));
        self.held.iter().chain(ahead).map(|s| s.t_s)
    }

    /// Counts the interval `dt` (s) from the sample given out before: going back, or
    /// the slots it moved on on the slot clock, more than one a gap of lost samples
    /// ([`GapAccount`]).
    fn count_interval(&mut self, dt: f64) {
        if dt <= 0.0 {
            self.report.t_non_increasing += 1;
        }
        let slots = self.clock.as_mut().map_or(1, |c| c.step(dt));
        // (A tag of 1e300, a damaged line, is a gap of more samples than a u64 counts.)
        let lost = (self.clock)
            .filter(|_| slots >= 2)
            .map(|c| (slots - 1, c.period_s()));
        self.gaps.interval(&mut self.report, dt, lost);
        self.given_slots = slots;
        self.slot = self.slot.saturating_add(slots);
    }

    /// The next sample accepted (its time as written), or `None` at the end.
    fn next_accepted(&mut self) -> Result<Option<TextSample>, FormatError> {
        self.prime()?;
        loop {
            let s = match self.ahead.pop_front() {
                Some(s) => s,
                None => match self.next_raw()? {
                    Some(s) => s,
                    None => return Ok(None),
                },
            };
            self.report.records_read += 1;
            let key = resent_key(&s);
            let place = self.place(s.t_s);
            if let Some(prev) = self.prev {
                let repeated = || {
                    if key == resent_key(&prev) {
                        Some(prev.line)
                    } else if s.t_s < prev.t_s {
                        self.recent.seen(place?, &key)
                    } else {
                        None
                    }
                };
                if let Some(line) = repeated() {
                    self.report.rejected.duplicate_seq += 1;
                    self.faults.push_with(s.line, || {
                        format!(
                            "repeats line {line} (its time tag and values): a record sent \
                             again, or logs joined over the stretch they share"
                        )
                    });
                    continue;
                }
            }
            self.prev = Some(s);
            self.first_t_s.get_or_insert(s.t_s);
            if let Some(place) = place.or_else(|| self.place(s.t_s)) {
                self.recent.keep(place, key, s.line);
            }
            self.report.records_accepted += 1;
            self.report.imu_accepted += 1;
            return Ok(Some(s));
        }
    }

    /// A time's place in the log: its sample intervals from the first sample's time
    /// (`None` before the first, or without a period).
    fn place(&self, t_s: f64) -> Option<u64> {
        let intervals = (t_s - self.first_t_s?) / self.period_s?;
        // `as` saturates: a damaged tag's place is some slot, its key still its own.
        intervals
            .is_finite()
            .then(|| intervals.round() as i64 as u64)
    }
}

/// The periodogram's peaks [`first_slots`] runs a slot clock on, the strongest: the
/// period and, of a jitter repeating every few lines, the sidebands either side.
const CANDIDATE_PEAKS: usize = 5;

/// The slots of a log's first lines (`tags_s`, their median positive step `median_s`):
/// their period, and the first line's tag less its slot's time, s.
///
/// The lines are taken in stretches whose tags go on by up to 20 median steps (a tag
/// going back, leaping, or a clock set back parts them: across such a part the phases
/// would turn by the part's length times the period's error). The period is the one at
/// which the longest stretch's tags' phases agree best (the phasors `exp(2πi t / period)`
/// summed: lines lost do not move them, and a random jitter only shortens their sum),
/// searched within a quarter of the median step on a grid a thousandth of it apart, then
/// a twenty-thousandth about the best, and between that grid's points by the parabola
/// through the best and its neighbours (its half and its double, where tags on its slots
/// agree as well, are beyond). Of the grid's [`CANDIDATE_PEAKS`] strongest peaks, the
/// strongest is taken unless a slot clock started on another's slots misreads (reads as
/// lost, or early by half a period) at most half as many of the stretch's lines, and four
/// fewer. A jitter that repeats every few lines (a logger's polling beating with the
/// IMU's rate) gives the phasors side peaks a repetition's frequency either side of the
/// period's, stronger than it (0.3 of a period every 7 lines: at 0.875 and 1.17 of the
/// period, J₁ = 0.58 of the lines' count against J₀ = 0.31), where the clock misreads a
/// line a repetition; taken, Kingston so jittered read a line lost every 13 lines, or a
/// clock set back at every other line, and went "ok" hundreds of metres off. The first
/// line's slot is where the first stretch's phases agree at that period. The median
/// step is off the period by the jitter where lines were lost among the first, or where
/// they jitter (3 % with a third of a period of it over 100 lines), and a slot clock that
/// starts off its period by more than a few per cent slips a slot every few lines,
/// reading lines lost and clocks set back; one started on the first line's tag is off by
/// that line's jitter. The median and the first tag stand when the phases do not agree
/// (their sum under a fifth of the stretch's lines, and the clock misreading more than
/// one line in fifty), or over a stretch of fewer than eight lines. A log `lost_regularly`
/// ([`crate::text_ticks::TickReading::LinesLost`]) takes the strongest peak.
fn first_slots(tags_s: &[f64], median_s: f64, lost_regularly: bool) -> (f64, f64) {
    const STRETCH_STEPS: f64 = 20.0;
    let mut stretches: Vec<&[f64]> = Vec::new();
    let mut from = 0;
    for k in 1..=tags_s.len() {
        let parted = k == tags_s.len() || {
            let step_s = tags_s[k] - tags_s[k - 1];
            !(step_s > 0.0 && step_s <= STRETCH_STEPS * median_s)
        };
        if parted {
            stretches.push(&tags_s[from..k]);
            from = k;
        }
    }
    let Some(longest) = stretches.iter().copied().max_by_key(|s| s.len()) else {
        return (median_s, 0.0);
    };
    if longest.len() < 8 {
        return (median_s, 0.0);
    }
    // Phases from a stretch's middle line: their error from the period's grows with the
    // time from it.
    let sum = |tags_s: &[f64], period_s: f64| {
        let mid_s = tags_s[tags_s.len() / 2];
        let (length, phase) = phasor_sum(tags_s.iter().map(|&t_s| (t_s - mid_s) / period_s));
        (length, phase, mid_s)
    };
    // A stretch's first tag less its slot's time, its slots `period_s` apart where its
    // phases agree: `mid_s + phase + m period`.
    let first_late_s = |stretch: &[f64], period_s: f64| {
        let (_, phase, mid_s) = sum(stretch, period_s);
        let from_s = stretch[0] - mid_s - phase * period_s;
        from_s - (from_s / period_s).round() * period_s
    };
    let best_of = |candidates: &mut dyn Iterator<Item = f64>| {
        let mut best = (median_s, f64::NEG_INFINITY);
        for p in candidates {
            let (length, ..) = sum(longest, p);
            if length > best.1 {
                best = (p, length);
            }
        }
        best
    };
    // The coarse grid's peaks, the strongest first: of the strongest few, the one on
    // whose slots a slot clock reads the fewest of the stretch's lines as lost or early,
    // where the strongest's reads at least twice as many and four more.
    let grid: Vec<(f64, f64)> = (-250..=250)
        .map(|k| {
            let p = median_s * (1.0 + k as f64 * 1e-3);
            (p, sum(longest, p).0)
        })
        .collect();
    let mut peaks: Vec<(f64, f64)> = (1..grid.len() - 1)
        .filter(|&i| grid[i].1 >= grid[i - 1].1 && grid[i].1 > grid[i + 1].1)
        .map(|i| grid[i])
        .collect();
    peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
    let misread = |p: f64| {
        let mut clock = SlotClock::new(p, first_late_s(longest, p));
        let mut misread = 0usize;
        for w in longest.windows(2) {
            let from_slot = (w[1] - w[0] + (w[0] - clock.slot_of(w[0]))) / clock.period_s();
            misread += usize::from(!(0.5..1.5).contains(&from_slot));
            clock.step(w[1] - w[0]);
        }
        misread
    };
    let Some(&(strongest_s, _)) = peaks.first() else {
        return (median_s, 0.0);
    };
    // Another peak only where the strongest's slots misread many more lines: lines lost
    // or written off their slot are misread at the period too. Not for a log read as
    // losing lines regularly: its lost lines are a regular jitter's sidebands to the
    // phasors, and one line lost in five read at a period of five fourths of its step
    // (each line a slot, none lost) fewest.
    let coarse_s = if lost_regularly {
        strongest_s
    } else {
        let strongest_misread = misread(strongest_s);
        let (fewest_s, fewest) = (peaks.iter().take(CANDIDATE_PEAKS))
            .map(|&(p, _)| (p, misread(p)))
            .min_by_key(|&(_, n)| n)
            .unwrap_or((strongest_s, strongest_misread));
        if 2 * fewest <= strongest_misread && fewest + 4 <= strongest_misread {
            fewest_s
        } else {
            strongest_s
        }
    };
    const FINE_STEP: f64 = 5e-5;
    let (fine_s, length) =
        best_of(&mut (-20..=20).map(|k| coarse_s * (1.0 + k as f64 * FINE_STEP)));
    // The peak between its grid's neighbours, by the parabola through the three.
    let step_s = fine_s * FINE_STEP;
    let (before, after) = (
        sum(longest, fine_s - step_s).0,
        sum(longest, fine_s + step_s).0,
    );
    let curvature = before - 2.0 * length + after;
    let period_s = match 0.5 * (before - after) / curvature {
        shift if curvature < 0.0 && shift.abs() <= 1.0 => fine_s + shift * step_s,
        _ => fine_s,
    };
    // (A peak on whose slots the clock misreads no line in fifty agrees however weak:
    // a jitter repeating every 5 or 7 lines by 0.35 of a period leaves the period's an
    // eighth of the lines' count, and the median step is 12 % off.)
    let agree = sum(longest, period_s).0 >= 0.2 * longest.len() as f64
        || 50 * misread(period_s) <= longest.len();
    if !(agree && period_s.is_finite() && period_s > 0.0) {
        return (median_s, 0.0);
    }
    let late_s = first_late_s(stretches[0], period_s);
    (period_s, if late_s.is_finite() { late_s } else { 0.0 })
}

/// The time a line tagged `t_s` takes when it was written off its slot alone: the middle
/// of its neighbours' times (`prev_s`, as given out, and `next_s`) when it is more than
/// half a period of `period_s` off its slot (one period after the last line's,
/// `prev_slot_s` on the slot clock), lies between them and the next line is on the slot
/// after, to half a period; else `None`, its tag stands. (The middle, not the slot: the
/// clock lags a tag stream by its jitter's fraction, the neighbours do not.)
///
/// A logger that stamps its lines as they come writes one late now and then (or early,
/// after a late one). Kept, a line late by more than half a period read as a gap of a
/// sample lost before it (the derive scaled its increments: a turn's angle increment 1.6
/// times over) and its interval and the next gave their samples' rates over 1.6 and 0.4
/// periods. A tag going back, or past the next, is the derive's to repair; two lines off
/// together are left as written. Beside a gap of lines lost the reading is the tags':
/// a line early after the gap may read as one late with a line fewer lost. A line off by
/// its jitter (within half a period of its slot, however far from its neighbours' middle)
/// is no line off.
fn slot_time(prev_slot_s: f64, prev_s: f64, t_s: f64, next_s: f64, period_s: f64) -> Option<f64> {
    let slot_s = prev_slot_s + period_s;
    let next_on_slot = (next_s - slot_s - period_s).abs() < 0.5 * period_s;
    (next_on_slot && prev_s < t_s && t_s < next_s && (t_s - slot_s).abs() > 0.5 * period_s)
        .then_some(prev_s + 0.5 * (next_s - prev_s))
}

/// Seconds a text log's clock may be set back at once and be taken as a step: an hour
/// (a logger on local time over a change from summer time) and a second. Further back, the
/// lines after are left as written (the derive then names the tags that do not increase):
/// a log of two parts in the wrong order is no clock set back.
pub const MAX_CLOCK_STEP_BACK_S: f64 = 3601.0;

/// Seconds a text log's clock may be set back in all: a day. Beyond, a step is left as
/// written (the derive names the tags that do not increase), so that every tag given out
/// stays within a day of [`MAX_TAG_S`], timed to the nanosecond in an `i64`.
pub const MAX_CLOCK_SHIFT_S: f64 = 86_400.0;

/// How far a text log's clock was set back at a line tagged `t_s`, s, so that the line
/// takes its slot's time, one period of `period_s` after the last line's slot
/// (`prev_slot_s`, on the slot clock): when the line is less than half a period after
/// that slot (or before it), while the last line moved on by one slot (`prev_slots`) and
/// the next (`next_s`) goes on from this one at a period, to half a period (the logger's
/// clock set back by a time sync, or to standard time, while it logs), the next more than
/// a quarter of a period early of its slot on the clock as it was; else `None`. Every
/// later tag is moved by as much. A line alone off its slot is [`slot_time`]'s (tried
/// first); a line whose next does not go on from it (a tag repeated, going back alone),
/// or after a line that leapt forward alone, is the derive's to repair. A clock set
/// forward reads as lines lost, as it must without sequence numbers. A separate odometer
/// file and the manifest's control points are taken on the log's clock at its start
/// (what the tags are moved to). Judged against the slot clock, not the last line's tag,
/// a line early by its jitter after one late by its jitter (their interval short of half
/// a period by the two) is no step.
fn clock_step_back_s(
    prev_slots: u64,
    prev_slot_s: f64,
    t_s: f64,
    next_s: f64,
    period_s: f64,
) -> Option<f64> {
    let step_s = prev_slot_s + period_s - t_s;
    (t_s - prev_slot_s <= 0.5 * period_s
        && prev_slots == 1
        && (next_s - t_s - period_s).abs() < 0.5 * period_s
        && next_s - (prev_slot_s + 2.0 * period_s) < -0.25 * period_s
        && step_s <= MAX_CLOCK_STEP_BACK_S)
        .then_some(step_s)
}

/// Lines whose tags tell the phase of a text log's slots either side of a gap: the line
/// after the gap and the next 79, and the 80 before it ([`clock_step_forward_s`]).
const STEP_PHASE_LINES: usize = 80;

/// The phasors `exp(2πi x)` of positions `x` in periods, summed: the sum's length and
/// its angle in periods (within half of one). Lines on slots a period apart agree at the
/// same angle; a random jitter only shortens the sum.
fn phasor_sum(positions: impl IntoIterator<Item = f64>) -> (f64, f64) {
    let (mut cos, mut sin) = (0.0, 0.0);
    for x in positions {
        let angle = std::f64::consts::TAU * x;
        cos += angle.cos();
        sin += angle.sin();
    }
    (cos.hypot(sin), sin.atan2(cos) / std::f64::consts::TAU)
}

/// How far a text log's clock was set forward at a line tagged `after_s[0]` (the lines
/// after it `after_s[1..]`, the lines given out before it `before_s`, the last of them
/// on the slot clock's slot at `prev_slot_s`, all as written on the clock so far), s:
/// when the line moved on more than one and a half periods of `period_s` from the slot
/// clock's last slot, and the slots the lines after it agree on are more than a quarter
/// of a period off those the lines before agree on (the logger's clock set forward by a
/// time sync while it logs): the whole periods and the phase the slots moved by, no line
/// lost; else `None`, lines lost. Each side needs [`STEP_PHASE_LINES`] lines, their
/// phases agreeing (their mean vector at least 0.35 of their count).
///
/// A text log has no sequence numbers, and lines lost move the tags on by whole periods:
/// the IMU integrates over its own clock's, which runs on through them, so that the lines
/// after are on the slots before. A clock set forward moves them by its step, whole
/// periods and a phase. So does an IMU restarted after a pause, but it is down for
/// seconds; the rule is asked only across a gap the run bridges (the derive's
/// `max_gap_s`). A step of whole periods, to a quarter of a period, is lines lost, as
/// before (read as a gap, each filled from the rates either side).
///
/// The phases are fitted to both sides' lines at once, each side's offset and one drift
/// (the period's error, which turns the phases by its ratio to the period every period:
/// 0.2 % turns the two sides' mean phases 0.1 of a period apart over their 50 periods).
/// The lines' jitter then moves the two offsets' difference by √(8 / n) of its σ for n
/// lines a side: 0.045 of a period with a uniform jitter of up to a quarter of one (the
/// quarter 5.5 σ off). A jitter that moves with the gap (a logger's latency changed as it
/// lost lines) cannot be told from a step.
fn clock_step_forward_s(
    prev_slot_s: f64,
    before_s: &[f64],
    after_s: &[f64],
    period_s: f64,
) -> Option<f64> {
    // The line after it moved on from it by a gap too: the step, if any, is judged
    // there (a line alone on the slots before is no run to tell apart).
    if before_s.len() < STEP_PHASE_LINES
        || after_s.len() < STEP_PHASE_LINES
        || after_s[1] - after_s[0] > 1.5 * period_s
    {
        return None;
    }
    // Positions in periods from the last slot, each side's phases unwrapped about their
    // mean's (`None`: they do not agree).
    let at = |t_s: f64| (t_s - prev_slot_s) / period_s;
    let unwrapped = |tags_s: &[f64]| {
        let (length, mean) = phasor_sum(tags_s.iter().map(|&t_s| at(t_s)));
        if length < 0.35 * tags_s.len() as f64 {
            return None;
        }
        let points: Vec<(f64, f64)> = (tags_s.iter())
            .map(|&t_s| {
                let x = at(t_s);
                let off = x - mean;
                (x, mean + off - off.round())
            })
            .collect();
        Some(points)
    };
    let (before, after) = (unwrapped(before_s)?, unwrapped(after_s)?);
    let means = |points: &[(f64, f64)]| {
        let n = points.len() as f64;
        let (sx, sy) = (points.iter()).fold((0.0, 0.0), |(sx, sy), (x, y)| (sx + x, sy + y));
        (sx / n, sy / n)
    };
    let (mb, ma) = (means(&before), means(&after));
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (points, (mx, my)) in [(&before, mb), (&after, ma)] {
        for (x, y) in points {
            sxy += (x - mx) * (y - my);
            sxx += (x - mx) * (x - mx);
        }
    }
    let drift = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    // Each side's phase at position 0, and how far the slots moved.
    let (phase_before, phase_after) = (mb.1 - drift * mb.0, ma.1 - drift * ma.0);
    let moved = phase_after - phase_before - (phase_after - phase_before).round();
    // The first line's lateness from the slot after the last line's, as the lines before
    // put their slots.
    let late_s = after_s[0] - (prev_slot_s + (phase_before + 1.0) * period_s);
    if !(late_s > 0.5 * period_s && moved.abs() > 0.25) {
        return None;
    }
    // Only then, for what it costs: neither side's lines part into two runs on slots
    // apart (a step under half a period, which the slot clock follows as a jitter,
    // before the gap; a step among the lines after it): at no line do the phases of a
    // side's lines before it and from it on (their mean vectors' angles, about the
    // fitted slots) differ by more than four of their σ (from the lines' scatter about
    // the slots, at least a hundredth of a period).
    let offs = |points: &[(f64, f64)], phase: f64| -> Vec<f64> {
        (points.iter())
            .map(|(x, y)| {
                let off = y - (phase + drift * x);
                off - off.round()
            })
            .collect()
    };
    let (offs_before, offs_after) = (offs(&before, phase_before), offs(&after, phase_after));
    let squares: f64 = offs_before.iter().chain(&offs_after).map(|o| o * o).sum();
    let sigma = (squares / (offs_before.len() + offs_after.len() - 3) as f64)
        .sqrt()
        .max(0.01);
    let parted = |offs: &[f64]| {
        let phasor = |o: &f64| {
            let angle = std::f64::consts::TAU * o;
            (angle.cos(), angle.sin())
        };
        let add = |(c, s): (f64, f64), (dc, ds): (f64, f64)| (c + dc, s + ds);
        let total = offs.iter().map(phasor).fold((0.0, 0.0), add);
        let mut head = (0.0, 0.0);
        let n = offs.len();
        (1..n).any(|k| {
            head = add(head, phasor(&offs[k - 1]));
            let tail = (total.0 - head.0, total.1 - head.1);
            let turn = (head.1.atan2(head.0) - tail.1.atan2(tail.0)) / std::f64::consts::TAU;
            let apart = (turn - turn.round()).abs();
            let (a, b) = (k as f64, (n - k) as f64);
            apart > 4.0 * sigma * (1.0 / a + 1.0 / b).sqrt()
        })
    };
    if parted(&offs_before) || parted(&offs_after) {
        return None;
    }
    let whole = (late_s / period_s - moved).round();
    let step_s = (whole + moved) * period_s;
    (step_s.is_finite() && step_s > 0.0).then_some(step_s)
}

/// What makes a text line the same as another: its time and values, bit for bit.
fn resent_key(s: &TextSample) -> [u64; 7] {
    let [a, b, c] = s.dtheta_rad.map(f64::to_bits);
    let [d, e, f] = s.dvel_mps.map(f64::to_bits);
    [s.t_s.to_bits(), a, b, c, d, e, f]
}

/// One odometer sample of a separate file, converted to cumulative distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometerSample {
    /// Time, s, in the IMU log's time base.
    pub t_s: f64,
    /// Cumulative distance from the first sample, m.
    pub distance_m: f64,
}

/// A two-column line's time and value, or why it is not one: a line of more numbers is
/// named a file of that many columns, whose value's column `[odometer] value_column`
/// names.
fn two_numbers(text: &str) -> Result<[f64; 2], String> {
    let mut values = [0f64; 2];
    let mut n = 0;
    // Whether the first two fields are numbers, and all the fields.
    let (mut leading, mut finite) = (true, true);
    for field in text
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|f| !f.is_empty())
        .take(MAX_VALUE_COLUMN + 1)
    {
        match field.parse::<f64>() {
            Ok(v) if v.is_finite() && n < 2 => values[n] = v,
            Ok(v) if v.is_finite() => {}
            _ => {
                leading &= n >= 2;
                finite = false;
            }
        }
        n += 1;
    }
    if n == 2 && finite {
        return Ok(values);
    }
    let hint = if has_decimal_commas(text) {
        DECIMAL_COMMA_HINT.to_owned()
    } else if n > 2 && leading {
        let n = if n > MAX_VALUE_COLUMN {
            format!("more than {MAX_VALUE_COLUMN}")
        } else {
            n.to_string()
        };
        format!(
            " (a file of {n} columns? name the value's in the manifest's [odometer] \
             value_column: 2 for the second, the time being the first)"
        )
    } else {
        String::new()
    };
    Err(format!(
        "expected two numbers `t_s value`, got {text:?}{hint}"
    ))
}

/// A line's time (its first column) and the value of its `column` (1-based), the other
/// columns left unread, or why it has none: split at its commas when it has one (a
/// CSV's empty fields count), else at its spaces.
fn time_and_column(text: &str, column: usize) -> Result<[f64; 2], String> {
    // One pass over the line: the time, then the value `column - 2` fields on (`column`
    // is 2 or more: the time is the first).
    let mut fields = line_fields(text);
    let number = |f: Option<&str>| {
        f.and_then(|f| f.parse::<f64>().ok())
            .filter(|v| v.is_finite())
    };
    let t = number(fields.next());
    match (t, number(fields.nth(column.saturating_sub(2)))) {
        (Some(t), Some(v)) => Ok([t, v]),
        _ => {
            let hint = if has_decimal_commas(text) {
                DECIMAL_COMMA_HINT
            } else {
                ""
            };
            Err(format!(
                "expected the time in column 1 and the value in column {column} \
                 ([odometer] value_column), got {text:?}{hint}"
            ))
        }
    }
}

/// A line's fields, each trimmed: split at its commas when it has one (a CSV's empty
/// fields count), else at its spaces.
fn line_fields(text: &str) -> impl Iterator<Item = &str> {
    let comma = text.contains(',');
    text.split(move |c: char| if comma { c == ',' } else { c.is_whitespace() })
        .map(str::trim)
        .filter(move |f| comma || !f.is_empty())
}

/// The column (1-based) that a header line `text` names `name` (its fields as
/// [`line_fields`] gives them, each trimmed of double quotes and spaces), or why
/// there is none: the name absent (the line's names listed), the time's column, beyond
/// [`MAX_VALUE_COLUMN`], or a line of numbers.
fn header_column(text: &str, name: &str) -> Result<usize, String> {
    let fields: Vec<&str> = line_fields(text)
        .map(|f| f.trim_matches('"').trim())
        .collect();
    let wanted = format!(
        "[odometer] value_column = {name:?} names the value's column on the file's header \
         line"
    );
    match fields.iter().position(|f| *f == name) {
        Some(0) => Err(format!(
            "{wanted}, and the header gives that name to column 1, the time's"
        )),
        Some(i) if i < MAX_VALUE_COLUMN => Ok(i + 1),
        Some(i) => Err(format!(
            "{wanted}, and the header gives it to column {}, beyond {MAX_VALUE_COLUMN}",
            i + 1
        )),
        None if fields.first().is_some_and(|f| f.parse::<f64>().is_ok()) => Err(format!(
            "{wanted}, and the file's first line holds numbers, no names ({}): name the \
             column by its number (2 for the second, the time being the first)",
            shown(text)
        )),
        None => {
            const LISTED: usize = 16;
            let mut names: Vec<String> = fields.iter().take(LISTED).map(|f| shown(f)).collect();
            if fields.len() > LISTED {
                names.push(format!("… {} in all", fields.len()));
            }
            Err(format!(
                "{wanted}, and its header line names none so: its columns are {}",
                names.join(", ")
            ))
        }
    }
}

/// `text` quoted for a message, at most 40 characters of it.
fn shown(text: &str) -> String {
    match text.char_indices().nth(40) {
        Some((end, _)) => format!("{:?}…", &text[..end]),
        None => format!("{text:?}"),
    }
}

/// Fastest a land vehicle's odometer may say it went, m/s (360 km/h): a speed beyond it
/// is a corrupt reading, and a step of distance beyond it a corrupt count.
pub const LAND_SPEED_RANGE_MPS: f64 = 100.0;

/// A speed file's line on its way to its verdict: its number, and its time, s, and speed,
/// m/s, or why it was rejected as it was read (`None` once the faults kept are full: the
/// reasons held stay within [`FaultLog::KEPT`]).
type SpeedLine = (u64, Result<(f64, f64), Option<String>>);

/// Streaming reader of a two-column odometer file (`t_s value`), giving cumulative
/// distance, with accounting ([`OdometerFileReport`]).
///
/// Speed is integrated with the trapezoidal rule. Lines that are not two finite numbers,
/// go back in time or give a speed beyond [`LAND_SPEED_RANGE_MPS`] are rejected, counted
/// and (the first 1000) returned as faults with their line; the rest is kept. Speeds that
/// jump faster than a land vehicle's and come back ([`crate::speed_spikes`]) are rejected
/// the same way, their reason saying so. Memory is bounded by one line, and by a burst's
/// readings while one is open, whatever the file.
pub struct OdometerFileReader<R: BufRead> {
    lines: LineReader<R>,
    kind: OdometerKind,
    report: OdometerFileReport,
    faults: FaultLog,
    /// Time and value of the last accepted line, and its distance, m.
    prev: Option<(f64, f64, f64)>,
    /// Time of the last line kept, s (times must advance).
    last_t_s: Option<f64>,
    /// The last line read that passed its own checks (line, time s, value in SI),
    /// judged against the next such line: a tag that leapt forward alone, the next
    /// going on from the line before it, is the glitch, not the lines after it.
    pending: Option<(u64, f64, f64)>,
    /// A line read past `pending` to judge the file's first line, read next.
    queued: Option<(u64, f64, f64)>,
    /// A speed file's lines, in order, to their verdicts.
    spikes: SpeedSpikes<SpeedLine>,
    /// Reasons held in `spikes`.
    held_reasons: usize,
    /// The time tags over GPS-week and day rollovers.
    tags: TagUnwrap,
    /// A speed file's floor (`[odometer] speed_floor_mps`), applied to the speeds kept.
    floor: Option<SpeedFloor>,
    /// The value's column, 1-based, in a file of more columns (`[odometer]
    /// value_column`); `None`: two columns, `t_s value`.
    value_column: Option<usize>,
    /// The value's column's name on the file's header line, its first line of text, until
    /// that line is read (`value_column` then holds its number).
    value_header: Option<String>,
    /// The log's clock steps, followed where the file's tags show them
    /// ([`Self::on_log_clock`]).
    log_clock: Option<FollowedSteps>,
}

/// Highest column `[odometer] value_column` may name: an OBD-II logger's CSV has tens.
pub const MAX_VALUE_COLUMN: usize = 64;

impl<R: BufRead> OdometerFileReader<R> {
    /// Wraps a buffered source holding values of `kind`.
    pub fn new(src: R, kind: OdometerKind) -> Self {
        Self {
            lines: LineReader::new(src),
            kind,
            report: OdometerFileReport::default(),
            faults: FaultLog::default(),
            prev: None,
            last_t_s: None,
            pending: None,
            queued: None,
            spikes: SpeedSpikes::default(),
            held_reasons: 0,
            tags: TagUnwrap::default(),
            floor: None,
            value_column: None,
            value_header: None,
            log_clock: None,
        }
    }

    /// A file written on the log's clock, set back or forward while it logged by `steps`
    /// (the log's, in order; [`IngestReport::text_clock_steps`]): its tags are moved by
    /// each step they show, onto the log's clock at its start ([`FollowedSteps`]; counted
    /// in [`OdometerFileReport::clock_steps_followed`] and `clock_steps_not_shown`).
    /// Without it, or with no step, every tag as written.
    pub fn on_log_clock(mut self, steps: &[TextClockStep]) -> Self {
        self.log_clock = (!steps.is_empty()).then(|| FollowedSteps::new(steps));
        self
    }

    /// The value read from `column` (1-based, 2 to [`MAX_VALUE_COLUMN`]; the time is the
    /// first) of lines of that many columns or more, the others left unread (an OBD-II
    /// logger's CSV: time, speed, engine speed, …); `None`, as without it: lines of two
    /// numbers. A line with a comma is split at its commas, its empty fields counted (a
    /// CSV's missing reading), else at its spaces.
    pub fn with_value_column(mut self, column: Option<usize>) -> Self {
        self.value_column = column.filter(|c| (2..=MAX_VALUE_COLUMN).contains(c));
        self
    }

    /// The value read from the column the file's header line (its first line that is
    /// neither blank nor a comment) names `name` (`[odometer] value_column = "speed_mps"`),
    /// as [`Self::with_value_column`] reads a column by number; the header line is
    /// rejected as such. A file whose first line names no such column, or holds numbers,
    /// fails, naming its line and columns. `None`: unset.
    pub fn with_value_header(mut self, name: Option<&str>) -> Self {
        self.value_header = name.map(str::to_owned);
        self
    }

    /// Its first time tag taken beside the IMU log's first, `log_first_s` (as written):
    /// a file begun within an hour after a GPS week's or a day's end where the log began
    /// within an hour before it has the period added to its tags (counted in
    /// `week_rollovers` or `day_rollovers`); begun within the hour before where the log
    /// began within the hour after, the period taken from its tags up to its own
    /// rollover. Without it, a logger started a minute after the IMU's across midnight in
    /// seconds of day had tags a day apart from the log's.
    pub fn beside_log_from(mut self, log_first_s: Option<f64>) -> Self {
        self.tags.log_first_s = log_first_s;
        self
    }

    /// Speeds kept below `floor_mps` in magnitude read as 0 (`None`, or a distance
    /// file: every value as written).
    pub fn with_speed_floor(mut self, floor_mps: Option<f64>) -> Self {
        self.floor = floor_mps
            .filter(|_| self.kind.is_speed())
            .map(SpeedFloor::new);
        self
    }

    /// What the speed floor took away so far (`None` without one).
    pub fn speed_floor(&self) -> Option<SpeedFloorReport> {
        self.floor.as_ref().map(SpeedFloor::report)
    }

    /// The accounting so far (final after the last sample).
    pub fn report(&self) -> &OdometerFileReport {
        &self.report
    }

    /// The first 1000 line faults and their total count.
    pub fn faults(&self) -> (&[LineFault], u64) {
        (&self.faults.kept, self.faults.total)
    }

    /// A speed file's readings left out as spikes, and its jumps kept (the speed did not
    /// come back), so far.
    pub fn spikes(&self) -> (u64, u64) {
        (self.spikes.spikes, self.spikes.jumps_kept)
    }

    /// The line `line` rejected, its reason written only when it is kept.
    fn reject(&mut self, line: u64, reason: impl FnOnce() -> String) {
        self.report.lines_rejected += 1;
        self.faults.push_with(line, reason);
    }

    /// A line rejected as it was read: at once for distances, in its place among the
    /// speeds' verdicts.
    fn reject_read(&mut self, reason: String) {
        self.reject_read_at(self.lines.line_no, reason);
    }

    /// As [`Self::reject_read`], for line `line` (read before the current one).
    fn reject_read_at(&mut self, line: u64, reason: String) {
        if self.kind.is_speed() {
            let kept = self.faults.kept.len() + self.held_reasons < FaultLog::KEPT;
            self.held_reasons += usize::from(kept);
            self.spikes.push(None, (line, Err(kept.then_some(reason))));
        } else {
            self.reject(line, || reason);
        }
    }

    /// A line kept: its distance, m, from the last kept.
    fn accept(&mut self, t: f64, v: f64) -> OdometerSample {
        let v = match &mut self.floor {
            Some(floor) => floor.read(t, v),
            None => v,
        };
        let distance_m = match (self.kind.is_speed(), self.prev) {
            (false, _) => v,
            (true, Some((pt, pv, pd))) => pd + 0.5 * (pv + v) * (t - pt),
            (true, None) => 0.0,
        };
        self.prev = Some((t, v, distance_m));
        self.report.lines_accepted += 1;
        OdometerSample { t_s: t, distance_m }
    }

    /// Returns the next accepted sample, or `None` at the end.
    pub fn next_sample(&mut self) -> Result<Option<OdometerSample>, FormatError> {
        loop {
            while let Some(((line, read), verdict)) = self.spikes.pop() {
                match (read, verdict) {
                    (Err(Some(reason)), _) => {
                        self.held_reasons -= 1;
                        self.reject(line, || reason);
                    }
                    // Not held: the faults kept were full, as they are now.
                    (Err(None), _) => self.reject(line, String::new),
                    (Ok((t, v)), Verdict::Spike(from)) => {
                        // In the file's unit.
                        let kind = self.kind;
                        self.reject(line, || match from {
                            Some((t0, v0)) => format!(
                                "speed {} at {t} s left out: it jumped from {} at {t0} s \
                                 faster than a land vehicle brakes or accelerates \
                                 ({MAX_BRAKING_MPS2} and {MAX_ACCEL_MPS2} m/s²) and came \
                                 back (a spike)",
                                kind.as_written(v),
                                kind.as_written(v0)
                            ),
                            None => format!(
                                "speed {} at {t} s left out: the readings after it, the \
                                 first of the file, jump from it faster than a land vehicle \
                                 brakes or accelerates (a spike)",
                                kind.as_written(v)
                            ),
                        })
                    }
                    (Ok((t, v)), _) => return Ok(Some(self.accept(t, v))),
                }
            }
            match self.read_line()? {
                Some((_, t, v)) if !self.kind.is_speed() => {
                    return Ok(Some(self.accept(t, v)));
                }
                Some((line, t, v)) => self.spikes.push(Some((t, v)), (line, Ok((t, v)))),
                None if self.spikes.is_finished() => return Ok(None),
                None => self.spikes.finish(),
            }
        }
    }

    /// The next line kept: its number, time and value, its checks passed and its time
    /// after the last kept; lines that fail them are rejected on the way. A line whose
    /// time leapt forward alone (the next line's time lies between the last kept and
    /// it; for the file's first line, the next two lines' times, in order) is rejected,
    /// not the lines after it: kept, it would have every line up to its time rejected as
    /// not after it, and the odometer bridged over them. `None` at the end.
    fn read_line(&mut self) -> Result<Option<(u64, f64, f64)>, FormatError> {
        loop {
            let next = match self.queued.take() {
                Some(queued) => Some(queued),
                None => self.read_checked()?,
            };
            let Some(held) = self.pending.take() else {
                match next {
                    Some(next) => self.pending = Some(next),
                    None => return Ok(None),
                }
                continue;
            };
            let Some(next) = next else {
                self.last_t_s = Some(held.1);
                return Ok(Some(held));
            };
            if next.1 > held.1 {
                self.pending = Some(next);
                self.last_t_s = Some(held.1);
                return Ok(Some(held));
            }
            match self.last_t_s {
                Some(kept_t) if kept_t < next.1 && next.1 < held.1 => {
                    self.reject_read_at(
                        held.0,
                        format!(
                            "time {} leaps ahead of the lines about it ({kept_t} before, \
                             {} after): a glitch in its time tag",
                            held.1, next.1
                        ),
                    );
                    self.pending = Some(next);
                }
                Some(_) => {
                    self.reject_read_at(next.0, format!("time {} is not after {}", next.1, held.1));
                    self.pending = Some(held);
                }
                None => {
                    // The first line: the line after the next tells which of the two
                    // is out of order.
                    let after = self.read_checked()?;
                    self.queued = after;
                    match after {
                        Some(after) if next.1 < after.1 && after.1 < held.1 => {
                            self.reject_read_at(
                                held.0,
                                format!(
                                    "time {} leaps ahead of the lines after it ({} and \
                                     {}), no line kept before it: a glitch in its time tag",
                                    held.1, next.1, after.1
                                ),
                            );
                            self.pending = Some(next);
                        }
                        _ => {
                            self.reject_read_at(
                                next.0,
                                format!("time {} is not after {}", next.1, held.1),
                            );
                            self.pending = Some(held);
                        }
                    }
                }
            }
        }
    }

    /// The next line that passes its own checks (its number, time and value), whatever
    /// its time against the lines before it; lines that fail them are rejected on the
    /// way. `None` at the end.
    fn read_checked(&mut self) -> Result<Option<(u64, f64, f64)>, FormatError> {
        while let Some(line) = self.lines.next_line()? {
            let Some(record) = line.record() else {
                continue;
            };
            self.report.lines_read += 1;
            let text = match record {
                Ok(text) => text,
                Err(reason) => {
                    self.reject_read(reason);
                    continue;
                }
            };
            if let Some(name) = self.value_header.take() {
                let column = header_column(text, &name).map_err(|reason| FormatError::Line {
                    line: self.lines.line_no,
                    reason,
                })?;
                self.value_column = Some(column);
                self.reject_read(format!(
                    "the file's header line (its columns' names): {name:?} is column {column} \
                     ([odometer] value_column)"
                ));
                continue;
            }
            let read = match self.value_column {
                None => two_numbers(text),
                Some(column) => time_and_column(text, column),
            };
            let [t, given] = match read {
                Ok(values) => values,
                Err(reason) => {
                    self.reject_read(reason);
                    continue;
                }
            };
            if let Some(reason) = tag_beyond_range(t) {
                self.reject_read(reason);
                continue;
            }
            let t = self.tags.unwrap(t);
            let r = &mut self.report;
            self.tags.count(&mut r.week_rollovers, &mut r.day_rollovers);
            if let Some(reason) = tag_beyond_range(t) {
                self.reject_read(reason);
                continue;
            }
            let t = match &mut self.log_clock {
                Some(clock) => {
                    let t = clock.time_s(t);
                    r.clock_steps_followed = clock.followed();
                    r.clock_steps_not_shown = clock.not_shown();
                    t
                }
                None => t,
            };
            // m/s or m from here on.
            let v = self.kind.si(given);
            if self.kind.is_speed() && v.abs() > LAND_SPEED_RANGE_MPS {
                let unit = self.kind.unit();
                self.reject_read(format!(
                    "speed {} {unit} is beyond a land vehicle's ({LAND_SPEED_RANGE_MPS} m/s)",
                    // 1e300 as such, not as 301 digits.
                    if given.abs() < 1e6 {
                        format!("{given}")
                    } else {
                        format!("{given:e}")
                    }
                ));
                continue;
            }
            return Ok(Some((self.lines.line_no, t, v)));
        }
        Ok(None)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A log in GPS seconds of week running over the rollover: its tags go on a week
    /// later, counted once; the odometer file's too. A step back that is no rollover
    /// (not from the week's last hour to its first) is a tag not after the one before.
    #[test]
    fn time_tags_over_a_gps_weeks_rollover_go_on() {
        let tags = [604_799.8, 604_799.9, 0.0, 0.1, 0.2];
        let text: String = tags.iter().map(|t| format!("{t} 1 2 3 4 5 6\n")).collect();
        let (v, rep, _) = read_all(&text);
        let t: Vec<f64> = v.iter().map(|s| s.t_s).collect();
        assert_eq!(t, [604_799.8, 604_799.9, 604_800.0, 604_800.1, 604_800.2]);
        assert_eq!((rep.week_rollovers, rep.t_non_increasing), (1, 0));
        assert!(rep.is_consistent(), "{rep:?}");

        let mut odo =
            OdometerFileReader::new(&b"604799 1.0\n0 1.0\n1 2.0\n"[..], OdometerKind::SpeedMps);
        let mut samples = Vec::new();
        while let Some(s) = odo.next_sample().unwrap() {
            samples.push(s);
        }
        let t: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
        assert_eq!(t, [604_799.0, 604_800.0, 604_801.0], "{:?}", odo.faults());
        assert_eq!(odo.report().week_rollovers, 1);
        assert!((samples[2].distance_m - 2.5).abs() < 1e-12);

        // Rollovers by turns, without end: their weeks pass the span kept, and the lines
        // past it are rejected, not saturated.
        let turns: String = (0..40_000)
            .map(|k| {
                if k % 2 == 0 {
                    "604799.5 1 2 3 4 5 6\n"
                } else {
                    "0.5 1 2 3 4 5 6\n"
                }
            })
            .collect();
        let (v, rep, _) = read_all(&turns);
        assert!(v.iter().all(|s| s.t_s.abs() <= MAX_TAG_S), "{:?}", v.last());
        assert_eq!(rep.week_rollovers, 20_000);
        assert!(v.len() < 40_000 && rep.is_consistent(), "{rep:?}");
        let turns = turns.replace(" 1 2 3 4 5 6", " 1.0");
        let mut odo = OdometerFileReader::new(turns.as_bytes(), OdometerKind::SpeedMps);
        let mut last_s = 0.0;
        while let Some(s) = odo.next_sample().unwrap() {
            last_s = s.t_s;
        }
        assert!(last_s > 0.0 && last_s <= MAX_TAG_S, "{last_s}");
        assert!(odo.report().lines_rejected > 0, "{:?}", odo.report());
        for tags in [[600_000.0, 0.5], [604_799.0, 3_600.0]] {
            let text: String = tags.iter().map(|t| format!("{t} 1 2 3 4 5 6\n")).collect();
            let (v, rep, _) = read_all(&text);
            assert_eq!(v[1].t_s, tags[1]);
            assert_eq!((rep.week_rollovers, rep.t_non_increasing), (0, 1));
        }
    }

    /// A log in UTC seconds of day running over midnight: its tags go on a day later,
    /// counted, the odometer file's too; twice over two midnights. A log in seconds of
    /// week runs through a day's end without a step back, and stays as written.
    #[test]
    fn time_tags_over_a_days_rollover_go_on() {
        let tags = [86_399.8, 86_399.9, 0.0, 0.1];
        let text: String = tags.iter().map(|t| format!("{t} 1 2 3 4 5 6\n")).collect();
        let (v, rep, _) = read_all(&text);
        let t: Vec<f64> = v.iter().map(|s| s.t_s).collect();
        assert_eq!(t, [86_399.8, 86_399.9, 86_400.0, 86_400.1]);
        assert_eq!((rep.day_rollovers, rep.week_rollovers), (1, 0));
        assert_eq!(rep.t_non_increasing, 0);

        let mut odo = OdometerFileReader::new(
            &b"86399 1.0\n0 1.0\n86399 1.0\n1 1.0\n"[..],
            OdometerKind::SpeedMps,
        );
        let mut t = Vec::new();
        while let Some(s) = odo.next_sample().unwrap() {
            t.push(s.t_s);
        }
        assert_eq!(t, [86_399.0, 86_400.0, 172_799.0, 172_801.0]);
        assert_eq!(odo.report().day_rollovers, 2);

        let week_s: String = [86_399.9, 86_400.0, 86_400.1]
            .iter()
            .map(|t| format!("{t} 1 2 3 4 5 6\n"))
            .collect();
        let (v, rep, _) = read_all(&week_s);
        assert_eq!(v[2].t_s, 86_400.1);
        assert_eq!(rep.day_rollovers, 0);
    }

    /// A speed or distance line whose time tag leapt forward alone (the next line goes
    /// on from the line before it; for the first line, the next two in order) is the
    /// line rejected, naming its leap, and the lines after it are kept; its fault takes
    /// its place among a malformed line's after it. A step back that lasts (two lines
    /// going on from below the last kept) is still the lines after it rejected. Before,
    /// the line that leapt was kept and every line up to its time rejected.
    #[test]
    fn a_time_tag_that_leapt_forward_alone_is_the_line_rejected() {
        let read = |text: &str, kind| {
            let mut odo = OdometerFileReader::new(text.as_bytes(), kind);
            let mut t = Vec::new();
            while let Some(s) = odo.next_sample().unwrap() {
                t.push((s.t_s, s.distance_m));
            }
            let faults: Vec<(u64, String)> = (odo.faults().0.iter())
                .map(|f| (f.line, f.reason.clone()))
                .collect();
            let r = odo.report();
            assert_eq!(r.lines_read, r.lines_accepted + r.lines_rejected, "{r:?}");
            (t, faults)
        };
        let (t, faults) = read("0 1\n1 1\n60 1\n2 1\n3 1\n", OdometerKind::SpeedMps);
        assert_eq!(t, [(0.0, 0.0), (1.0, 1.0), (2.0, 2.0), (3.0, 3.0)]);
        assert_eq!(faults.len(), 1);
        assert_eq!(faults[0].0, 3);
        assert!(
            faults[0]
                .1
                .contains("time 60 leaps ahead of the lines about it (1 before, 2 after)"),
            "{faults:?}"
        );
        let (t, faults) = read("0 5\n1 6\n60 7\nx\n2 8\n", OdometerKind::DistanceM);
        assert_eq!(t, [(0.0, 5.0), (1.0, 6.0), (2.0, 8.0)]);
        let lines: Vec<u64> = faults.iter().map(|f| f.0).collect();
        assert_eq!(lines, [3, 4], "{faults:?}");
        let (t, faults) = read("60 1\n1 1\n2 1\n", OdometerKind::SpeedMps);
        assert_eq!(t, [(1.0, 0.0), (2.0, 1.0)]);
        assert_eq!(faults.len(), 1);
        assert!(
            faults[0].0 == 1
                && faults[0].1.contains(
                    "time 60 leaps ahead of the lines after it (1 and 2), no line kept before it"
                ),
            "{faults:?}"
        );
        // The first line kept when the next goes back alone.
        let (t, faults) = read("5 1\n1 1\n6 1\n", OdometerKind::SpeedMps);
        assert_eq!(t, [(5.0, 0.0), (6.0, 1.0)]);
        assert!(faults.len() == 1 && faults[0].0 == 2, "{faults:?}");
        // A tag repeated: the second line rejected.
        let (t, faults) = read("0 1\n1 1\n1 2\n2 1\n", OdometerKind::SpeedMps);
        assert_eq!(t.iter().map(|s| s.0).collect::<Vec<_>>(), [0.0, 1.0, 2.0]);
        assert!(faults.len() == 1 && faults[0].0 == 3, "{faults:?}");
        let (t, faults) = read("0 1\n1 1\n2 1\n0.5 1\n0.6 1\n3 1\n", OdometerKind::SpeedMps);
        assert_eq!(
            t.iter().map(|s| s.0).collect::<Vec<_>>(),
            [0.0, 1.0, 2.0, 3.0]
        );
        let lines: Vec<u64> = faults.iter().map(|f| f.0).collect();
        assert_eq!(lines, [4, 5], "{faults:?}");
    }

    /// An odometer file begun across midnight (or the week's end) from its log: after
    /// the log's first tag (within the hour each side), a day on, counted; before it, a
    /// day back until its own rollover. Begun on the log's side, or hours apart, as
    /// written.
    #[test]
    fn a_file_begun_across_midnight_from_its_log_is_taken_on_the_logs_side() {
        let tags = |text: &[u8], log_first_s: f64| {
            let mut odo = OdometerFileReader::new(text, OdometerKind::SpeedMps)
                .beside_log_from(Some(log_first_s));
            let mut t = Vec::new();
            while let Some(s) = odo.next_sample().unwrap() {
                t.push(s.t_s);
            }
            (t, odo.report().day_rollovers, odo.report().week_rollovers)
        };
        let after = b"10 0\n11 0\n";
        assert_eq!(tags(after, 86_370.0), (vec![86_410.0, 86_411.0], 1, 0));
        assert_eq!(tags(after, 604_790.0), (vec![604_810.0, 604_811.0], 0, 1));
        let before = b"86398 0\n86399 0\n1 0\n";
        assert_eq!(tags(before, 5.0), (vec![-2.0, -1.0, 1.0], 1, 0));
        assert_eq!(tags(after, 5.0), (vec![10.0, 11.0], 0, 0));
        assert_eq!(tags(after, 70_000.0), (vec![10.0, 11.0], 0, 0));
    }

    pub(crate) fn read_all(text: &str) -> (Vec<TextSample>, IngestReport, Vec<LineFault>) {
        let mut r = KfGinsReader::new(text.as_bytes());
        let mut v = Vec::new();
        while let Some(s) = r.next_sample().unwrap() {
            v.push(s);
        }
        (v, r.report().clone(), r.faults().0.to_vec())
    }

    #[test]
    fn reads_seven_columns_and_counts_faults() {
        let text = "# header\n0.01 1 2 3 4 5 6\n0.02 1 2 3 4 5 6\n0.03 x 2 3 4 5 6\n0.03 1 2 3\n\n0.03 1 2 3 4 5 6\n0.05 1 2 3 4 5 6\n";
        let (v, rep, faults) = read_all(text);
        assert_eq!(v.len(), 4);
        assert_eq!(rep.rejected.malformed_line, Some(2));
        assert_eq!(rep.lost_samples, 1);
        assert_eq!(
            faults.iter().map(|f| f.line).collect::<Vec<_>>(),
            vec![4, 5]
        );
        assert!(rep.is_consistent(), "{rep:?}");
    }

    /// The lines of a 7-column log at `tags_s`, each line's increments its own (a line
    /// of another's tag and increments is a line sent again).
    fn log_at(tags_s: &[f64]) -> String {
        (tags_s.iter().enumerate())
            .map(|(k, t)| format!("{t:.6} {k} 2 3 4 5 6\n"))
            .collect()
    }

    /// A line written 0.7 of a period late and one 0.7 early, each between lines on
    /// time, take their slots' times and are counted; neither is a gap, while a line
    /// lost (at 0.08 s) is one, and a line 0.4 of a period off keeps its tag. Before, the
    /// late line closed a gap of one sample lost and the derive scaled its increments.
    #[test]
    fn a_line_written_late_or_early_alone_takes_its_slot() {
        let tags = [
            0.0, 0.01, 0.027, 0.03, 0.04, 0.043, 0.06, 0.07, 0.09, 0.10, 0.114, 0.12,
        ];
        let (v, rep, _) = read_all(&log_at(&tags));
        let got: Vec<f64> = v.iter().map(|s| s.t_s).collect();
        let want = [
            0.0, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.09, 0.10, 0.114, 0.12,
        ];
        assert!(
            got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-12),
            "{got:?}"
        );
        assert_eq!(
            (rep.lines_off_slot, rep.seq_gaps, rep.lost_samples),
            (2, 1, 1)
        );
        assert_eq!((rep.records_accepted, rep.t_non_increasing), (12, 0));
        assert!(
            rep.lines_off_slot_said()
                .unwrap()
                .starts_with("2 lines written late")
        );
        assert!(rep.is_consistent(), "{rep:?}");
    }

    /// A line off beside a gap (its neighbours three periods apart), and a line whose tag
    /// goes back or past the next (the derive's to repair), keep their tags: which slot
    /// such a line holds cannot be told from the lines lost.
    #[test]
    fn a_line_off_beside_a_gap_or_past_its_neighbour_keeps_its_tag() {
        // Lines on time after them: the period is the median interval.
        let on_time = |tags: &[f64]| {
            let mut tags = tags.to_vec();
            tags.extend((7..20).map(|k| k as f64 * 0.01));
            tags
        };
        let (v, rep, _) = read_all(&log_at(&on_time(&[0.0, 0.01, 0.027, 0.04, 0.05])));
        assert_eq!(v[2].t_s, 0.027);
        assert_eq!((rep.lines_off_slot, rep.lost_samples), (0, 2));
        let tags = on_time(&[0.0, 0.01, 0.005, 0.03, 0.04, 0.065, 0.06]);
        let (v, rep, _) = read_all(&log_at(&tags));
        let got: Vec<f64> = v.iter().map(|s| s.t_s).collect();
        assert_eq!(got, tags);
        assert_eq!((rep.lines_off_slot, rep.t_non_increasing), (0, 2));
    }

    /// A logger whose lines jitter at random by up to a tenth of a period, with pairs
    /// here and there of a line 0.35 of a period late and the next 0.35 early (their
    /// interval 0.3 of a period), or the other way (1.7 periods): no pair is a clock set
    /// back or a line lost, every line is one slot on and keeps its tag. Before, judged
    /// against the last line's tag, the first read as the clock set back by 0.7 of a
    /// period and the second as a line lost.
    #[test]
    fn a_line_off_by_its_jitter_after_one_off_the_other_way_is_a_slot_on() {
        let random = |k: usize| ((k as f64 * 12.9898 + 7.0).sin() * 43_758.545).rem_euclid(1.0);
        let mut jitter: Vec<f64> = (0..600).map(|k| 0.2 * random(k + 1000) - 0.1).collect();
        let mut pairs = 0;
        let mut k = 2;
        while k + 3 < jitter.len() {
            if random(k) < 0.15 {
                let sign = if random(k + 5000) < 0.5 { 1.0 } else { -1.0 };
                (jitter[k], jitter[k + 1]) = (0.35 * sign, -0.35 * sign);
                pairs += 1;
                k += 3;
            } else {
                k += 1;
            }
        }
        assert!(pairs > 50, "{pairs}");
        let tags: Vec<f64> = (jitter.iter().enumerate())
            .map(|(k, j)| (k as f64 + j) * 0.01)
            .collect();
        let (v, rep, _) = read_all(&log_at(&tags));
        let slots: Vec<u64> = v.iter().map(|s| s.slot).collect();
        assert_eq!(slots, (0..600).collect::<Vec<u64>>());
        assert!(
            v.iter().zip(&tags).all(|(s, t)| (s.t_s - t).abs() < 1e-6),
            "a tag moved"
        );
        assert_eq!(
            (
                rep.text_clock_steps_back,
                rep.lines_off_slot,
                rep.seq_gaps,
                rep.lost_samples,
                rep.t_non_increasing
            ),
            (0, 0, 0, 0, 0)
        );
    }

    /// The slots of a log's first lines, from a median step 3 % off (lines lost among
    /// them, a jitter of up to 0.3 of a period): the period to 0.1 % and the first line's
    /// lateness to 0.05 of a period; fewer than eight lines leave the median and the
    /// first tag.
    #[test]
    fn the_first_lines_give_the_slots_period_and_phase() {
        let period = 0.01;
        // A jitter drawn at random (a jitter of one frequency would have its sidebands
        // agree better than its period).
        let jitter =
            |k: usize| ((k as f64 * 12.9898 + 1.0).sin() * 43_758.545).rem_euclid(1.0) * 0.6 - 0.3;
        let tags: Vec<f64> = (0..101)
            .map(|k| k + k / 7)
            .enumerate()
            .map(|(k, slot)| 5.0 + (slot as f64 + 0.2 + jitter(k)) * period)
            .collect();
        let (p, first_late) = first_slots(&tags, 0.97 * period, false);
        assert!((p / period - 1.0).abs() < 1e-3, "{p}");
        let late = tags[0] - (5.0 + 0.2 * period);
        assert!(
            (first_late - late).abs() < 0.05 * period,
            "{first_late} for {late}"
        );
        assert_eq!(first_slots(&tags[..7], period, false), (period, 0.0));
    }

    /// A jitter that repeats every few lines (a logger's polling beating with the IMU's
    /// rate; 0.3 or 0.35 of a period every 4.3 to 25 lines): the first lines' period to
    /// 0.5 %, and over 3000 lines every line in its slot, none read as lost, off its slot
    /// or stepped. The phases agree best at a side peak there (0.875 or 1.17 of the period
    /// every 7 lines), where a slot clock misreads a line in seven: taken, Kingston so
    /// jittered read a line lost every 13 lines, or a clock set back at every other line,
    /// and went "ok" hundreds of metres off.
    #[test]
    fn a_jitter_that_repeats_every_few_lines_keeps_the_period() {
        let period = 0.01;
        for (amp, lines) in [
            (0.3, 7.0),
            (0.3, 13.0),
            (0.3, 25.0),
            (0.35, 7.0),
            (0.35, 5.0),
            (0.3, 4.3),
        ] {
            let tags: Vec<f64> = (0..3000)
                .map(|k| {
                    let jitter = amp * (std::f64::consts::TAU * k as f64 / lines).sin();
                    100.0 + (k as f64 + jitter) * period
                })
                .collect();
            let mut steps: Vec<f64> = tags.windows(2).take(100).map(|w| w[1] - w[0]).collect();
            steps.sort_by(f64::total_cmp);
            let (p, _) = first_slots(&tags[..101], steps[50], false);
            assert!((p / period - 1.0).abs() < 5e-3, "{amp} every {lines}: {p}");
            let (v, rep, _) = read_all(&log_at(&tags));
            let slots: Vec<u64> = v.iter().map(|s| s.slot).collect();
            assert_eq!(
                slots,
                (0..3000).collect::<Vec<u64>>(),
                "{amp} every {lines}"
            );
            assert_eq!(
                (
                    rep.lost_samples,
                    rep.lines_off_slot,
                    rep.text_clock_steps_back
                ),
                (0, 0, 0),
                "{amp} every {lines}"
            );
        }
    }

    /// A source whose reading fails at its end ("the disk failed").
    pub(crate) struct FailsAtEnd(pub(crate) std::io::Cursor<Vec<u8>>);

    impl std::io::Read for FailsAtEnd {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            match self.0.read(buf)? {
                0 => Err(std::io::Error::other("the disk failed")),
                n => Ok(n),
            }
        }
    }

    /// An error reading the line after a sample (the one read ahead to tell whether the
    /// sample is off its slot) comes after that sample, as before the look-ahead.
    #[test]
    fn an_error_reading_ahead_comes_after_the_sample_before_it() {
        let tags: Vec<f64> = (0..150).map(|k| k as f64 * 0.01).collect();
        let src = FailsAtEnd(std::io::Cursor::new(log_at(&tags).into_bytes()));
        let mut r = KfGinsReader::new(std::io::BufReader::new(src));
        let mut read = 0;
        let err = loop {
            match r.next_sample() {
                Ok(Some(_)) => read += 1,
                Ok(None) => panic!("the error was lost"),
                Err(e) => break e,
            }
        };
        assert_eq!(read, 150);
        assert!(err.to_string().contains("the disk failed"), "{err}");
    }

    /// A logger's clock set back by 0.7 of a period, by 3 periods and by 1.5 s while it
    /// logs: each line after a step takes the time one period after the line before, the
    /// later tags moved by the steps (counted, with their sum); a line repeated as the
    /// one before, a line alone back and a step back beyond an hour and a second are no
    /// step (the derive's to repair or fail). Before, every tag after a step was
    /// "not increasing" and the derive failed.
    #[test]
    fn a_clock_set_back_while_logging_is_taken_out_of_the_time_base() {
        let mut tags: Vec<f64> = (0..200).map(|k| k as f64 * 0.01).collect();
        for (from, back_s) in [(120, 0.007), (150, 0.03), (170, 1.5)] {
            tags[from..].iter_mut().for_each(|t| *t -= back_s);
        }
        let (v, rep, _) = read_all(&log_at(&tags));
        let got: Vec<f64> = v.iter().map(|s| s.t_s).collect();
        assert!(
            got.iter()
                .enumerate()
                .all(|(k, t)| (t - k as f64 * 0.01).abs() < 1e-9),
            "{got:?}"
        );
        assert_eq!(
            (
                rep.text_clock_steps_back,
                rep.t_non_increasing,
                rep.lost_samples
            ),
            (3, 0, 0)
        );
        assert!((rep.text_clock_shift_s - 1.537).abs() < 1e-9, "{rep:?}");
        let at: Vec<(u64, f64)> = (rep.text_clock_steps.iter())
            .map(|s| (s.line, (s.step_s * 1e6).round() / 1e6))
            .collect();
        assert_eq!(at, [(121, 0.007), (151, 0.03), (171, 1.5)]);
        let said = rep.text_clock_said().unwrap();
        assert!(
            said.contains("set back 3 times while it logged (line 121 +0.007 s, line 151 +0.030 s, line 171 +1.500 s;"),
            "{said}"
        );
        // 33 steps of 3000 s, 30 lines apart: the first 28 taken out (84 000 s, within
        // a day), the other five left as written (each a tag going back).
        let mut tags: Vec<f64> = (0..1000).map(|k| k as f64 * 0.01).collect();
        for from in (30..1000).step_by(30) {
            tags[from..].iter_mut().for_each(|t| *t -= 3000.0);
        }
        let (v, rep, _) = read_all(&log_at(&tags));
        assert_eq!((rep.text_clock_steps_back, rep.t_non_increasing), (28, 5));
        assert!(
            rep.text_clock_said()
                .unwrap()
                .contains(", …; every step in ingest.json")
        );
        let many = IngestReport {
            text_clock_steps_back: 150,
            text_clock_steps: vec![
                TextClockStep {
                    line: 9,
                    step_s: 0.5,
                    tag_s: 1.0,
                    tag_before_s: 1.5,
                };
                TextClockStep::KEPT
            ],
            ..rep
        };
        assert!(
            many.text_clock_steps_listed()
                .ends_with(", …; the first 100 in ingest.json")
        );
        assert!((v[29 * 30].t_s - (29.0 * 30.0 * 0.01 - 3000.0)).abs() < 1e-6);
        // Not steps: a line repeated, a line back alone, and an hour and 2 s back.
        let mut tags: Vec<f64> = (0..200).map(|k| k as f64 * 0.01).collect();
        tags[120] = tags[119];
        tags[150] -= 0.05;
        tags[170..].iter_mut().for_each(|t| *t -= 3602.0);
        let (v, rep, _) = read_all(&log_at(&tags));
        assert_eq!(v[120].t_s, tags[119]);
        assert_eq!(v[171].t_s, tags[171]);
        assert_eq!((rep.text_clock_steps_back, rep.t_non_increasing), (0, 3));
    }

    /// A log at 100 Hz jittering by up to 0.04 of a period, with 2 lines lost at line 101
    /// and 3 at line 301, and its clock set forward by 3.37 periods at line 201: the step
    /// is taken out (the tags from line 201 on moved back by it, its slot the one after
    /// line 200's) and the lines lost stay counted. A step of whole periods reads as lines
    /// lost, as it must; so does a step with fewer than [`STEP_PHASE_LINES`] lines before
    /// it.
    #[test]
    fn a_clock_set_forward_is_taken_out_not_read_as_lines_lost() {
        let period = 0.01;
        let log = |step_at: usize, step: f64| -> (Vec<u64>, Vec<f64>) {
            let mut slot = 0u64;
            let mut slots = Vec::new();
            let mut tags = Vec::new();
            for k in 0..400 {
                slot += match k {
                    100 => 3,
                    300 => 4,
                    _ => 1,
                };
                let jitter = 0.04 * (k as f64 * 1.7).sin();
                let stepped = if k >= step_at { step } else { 0.0 };
                slots.push(slot);
                tags.push((slot as f64 + jitter + stepped) * period);
            }
            (slots, tags)
        };
        let (slots, tags) = log(200, 3.37);
        let (v, rep, _) = read_all(&log_at(&tags));
        assert_eq!((rep.text_clock_steps_forward, rep.lost_samples), (1, 5));
        let step = rep.text_clock_steps[0];
        assert_eq!(step.line, 201);
        assert!(
            (step.step_s + 3.37 * period).abs() < 0.01 * period,
            "{step:?}"
        );
        assert!((v[200].slot - v[199].slot, v[300].slot - v[299].slot) == (1, 4));
        for (k, s) in v.iter().enumerate() {
            let moved = if k >= 200 { step.step_s } else { 0.0 };
            assert!((s.t_s - (tags[k] + moved)).abs() < 1e-6, "line {}", k + 1);
            assert_eq!(s.slot + slots[0], slots[k]);
        }
        assert!(rep.text_clock_said().unwrap().starts_with(
            "the log's clock was set forward once while it logged (line 201 -0.034 s"
        ));
        // Whole periods: 3 lines lost more.
        let (_, tags) = log(200, 3.0);
        let (_, rep, _) = read_all(&log_at(&tags));
        assert_eq!((rep.text_clock_steps_forward, rep.lost_samples), (0, 8));
        // Too near the log's start to tell.
        let (_, tags) = log(50, 3.37);
        let (_, rep, _) = read_all(&log_at(&tags));
        assert_eq!((rep.text_clock_steps_forward, rep.lost_samples), (0, 8));
    }

    /// Simulated logs, a line lost in four (in stretches of one to three) and jittering at
    /// random by up to a quarter of a period: no line is read as the clock set forward
    /// (200 logs, about 50 000 gaps). Logs losing one line in fifty, jittering by up to a
    /// tenth of a period, set forward once in their middle by 2 to 20 periods and a phase of
    /// 0.3 to 0.5 of one either way (the line after the step not lost): every step is taken
    /// out at its line, to 0.08 of a period (200 logs; the phase's σ with 80 lines a side
    /// is 0.018).
    #[test]
    fn clock_steps_forward_are_told_from_lines_lost_in_simulated_logs() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(82);
        let period = 0.01;
        for stepped in [false, true] {
            for _ in 0..200 {
                let n = rng.random_range(400..1500);
                let (amp, lost_in) = if stepped { (0.1, 50) } else { (0.25, 4) };
                let at = n / 2;
                let step = rng.random_range(2..=20) as f64
                    + rng.random_range(0.3..0.5) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                let mut slot = 0u64;
                let mut tags = Vec::new();
                for k in 0..n {
                    if k != at && k != at + 1 && rng.random_range(0..lost_in) == 0 {
                        slot += rng.random_range(1..=3);
                    }
                    slot += 1;
                    let moved = if stepped && k >= at { step } else { 0.0 };
                    tags.push((slot as f64 + rng.random_range(-amp..amp) + moved) * period);
                }
                let (_, rep, _) = read_all(&log_at(&tags));
                if !stepped {
                    assert_eq!(
                        rep.text_clock_steps_forward, 0,
                        "{:?}",
                        rep.text_clock_steps
                    );
                    continue;
                }
                assert_eq!(rep.text_clock_steps_forward, 1, "step {step}");
                let got = rep.text_clock_steps[0];
                assert_eq!(got.line, at as u64 + 1);
                assert!(
                    (got.step_s + step * period).abs() < 0.08 * period,
                    "{got:?} for {step}"
                );
            }
        }
    }

    proptest::proptest! {
        /// Lines on their slots to a sixteenth of a period, lost in stretches of up to
        /// three, with lines written 0.65–0.85 of a period late or early alone, two lines
        /// a slot apart either side: every off line takes its slot's time (to the others'
        /// sixteenth), every gap is counted as it was lost and nothing more. (The margins
        /// to the rule's half periods are 0.09 of a period, well beyond the median
        /// interval's error as the period.)
        #[test]
        fn lines_off_alone_take_their_slots_and_gaps_stay_counted(
            lines in proptest::collection::vec((0u64..12, -0.0625f64..0.0625, 0u8..20, 0.65f64..0.85), 110..300),
        ) {
            let period = 0.01;
            let mut slots = Vec::new();
            let mut slot = 0u64;
            for &(lost, _, _, _) in &lines {
                // A stretch of 1–3 lines lost before a quarter of the lines (the period
                // is the median interval).
                slot += 1 + lost.saturating_sub(8);
                slots.push(slot);
            }
            let mut tags: Vec<f64> = (slots.iter().zip(&lines))
                .map(|(&s, &(_, jitter, _, _))| (s as f64 + jitter) * period)
                .collect();
            let mut off = vec![false; tags.len()];
            for k in 2..tags.len() - 2 {
                let (_, _, pick, by) = lines[k];
                // Two slots either side on lines (beside a gap, a line early after it
                // reads as well as the line before it late across it), the one before
                // not off.
                let alone = !off[k - 1]
                    && slots[k - 2] + 2 == slots[k]
                    && slots[k + 2] == slots[k] + 2;
                // One line in ten off, late or early (shrinking to none).
                let sign = match pick { 19 => 1.0, 18 => -1.0, _ => 0.0 };
                if alone && sign != 0.0 {
                    tags[k] = (slots[k] as f64 + sign * by) * period;
                    off[k] = true;
                }
            }
            let (v, rep, _) = read_all(&log_at(&tags));
            proptest::prop_assert_eq!(v.len(), tags.len());
            let lost: u64 = slots.windows(2).map(|w| w[1] - w[0] - 1).sum();
            proptest::prop_assert_eq!(rep.lost_samples, lost);
            proptest::prop_assert_eq!(rep.lines_off_slot, off.iter().filter(|o| **o).count() as u64);
            for (k, s) in v.iter().enumerate() {
                let slot_s = slots[k] as f64 * period;
                let within = 0.0625 * period + 1e-12;
                proptest::prop_assert!((s.t_s - slot_s).abs() <= within, "line {} at {} for {}", k, s.t_s, slot_s);
            }
        }

        /// Lines jittering by up to a quarter of a period about their slots, lost in
        /// stretches of up to three before a quarter of them: every line's slot is its
        /// own ([`TextSample::slot`]), every line lost is counted and no line is read as
        /// off its slot or as the clock set back; the tags stand as written.
        #[test]
        fn jittering_lines_keep_their_slots(
            lines in proptest::collection::vec((0u64..12, -0.25f64..0.25), 110..1500),
        ) {
            let period = 0.01;
            let mut slots = Vec::new();
            let mut slot = 0u64;
            for &(lost, _) in &lines {
                slot += 1 + lost.saturating_sub(8);
                slots.push(slot);
            }
            let tags: Vec<f64> = (slots.iter().zip(&lines))
                .map(|(&s, &(_, jitter))| (s as f64 + jitter) * period)
                .collect();
            let (v, rep, _) = read_all(&log_at(&tags));
            proptest::prop_assert_eq!(v.len(), tags.len());
            for (s, &slot) in v.iter().zip(&slots) {
                proptest::prop_assert_eq!(s.slot, slot - slots[0], "line {}", s.line);
                proptest::prop_assert!((s.t_s - tags[s.line as usize - 1]).abs() < 1e-6);
            }
            let lost: u64 = slots.windows(2).map(|w| w[1] - w[0] - 1).sum();
            proptest::prop_assert_eq!(rep.lost_samples, lost);
            proptest::prop_assert_eq!(
                (rep.lines_off_slot, rep.text_clock_steps_back, rep.t_non_increasing),
                (0, 0, 0)
            );
        }

        /// Any tags (steps of any size and sign, repeats, leaps): every line is accepted
        /// or rejected without a panic, the account adds up, every time given out is
        /// finite and within a day of the range, and the clock's shift within a day.
        #[test]
        fn any_tags_are_read_without_a_panic_and_account_for_every_line(
            steps in proptest::collection::vec(
                proptest::prop_oneof![
                    proptest::strategy::Just(0.01f64),
                    -0.05f64..0.05,
                    -4000.0f64..4000.0,
                    proptest::strategy::Just(0.0),
                ],
                2..300,
            ),
        ) {
            let tags: Vec<f64> = steps
                .iter()
                .scan(0.0, |t, step| {
                    *t += step;
                    Some(*t)
                })
                .collect();
            let (v, rep, _) = read_all(&log_at(&tags));
            proptest::prop_assert!(rep.is_consistent(), "{:?}", rep);
            proptest::prop_assert_eq!(rep.records_read, tags.len() as u64);
            proptest::prop_assert!(rep.text_clock_shift_s <= MAX_CLOCK_SHIFT_S);
            for s in &v {
                proptest::prop_assert!(s.t_s.is_finite() && s.t_s.abs() <= MAX_TAG_S + MAX_CLOCK_SHIFT_S);
            }
        }

        /// Lines on their slots to a sixteenth of a period, the logger's clock set back
        /// by 0.65–40 periods up to four times, 30 lines apart at least: every step is
        /// taken out (each line within half a period of its slot, the errors of the
        /// lines beside the steps adding up by a sixteenth each at most), nothing is
        /// lost and every step counted.
        #[test]
        fn a_clock_set_back_is_taken_out_wherever_and_by_however_much(
            jitter in proptest::collection::vec(-0.0625f64..0.0625, 150..400),
            steps in proptest::collection::vec((30usize..100, 0.65f64..40.0), 0..5),
        ) {
            let period = 0.01;
            let mut tags: Vec<f64> = (jitter.iter().enumerate())
                .map(|(k, j)| (k as f64 + j) * period)
                .collect();
            let mut at = 0;
            let mut made = 0;
            for &(after, back) in &steps {
                at += after;
                if at + 2 >= tags.len() {
                    break;
                }
                tags[at..].iter_mut().for_each(|t| *t -= back * period);
                made += 1;
            }
            let (v, rep, _) = read_all(&log_at(&tags));
            proptest::prop_assert_eq!(v.len(), tags.len());
            proptest::prop_assert_eq!((rep.text_clock_steps_back, rep.lost_samples), (made, 0));
            proptest::prop_assert_eq!((rep.t_non_increasing, rep.lines_off_slot), (0, 0));
            for (k, s) in v.iter().enumerate() {
                let slot_s = k as f64 * period;
                proptest::prop_assert!((s.t_s - slot_s).abs() < 0.5 * period, "line {} at {}", k, s.t_s);
            }
        }
    }

    /// Regression (fuzzing the text ingest): time tags that leap by 1e300 s (damaged
    /// lines) counted more lost samples than a u64 holds, and the count overflowed (a
    /// panic in a debug build, a wrong count in a release one); it now saturates. Within
    /// the tags accepted ([`MAX_TAG_S`]) it takes a period of 0.5 ns: two leaps of 9e9 s
    /// are 1.8e19 samples each.
    #[test]
    fn tags_that_leap_beyond_counting_saturate_the_lost_samples() {
        let mut text = String::from("-9e9 1 2 3 4 5 6\n");
        text.extend((0..100).map(|k| format!("{:e} 1 2 3 4 5 6\n", k as f64 * 5e-10)));
        text += "9e9 1 2 3 4 5 6\n";
        let (v, rep, _) = read_all(&text);
        assert_eq!(v.len(), 102);
        assert_eq!(rep.seq_gaps, 2);
        assert_eq!(rep.lost_samples, u64::MAX);
        // The lost samples × the period (0.5 ns, to the rounding of the tags' steps).
        let expected_s = u64::MAX as f64 * 5e-10;
        assert!(
            (rep.lost_duration_s / expected_s - 1.0).abs() < 1e-6,
            "{} for {expected_s}",
            rep.lost_duration_s
        );
        assert!(rep.is_consistent(), "{rep:?}");
    }

    /// Regression (probing the time range after the fuzzer's overflows): a time tag beyond
    /// what an i64 of nanoseconds holds saturated, so a file whose times are in
    /// microseconds since 1970 stood still at 9.2e9 s and failed for its odometer's
    /// speed; its lines are now refused, naming the units, and the tags within the range
    /// are kept.
    #[test]
    fn time_tags_beyond_the_span_timed_to_the_nanosecond_are_refused() {
        let text = "1700000000000000 1 2 3 4 5 6\n0.01 1 2 3 4 5 6\n-9e9 1 2 3 4 5 6\n\
                    9e9 1 2 3 4 5 6\n9000000001 1 2 3 4 5 6\n";
        let (v, rep, faults) = read_all(text);
        assert_eq!(
            v.iter().map(|s| s.t_s).collect::<Vec<_>>(),
            [0.01, -9e9, 9e9]
        );
        assert_eq!(faults.iter().map(|f| f.line).collect::<Vec<_>>(), [1, 5]);
        assert_eq!(
            faults[0].reason,
            "time 1.7e15 s is beyond ±9e9 s (285 years), the span the pipeline times to \
             the nanosecond: Unix time in microseconds (14 November 2023)? Write the \
             file's times in seconds"
        );
        assert!(rep.is_consistent(), "{rep:?}");
        // Unix milliseconds (a logger's, 18 May 2008) and nanoseconds named; a tag no
        // unit dates between 1980 and 2100 asked.
        for (t, said) in [
            (
                "1211068800123.4",
                "Unix time in milliseconds (18 May 2008)?",
            ),
            (
                "1211068800123456789",
                "Unix time in nanoseconds (18 May 2008)?",
            ),
            ("-1211068800123", "are the file's times in ms, µs or ns?"),
            ("9e25", "are the file's times in ms, µs or ns?"),
        ] {
            let (_, _, faults) = read_all(&format!("{t} 1 2 3 4 5 6\n0.01 1 2 3 4 5 6\n"));
            assert!(faults[0].reason.contains(said), "{t}: {}", faults[0].reason);
        }
        let odometer = b"1700000000000000 0\n1 0\n-9000000001 0\n2 0\n";
        let (d, _, lines, _) = read_odometer(odometer, OdometerKind::SpeedMps);
        assert_eq!((d.len(), lines), (2, vec![1, 3]));
        let reason = first_fault(odometer, OdometerKind::DistanceM);
        assert!(
            reason.starts_with("time 1.7e15 s is beyond ±9e9 s"),
            "{reason}"
        );
    }

    /// A sample is found again by its row or its time: the line it was read from, past
    /// comments, blank lines, rejected lines and a retransmitted duplicate; past the last,
    /// none.
    #[test]
    fn a_samples_line_is_found_by_its_row() {
        let text = "# header\n0.01 1 2 3 4 5 6\n0.02 1 2 3 4 5 6\n0.02 1 2 3 4 5 6\n0.03 x 2 3 4 5 6\n\n% note\n0.03 1 2 3 4 5 6\n0.05 1 2 3 4 5 6\n";
        let line = |k| find_sample_line(text.as_bytes(), |row, _| row == k).unwrap();
        assert_eq!(
            (0..5).map(line).collect::<Vec<_>>(),
            [Some(2), Some(3), Some(8), Some(9), None]
        );
        let (v, _, _) = read_all(text);
        assert_eq!(v.iter().map(|s| s.line).collect::<Vec<_>>(), [2, 3, 8, 9]);
        let tagged = |t_s| find_sample_line(text.as_bytes(), |_, s| s.t_s == t_s).unwrap();
        assert_eq!((tagged(0.03), tagged(0.04)), (Some(8), None));
    }

    /// A UTF-8 byte-order mark opening a file is no part of its first line: the first
    /// record (or comment) behind it is read as without it, in a log and in an odometer
    /// file; one further on is a fault.
    #[test]
    fn a_byte_order_mark_opening_a_file_is_not_its_first_line() {
        let plain = "0.01 1 2 3 4 5 6\n0.02 1 2 3 4 5 6\n";
        let (v, rep, _) = read_all(&format!("\u{feff}{plain}"));
        let (want, want_rep, _) = read_all(plain);
        assert_eq!((v, rep), (want, want_rep));
        let (v, rep, _) = read_all(&format!("\u{feff}# header\n{plain}"));
        assert_eq!((v.len(), rep.rejected.malformed_line), (2, Some(0)));
        let (v, rep, faults) = read_all(&format!("{plain}\u{feff}0.03 1 2 3 4 5 6\n"));
        assert_eq!((v.len(), rep.rejected.malformed_line), (2, Some(1)));
        assert_eq!(faults[0].line, 3);
        let (d, rep, faults, _) =
            read_odometer("\u{feff}0 0\n1 2\n".as_bytes(), OdometerKind::SpeedMps);
        assert_eq!((d, faults, rep.lines_rejected), (vec![0.0, 1.0], vec![], 0));
    }

    /// A log's 8th column may be left blank on any line, the first included: each line of
    /// 7 or 8 columns is a sample (its speed `None` without the 8th), and the log is of 8
    /// columns once a line has them. Before, the first line's count was the log's, and
    /// every line of the other count was rejected.
    #[test]
    fn an_8th_column_may_be_left_blank_on_any_line() {
        let text =
            "0.01 1 2 3 4 5 6\n0.02 1 2 3 4 5 6 7.5\n0.03,1,2,3,4,5,6,\n0.04 1 2 3 4 5 6 8\n";
        let mut r = KfGinsReader::new(text.as_bytes());
        assert_eq!(r.period_s().unwrap(), Some(0.01));
        assert_eq!(r.columns(), Some(8));
        let mut speeds = Vec::new();
        while let Some(s) = r.next_sample().unwrap() {
            speeds.push(s.speed_mps);
        }
        assert_eq!(speeds, [None, Some(7.5), None, Some(8.0)]);
        assert_eq!(r.report().rejected_total(), 0);
        let (v, _, _) = read_all("0.01 1 2 3 4 5 6\n0.02 1 2 3 4 5 6\n");
        assert!(v.iter().all(|s| s.speed_mps.is_none()) && v.len() == 2);
    }

    /// Why a line is not a record says what a user can mend: more columns than a log has,
    /// numbers written with decimal commas, lines that end in CR alone, UTF-16 text.
    #[test]
    fn a_rejected_lines_reason_names_what_to_mend() {
        let reason = |text: &[u8]| {
            let mut r = KfGinsReader::new(text);
            while r.next_sample().unwrap().is_some() {}
            r.faults().0[0].reason.clone()
        };
        assert_eq!(
            reason(b"0.01 1 2 3 4 5 6\n0.02 1 2 3 4 5 6 7 8 9 10\n"),
            "more than 8 columns, expected 7 or 8"
        );
        assert_eq!(
            reason(b"0,01 1 2 3 4 5,5 6\n"),
            "more than 8 columns, expected 7 or 8 (decimal commas? numbers take a decimal \
             point; a comma separates columns)"
        );
        let cr_only = "0.01 1 2 3 4 5 6\r".repeat(400);
        assert!(
            reason(cr_only.as_bytes()).contains("carriage returns in it: lines that end in CR"),
            "{}",
            reason(cr_only.as_bytes())
        );
        assert_eq!(
            first_fault(b"152143 0,00000\n", OdometerKind::SpeedMps),
            format!("expected two numbers `t_s value`, got \"152143 0,00000\"{DECIMAL_COMMA_HINT}")
        );
        let utf16: Vec<u8> = "\u{feff}0.01 1 2 3 4 5 6\n"
            .encode_utf16()
            .flat_map(u16::to_le_bytes)
            .collect();
        assert_eq!(
            reason(&utf16),
            "UTF-16 text (its byte-order mark): the file must be UTF-8 or ASCII"
        );
    }

    /// A comment line that is not UTF-8 (a crew's note in Latin-1) is a comment, in a log
    /// and in an odometer file; a record line that is not is a fault.
    #[test]
    fn a_comment_in_another_encoding_is_a_comment() {
        let text = b"# Messung \xfcber Land\n0.01 1 2 3 4 5 6\n  % n\xe4he\n0.02 1 2 3 4 5 6\n";
        let mut r = KfGinsReader::new(&text[..]);
        while r.next_sample().unwrap().is_some() {}
        assert_eq!((r.report().imu_accepted, r.faults().1), (2, 0));
        let bad = b"0.01 1 2 3 4 5 6\n0.02 1 2 3 4 5 \xfc\n";
        let mut r = KfGinsReader::new(&bad[..]);
        while r.next_sample().unwrap().is_some() {}
        assert_eq!(r.faults().0[0].reason, "not UTF-8 text");
        let (d, rep, faults, _) = read_odometer(b"# \xfcber\n0 0\n1 2\n", OdometerKind::SpeedMps);
        assert_eq!((d, faults, rep.lines_rejected), (vec![0.0, 1.0], vec![], 0));
    }

    #[test]
    fn overlong_line_is_cut_and_counted() {
        let long = "9".repeat(10 * MAX_LINE_BYTES);
        let text = format!("0.01 1 2 3 4 5 6\n{long}\n0.02 1 2 3 4 5 6\n");
        let (v, rep, _) = read_all(&text);
        assert_eq!(v.len(), 2);
        assert_eq!(rep.rejected.malformed_line, Some(1));
    }

    /// Distances, accounting, the kept faults' line numbers and the faults' total.
    fn read_odometer(
        text: &[u8],
        kind: OdometerKind,
    ) -> (Vec<f64>, OdometerFileReport, Vec<u64>, u64) {
        let mut r = OdometerFileReader::new(text, kind);
        let mut d = Vec::new();
        while let Some(s) = r.next_sample().unwrap() {
            d.push(s.distance_m);
        }
        let (kept, total) = r.faults();
        let lines = kept.iter().map(|f| f.line).collect();
        (d, r.report().clone(), lines, total)
    }

    /// The reason of the first line `text` rejects, as `kind`.
    fn first_fault(text: &[u8], kind: OdometerKind) -> String {
        let mut r = OdometerFileReader::new(text, kind);
        while r.next_sample().unwrap().is_some() {}
        r.faults().0[0].reason.clone()
    }

    /// A file of more columns (an OBD-II logger's: time, speed, engine speed, a status)
    /// reads the value's column `[odometer] value_column` names, the others unread; a
    /// CSV's empty field is a column (the speed missing: the line rejected, not the next
    /// column read as it). Without the setting, the first line's reason names the
    /// columns it has and the setting.
    #[test]
    fn a_file_of_more_columns_reads_the_column_named() {
        let read = |text: &[u8], column: Option<usize>| {
            let mut r =
                OdometerFileReader::new(text, OdometerKind::SpeedMps).with_value_column(column);
            let mut d = Vec::new();
            while let Some(s) = r.next_sample().unwrap() {
                d.push(s.distance_m);
            }
            let faults: Vec<(u64, String)> = (r.faults().0.iter())
                .map(|f| (f.line, f.reason.clone()))
                .collect();
            (d, faults)
        };
        let spaced = b"0 0 800 OK\n1 2 1500 OK\n2 2 1600 OK\n";
        assert_eq!(read(spaced, Some(2)), (vec![0.0, 1.0, 3.0], vec![]));
        let csv = b"time,speed,rpm\n0, 0, 800\n1,2,1500\n2,,1600\n3,2,1600\n";
        let (d, faults) = read(csv, Some(2));
        assert_eq!(d, vec![0.0, 1.0, 5.0]);
        assert_eq!(faults.iter().map(|f| f.0).collect::<Vec<_>>(), vec![1, 4]);
        assert_eq!(
            faults[1].1,
            "expected the time in column 1 and the value in column 2 ([odometer] \
             value_column), got \"2,,1600\""
        );
        // The value in the third column: engine speed first.
        let third = b"0 800 0\n1 1500 2\n2 1600 2\n";
        assert_eq!(read(third, Some(3)), (vec![0.0, 1.0, 3.0], vec![]));
        // A line without the column named.
        assert_eq!(read(b"0 800\n", Some(3)).1[0].0, 1);
        // Without the setting: named.
        assert_eq!(
            first_fault(spaced, OdometerKind::SpeedMps),
            "expected two numbers `t_s value`, got \"0 0 800 OK\" (a file of 4 columns? name \
             the value's in the manifest's [odometer] value_column: 2 for the second, the \
             time being the first)"
        );
        assert_eq!(
            first_fault(b"0 x\n", OdometerKind::SpeedMps),
            "expected two numbers `t_s value`, got \"0 x\""
        );
        // Two columns read alike with the setting at 2 or without it.
        let two = b"0 0\n1 2\n2 2\n";
        assert_eq!(read(two, Some(2)), read(two, None));
    }

    /// `value_column` given as a name reads the column the file's header line gives it
    /// (after comments and blank lines; spaces and double quotes around a name are not
    /// part of it), as its number does, the header line rejected as such; a header without
    /// the name, one giving it to the time's column, and a first line of numbers fail,
    /// naming the line and what it holds.
    #[test]
    fn a_file_of_more_columns_reads_the_column_its_header_names() {
        let named = |text: &[u8], name: &str| {
            let mut r =
                OdometerFileReader::new(text, OdometerKind::SpeedMps).with_value_header(Some(name));
            let mut d = Vec::new();
            loop {
                match r.next_sample() {
                    Ok(Some(s)) => d.push(s.distance_m),
                    Ok(None) => break,
                    Err(e) => return Err(e.to_string()),
                }
            }
            let faults: Vec<(u64, String)> = (r.faults().0.iter())
                .map(|f| (f.line, f.reason.clone()))
                .collect();
            Ok((d, faults, r.report().clone()))
        };
        let csv = b"# OBD log\n\n\"time\", \"rpm\" ,\"speed\"\n0,800,0\n1,1500,2\n2,1600,2\n";
        let (d, faults, report) = named(csv, "speed").unwrap();
        assert_eq!(d, vec![0.0, 1.0, 3.0]);
        assert_eq!(
            faults,
            vec![(
                3,
                "the file's header line (its columns' names): \"speed\" is column 3 \
                 ([odometer] value_column)"
                    .to_owned()
            )]
        );
        assert_eq!((report.lines_read, report.lines_rejected), (4, 1));
        let spaced = b"t v rpm\n0 0 800\n1 2 1500\n2 2 1600\n";
        assert_eq!(named(spaced, "v").unwrap().0, vec![0.0, 1.0, 3.0]);
        let wanted = "line 3: [odometer] value_column = \"speed_mps\" names the value's column \
                      on the file's header line";
        assert_eq!(
            named(csv, "speed_mps").unwrap_err(),
            format!(
                "{wanted}, and its header line names none so: its columns are \"time\", \"rpm\", \"speed\""
            )
        );
        let wanted = wanted.replace("line 3", "line 1").replace("speed_mps", "t");
        assert_eq!(
            named(spaced, "t").unwrap_err(),
            format!("{wanted}, and the header gives that name to column 1, the time's")
        );
        let err = named(b"0 0 800\n1 2 1500\n", "speed").unwrap_err();
        assert!(
            err.starts_with("line 1: [odometer] value_column = \"speed\"")
                && err.ends_with(
                    "and the file's first line holds numbers, no names (\"0 0 800\"): name the \
                     column by its number (2 for the second, the time being the first)"
                ),
            "{err}"
        );
        // A header of many long names is listed in part.
        let wide: String = (0..40).map(|i| format!("{}{i},", "n".repeat(50))).collect();
        let err = named(format!("{wide}\n").as_bytes(), "speed").unwrap_err();
        assert!(err.ends_with(", … 41 in all") && err.len() < 1500, "{err}");
    }

    #[test]
    fn speed_integrates_to_distance() {
        let (d, rep, faults, _) =
            read_odometer(b"0 0\n1 2\n2 2\n2 5\n3 0\n", OdometerKind::SpeedMps);
        assert_eq!(faults, vec![4]);
        assert_eq!(d, vec![0.0, 1.0, 3.0, 4.0]);
        assert_eq!(
            rep,
            OdometerFileReport {
                lines_read: 5,
                lines_accepted: 4,
                lines_rejected: 1,
                week_rollovers: 0,
                day_rollovers: 0,
                ..Default::default()
            }
        );
    }

    /// OBD-II's km/h (`kind = "speed_kmh"`) are read as m/s: the same distances as the
    /// speeds in m/s give, and a speed beyond 100 m/s named in the file's unit.
    #[test]
    fn speeds_in_km_h_are_read_as_m_s() {
        let (d, _, faults, _) =
            read_odometer(b"0 0\n1 7.2\n2 7.2\n3 400\n4 0\n", OdometerKind::SpeedKmh);
        // 7.2 km/h = 2 m/s; the line at 400 km/h rejected, the trapezoid spans it.
        assert_eq!(faults, vec![4]);
        assert_eq!(d, vec![0.0, 1.0, 3.0, 5.0]);
        let reason = first_fault(b"0 0\n1 400\n", OdometerKind::SpeedKmh);
        assert!(reason.starts_with("speed 400 km/h is beyond"), "{reason}");
        // A spike, in km/h as the file writes it.
        let text = b"0 36\n1 36\n2 36\n3 144\n4 36\n5 36\n6 36\n";
        let reason = first_fault(text, OdometerKind::SpeedKmh);
        assert!(
            reason.starts_with("speed 144 km/h at 3 s left out: it jumped from 36 km/h at 2 s"),
            "{reason}"
        );
    }

    #[test]
    fn every_odometer_line_is_accepted_or_rejected_with_its_number() {
        let long = "1".repeat(3 * MAX_LINE_BYTES);
        let mut text = format!(
            "# t_s distance_m\n0 0\n\n1 5 7\n1 nan\n2 10\n{long}\n3\n2.5 9\n% note\n3 1e300\n"
        )
        .into_bytes();
        text.extend_from_slice(b"\xff\n4 12");
        let (d, rep, lines, _) = read_odometer(&text, OdometerKind::DistanceM);
        // Distances are taken as read (their steps are the ingest's range check's).
        assert_eq!(d, vec![0.0, 10.0, 9.0, 1e300, 12.0]);
        assert_eq!(lines, vec![4, 5, 7, 8, 12]);
        assert_eq!(
            rep,
            OdometerFileReport {
                lines_read: 10,
                lines_accepted: 5,
                lines_rejected: 5,
                week_rollovers: 0,
                day_rollovers: 0,
                ..Default::default()
            }
        );
    }

    #[test]
    fn a_file_of_one_endless_line_is_read_in_bounded_memory() {
        // 64 MiB without a line break: one overlong line, never held whole.
        struct Endless(usize);
        impl std::io::Read for Endless {
            fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
                let n = buf.len().min(self.0);
                buf[..n].fill(b'7');
                self.0 -= n;
                Ok(n)
            }
        }
        let src = std::io::BufReader::new(Endless(64 << 20));
        let mut r = OdometerFileReader::new(src, OdometerKind::SpeedMps);
        assert!(r.next_sample().unwrap().is_none());
        assert_eq!(r.report().lines_rejected, 1);
        assert!(r.lines.buf.capacity() <= 2 * MAX_LINE_BYTES);
        assert_eq!(r.faults().1, 1);
    }

    /// A speed that jumps and comes back is a rejected line with its reason, in its
    /// place among the other faults; the trapezoid spans it.
    #[test]
    fn a_spike_is_a_line_fault_in_its_place() {
        let text = b"0 10\n1 10\n2 40\nx\n3 10\n4 10\n5 10\n";
        let (d, rep, lines, total) = read_odometer(text, OdometerKind::SpeedMps);
        assert_eq!(d, vec![0.0, 10.0, 30.0, 40.0, 50.0]);
        assert_eq!((lines, total), (vec![3, 4], 2));
        assert_eq!(
            (rep.lines_read, rep.lines_accepted, rep.lines_rejected),
            (7, 5, 2)
        );
        let mut r = OdometerFileReader::new(&text[..], OdometerKind::SpeedMps);
        while r.next_sample().unwrap().is_some() {}
        assert!(
            r.faults().0[0].reason.ends_with("(a spike)"),
            "{:?}",
            r.faults()
        );
        assert_eq!(r.spikes(), (1, 0));
    }

    #[test]
    fn line_faults_beyond_the_first_thousand_are_counted_only() {
        let text = "x\n".repeat(2500) + "0 1\n";
        let (d, rep, lines, total) = read_odometer(text.as_bytes(), OdometerKind::SpeedMps);
        assert_eq!(lines.len(), 1000);
        assert_eq!(total, 2500);
        assert_eq!(d, vec![0.0]);
        assert_eq!(rep.lines_rejected, 2500);
    }
}
