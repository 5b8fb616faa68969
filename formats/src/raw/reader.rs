//! Streaming decoder for the binary UNZ log with fault accounting (§1.3, §1.4).
//!
//! Framing rules, fixed so that every byte of a file is accounted for exactly once:
//! - in sync, a frame whose CRC matches is classified (IMU, mark, or unknown type);
//! - a frame whose CRC does not match counts as one `bad_crc` record, and the reader
//!   loses framing at its first byte;
//! - bytes that do not start with the sync pattern also lose framing;
//! - having lost framing, the reader searches forward, byte by byte, for the next
//!   `A5 5A` that frames a record with a valid CRC; every byte passed over counts in
//!   `bytes_skipped`, and finding one counts one `resync_event`. Sync patterns passed
//!   over while searching (framing a bad CRC) are part of the skipped bytes, not records;
//! - a frame cut short by the end of the file, with no valid frame after its start, is
//!   the truncated final record (`rejected.truncated`, `truncated_bytes`).

use std::io::Read;

use super::clock::{RecorderClock, Resolved};
use super::header::{FileHeader, HEADER_LEN};
use super::record::{
    IMU_PAYLOAD_LEN, ImuRecord, MARK_PAYLOAD_LEN, MAX_FRAME_LEN, MarkRecord, SYNC, TYPE_IMU,
    TYPE_MARK, frame_crc_ok, frame_len,
};
use crate::error::FormatError;
use crate::report::IngestReport;
use crate::resent::RecentRecords;

/// Buffer size of the reader: memory use is bounded by it whatever the file size.
const BUF_LEN: usize = 256 * 1024;
/// At most this many fault events are kept for the report (all are counted).
const MAX_EVENTS: usize = 1000;

/// What kind of fault an event records.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// A frame with a CRC mismatch.
    BadCrc,
    /// Bytes skipped until framing was found again.
    Resync,
    /// A retransmitted IMU record.
    DuplicateSeq,
    /// A reserved record type or a wrong length for a known type.
    UnknownType,
    /// The final record is cut short.
    Truncated,
    /// Samples missing between two accepted IMU records.
    SeqGap,
    /// `seq` went backwards.
    SeqBackwards,
    /// `t_us` did not increase.
    TimeNotIncreasing,
    /// The recorder's clock leapt forward while `seq` ran on (amount: µs); the tags from
    /// this record on are moved back by it.
    ClockAhead,
    /// The recorder's clock leapt back while `seq` ran on (amount: µs); the tags from this
    /// record on are moved forward by it.
    ClockBack,
    /// This record's tag alone was off its `seq`'s time, its neighbours agreeing (amount:
    /// µs, either way); it is given its `seq`'s time.
    LoneTagOff,
}

/// One fault, located by the byte offset of the record (or skipped run) in the file.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FaultEvent {
    /// Byte offset in the file.
    pub offset: u64,
    /// Kind of fault.
    pub kind: FaultKind,
    /// A size, depending on the kind: bytes skipped, samples lost, record type…
    pub amount: u64,
}

/// An accepted IMU sample with its counters unwrapped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImuSample {
    /// The record as read.
    pub raw: ImuRecord,
    /// Its time, µs since the header's start on the clock of the log's start: its tag,
    /// the recorder's clock steps taken out and a lone tag off given its `seq`'s time
    /// (the reader's `RecorderClock`).
    pub t_us: u64,
    /// `seq` unwrapped across 2^32 (the first record's `seq` is its own value).
    pub seq: u64,
    /// `odo_count` unwrapped across 2^32 (signed steps, so reversing is kept).
    pub odo_pulses: i64,
}

/// An accepted control-point mark.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MarkSample {
    /// The record as read.
    pub raw: MarkRecord,
    /// Its time, µs since the header's start on the clock of the log's start (its tag,
    /// the recorder's clock steps before it taken out).
    pub t_us: u64,
}

/// A record the reader accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Accepted {
    /// IMU sample.
    Imu(ImuSample),
    /// Control-point mark.
    Mark(MarkSample),
}

/// Streaming reader; see the module documentation for the framing rules.
pub struct RawReader<R: Read> {
    src: R,
    header: FileHeader,
    buf: Box<[u8]>,
    /// Unprocessed bytes are `buf[pos..end]`.
    pos: usize,
    end: usize,
    /// File offset of `buf[0]`.
    base: u64,
    eof: bool,
    done: bool,
    report: IngestReport,
    events: Vec<FaultEvent>,
    events_total: u64,
    last_imu: Option<(u32, u64, u64, u32, i64)>, // raw seq, unwrapped seq, t_us, raw odo, odo
    /// The IMU records accepted lately (`seq`, `t_us`) at their `seq`: a record going
    /// back to one of them is a duplicate (a block sent again, logs joined over their
    /// overlap), not a counter reset.
    recent: RecentRecords<(u32, u64)>,
    /// File offset of the record returned last.
    last_offset: u64,
    /// The recorder's clock, as `seq` says it ran.
    clock: RecorderClock,
}

impl<R: Read> RawReader<R> {
    /// Reads and validates the header; records are then pulled with [`Self::next_record`].
    pub fn new(mut src: R) -> Result<Self, FormatError> {
        let mut head = [0u8; HEADER_LEN];
        let got = read_full(&mut src, &mut head)
            .map_err(|source| FormatError::Io { offset: 0, source })?;
        let header = FileHeader::decode(&head[..got])?;
        // Skip a longer header of a later minor revision.
        let extra = usize::from(header.header_len) - HEADER_LEN;
        if extra > 0 {
            let mut skip = vec![0u8; extra];
            let got = read_full(&mut src, &mut skip).map_err(|source| FormatError::Io {
                offset: HEADER_LEN as u64,
                source,
            })?;
            if got < extra {
                return Err(FormatError::Header {
                    reason: format!("file ends inside the {}-byte header", header.header_len),
                });
            }
        }
        Ok(Self {
            src,
            base: u64::from(header.header_len),
            header,
            buf: vec![0u8; BUF_LEN].into_boxed_slice(),
            pos: 0,
            end: 0,
            eof: false,
            done: false,
            report: IngestReport::default(),
            events: Vec::new(),
            events_total: 0,
            last_imu: None,
            recent: RecentRecords::default(),
            last_offset: 0,
            clock: RecorderClock::default(),
        })
    }

    /// The decoded file header.
    pub fn header(&self) -> &FileHeader {
        &self.header
    }

    /// The accounting so far (final once [`Self::next_record`] returned `None`).
    pub fn report(&self) -> &IngestReport {
        &self.report
    }

    /// The first fault events (at most 1000) and the total number of events.
    pub fn events(&self) -> (&[FaultEvent], u64) {
        (&self.events, self.events_total)
    }

    /// Consumes the reader, returning the final report and fault events (a last record
    /// whose tag was off its `seq`'s time counted as a lone tag off).
    pub fn into_report(mut self) -> (IngestReport, Vec<FaultEvent>, u64) {
        if let Some(resolved) = self.clock.finish() {
            self.said_of_clock(resolved);
        }
        (self.report, self.events, self.events_total)
    }

    /// The byte offset in the file of the record [`Self::next_record`] returned last (0
    /// before the first).
    pub fn record_offset(&self) -> u64 {
        self.last_offset
    }

    fn offset_of(&self, i: usize) -> u64 {
        self.base + i as u64
    }

    fn event(&mut self, offset: u64, kind: FaultKind, amount: u64) {
        self.events_total += 1;
        if self.events.len() < MAX_EVENTS {
            self.events.push(FaultEvent {
                offset,
                kind,
                amount,
            });
        }
    }

    /// Makes at least `MAX_FRAME_LEN` bytes available from `pos` unless the file ends.
    fn fill(&mut self) -> Result<(), FormatError> {
        if self.eof || self.end - self.pos >= MAX_FRAME_LEN {
            return Ok(());
        }
        self.refill()
    }

    /// Moves `buf[pos..end]` to the front and reads until the buffer is full or the file
    /// ends, whatever is already buffered. The buffer holds far more than the two frames
    /// a resync search keeps, so this always makes room.
    fn refill(&mut self) -> Result<(), FormatError> {
        if self.eof {
            return Ok(());
        }
        self.buf.copy_within(self.pos..self.end, 0);
        self.base += self.pos as u64;
        self.end -= self.pos;
        self.pos = 0;
        while self.end < self.buf.len() {
            match self.src.read(&mut self.buf[self.end..]) {
                Ok(0) => {
                    self.eof = true;
                    break;
                }
                Ok(n) => self.end += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(source) => {
                    return Err(FormatError::Io {
                        offset: self.base + self.end as u64,
                        source,
                    });
                }
            }
        }
        Ok(())
    }

    /// Length of the frame starting at `i` if it is complete in the buffer.
    fn complete_frame_at(&self, i: usize) -> Option<usize> {
        if self.end - i < 4 || self.buf[i..i + 2] != SYNC {
            return None;
        }
        let n = frame_len(usize::from(self.buf[i + 3]));
        (self.end - i >= n).then_some(n)
    }

    fn valid_frame_at(&self, i: usize) -> bool {
        self.complete_frame_at(i)
            .is_some_and(|n| frame_crc_ok(&self.buf[i..i + n]))
    }

    /// Returns the next accepted record, or `None` at the end of the file.
    ///
    /// Faults never end the stream; only an I/O error does.
    pub fn next_record(&mut self) -> Result<Option<Accepted>, FormatError> {
        while !self.done {
            self.fill()?;
            let avail = self.end - self.pos;
            if avail == 0 {
                self.done = true;
                break;
            }
            let i = self.pos;
            let starts_with_sync = avail >= 2 && self.buf[i..i + 2] == SYNC;
            if !starts_with_sync {
                if avail == 1 && self.eof && self.buf[i] == SYNC[0] {
                    self.truncate_tail(i);
                } else {
                    self.resync(i, i)?;
                }
                continue;
            }
            match self.complete_frame_at(i) {
                Some(n) => {
                    if frame_crc_ok(&self.buf[i..i + n]) {
                        self.pos += n;
                        self.report.records_read += 1;
                        if let Some(rec) = self.classify(i) {
                            self.last_offset = self.offset_of(i);
                            return Ok(Some(rec));
                        }
                    } else {
                        self.report.records_read += 1;
                        self.report.rejected.bad_crc += 1;
                        let off = self.offset_of(i);
                        self.event(off, FaultKind::BadCrc, n as u64);
                        self.resync(i, i + 1)?;
                    }
                }
                None => {
                    // Cut short by the end of the file: the truncated final record,
                    // unless a valid frame starts inside it (then it was garbage).
                    if (i + 1..self.end).any(|j| self.valid_frame_at(j)) {
                        self.resync(i, i + 1)?;
                    } else {
                        self.truncate_tail(i);
                    }
                }
            }
        }
        Ok(None)
    }

    fn truncate_tail(&mut self, i: usize) {
        let n = (self.end - i) as u64;
        self.report.records_read += 1;
        self.report.rejected.truncated += 1;
        self.report.truncated_bytes += n;
        let off = self.offset_of(i);
        self.event(off, FaultKind::Truncated, n);
        self.pos = self.end;
        self.done = true;
    }

    /// Searches for framing from buffer index `from`; bytes from `lost_at` on are skipped.
    ///
    /// Works in file offsets, because refilling the buffer moves its contents.
    fn resync(&mut self, lost_at: usize, from: usize) -> Result<(), FormatError> {
        let lost_offset = self.offset_of(lost_at);
        let from_offset = self.offset_of(from);
        let mut q = from;
        loop {
            // Fast scan for the next sync byte.
            q += self.buf[q..self.end]
                .iter()
                .position(|&b| b == SYNC[0])
                .unwrap_or(self.end - q);
            if self.end - q < MAX_FRAME_LEN && !self.eof {
                // Refill, keeping one frame's worth of bytes before q: a frame cut short by
                // the end of the file may start there.
                let q_offset = self.offset_of(q);
                let keep_from = q_offset
                    .saturating_sub(MAX_FRAME_LEN as u64)
                    .max(from_offset);
                self.pos = (keep_from - self.base) as usize;
                // Not `fill`: up to two frames are kept, which it would take as enough
                // and never read on (the search then spun at the same place forever).
                self.refill()?;
                q = (q_offset - self.base) as usize;
                continue;
            }
            if q >= self.end {
                break;
            }
            if self.valid_frame_at(q) {
                let skipped = self.offset_of(q) - lost_offset;
                self.report.bytes_skipped += skipped;
                self.report.resync_events += 1;
                self.event(lost_offset, FaultKind::Resync, skipped);
                self.pos = q;
                return Ok(());
            }
            q += 1;
        }
        // The end of the file without framing: the first sync whose frame is cut short by
        // the end is the truncated final record; everything before it is skipped.
        let first = self
            .pos
            .max((from_offset.saturating_sub(self.base)) as usize);
        let tail = (first..self.end).find(|&j| {
            self.buf[j] == SYNC[0]
                && (j + 1 == self.end || self.buf[j + 1] == SYNC[1])
                && self.complete_frame_at(j).is_none()
        });
        let stop_offset = tail.map_or(self.offset_of(self.end), |j| self.offset_of(j));
        let skipped = stop_offset - lost_offset;
        self.report.bytes_skipped += skipped;
        self.event(lost_offset, FaultKind::Resync, skipped);
        match tail {
            Some(j) => self.truncate_tail(j),
            None => {
                self.pos = self.end;
                self.done = true;
            }
        }
        Ok(())
    }

    /// Classifies a valid frame at `i` of length `n`; returns it if accepted.
    fn classify(&mut self, i: usize) -> Option<Accepted> {
        let record_type = self.buf[i + 2];
        let len = usize::from(self.buf[i + 3]);
        let payload = &self.buf[i + 4..i + 4 + len];
        let offset = self.offset_of(i);
        match (record_type, len) {
            (TYPE_IMU, IMU_PAYLOAD_LEN) => {
                let mut p = [0u8; IMU_PAYLOAD_LEN];
                p.copy_from_slice(payload);
                let raw = ImuRecord::decode_payload(&p);
                self.accept_imu(raw, offset)
            }
            (TYPE_MARK, MARK_PAYLOAD_LEN) => {
                let mut p = [0u8; MARK_PAYLOAD_LEN];
                p.copy_from_slice(payload);
                self.report.records_accepted += 1;
                self.report.marks_accepted += 1;
                let raw = MarkRecord::decode_payload(&p);
                let t_us = self.clock.mark(raw.t_us);
                Some(Accepted::Mark(MarkSample { raw, t_us }))
            }
            _ => {
                self.report.rejected.unknown_type += 1;
                self.event(offset, FaultKind::UnknownType, u64::from(record_type));
                None
            }
        }
    }

    fn accept_imu(&mut self, raw: ImuRecord, offset: u64) -> Option<Accepted> {
        let Some((prev_seq_raw, prev_seq, prev_t, prev_odo_raw, prev_odo)) = self.last_imu else {
            let (t_us, _) = self.clock.imu(raw.t_us, Some(1), offset);
            return self.accepted_imu(raw, t_us, u64::from(raw.seq), i64::from(raw.odo_count));
        };
        let step = raw.seq.wrapping_sub(prev_seq_raw);
        let resent = || {
            step >= 1 << 31
                && raw.t_us <= prev_t
                && (self.recent.seen(u64::from(raw.seq), &(raw.seq, raw.t_us))).is_some()
        };
        if step == 0 || resent() {
            self.report.rejected.duplicate_seq += 1;
            self.event(offset, FaultKind::DuplicateSeq, u64::from(raw.seq));
            return None;
        }
        // A counter reset (a step back) keeps the stream going one sample on; it says
        // nothing of the time since the record before.
        let seq_step = (step < 1 << 31).then_some(u64::from(step));
        // What this record says of the one before comes first, in the file's order.
        let (t_us, resolved) = self.clock.imu(raw.t_us, seq_step, offset);
        if let Some(resolved) = resolved {
            self.said_of_clock(resolved);
        }
        if step >= 1 << 31 {
            self.report.seq_gaps += 1;
            self.event(
                offset,
                FaultKind::SeqBackwards,
                u64::from(step.wrapping_neg()),
            );
        } else if step > 1 {
            let lost = u64::from(step - 1);
            self.report.seq_gaps += 1;
            self.report.lost_samples += lost;
            self.event(offset, FaultKind::SeqGap, lost);
        }
        if raw.t_us <= prev_t {
            self.report.t_non_increasing += 1;
            self.event(offset, FaultKind::TimeNotIncreasing, prev_t - raw.t_us);
        }
        let odo_step = raw.odo_count.wrapping_sub(prev_odo_raw) as i32;
        self.accepted_imu(
            raw,
            t_us,
            prev_seq + seq_step.unwrap_or(1),
            prev_odo + i64::from(odo_step),
        )
    }

    /// Keeps an IMU record accepted as sample `seq` (unwrapped) at time `t_us` with
    /// `odo_pulses` (unwrapped).
    fn accepted_imu(
        &mut self,
        raw: ImuRecord,
        t_us: u64,
        seq: u64,
        odo_pulses: i64,
    ) -> Option<Accepted> {
        self.last_imu = Some((raw.seq, seq, raw.t_us, raw.odo_count, odo_pulses));
        self.recent
            .keep(u64::from(raw.seq), (raw.seq, raw.t_us), ());
        self.report.records_accepted += 1;
        self.report.imu_accepted += 1;
        self.report.lost_duration_s =
            self.report.lost_samples as f64 * self.header.sample_period_s();
        Some(Accepted::Imu(ImuSample {
            raw,
            t_us,
            seq,
            odo_pulses,
        }))
    }

    /// Counts what the clock found of a record whose tag was off, and lists it.
    fn said_of_clock(&mut self, resolved: Resolved) {
        let amount = |us: i128| u64::try_from(us.unsigned_abs()).unwrap_or(u64::MAX);
        match resolved {
            Resolved::Step { offset, leap_us } => {
                self.report.clock_steps += 1;
                let kind = if leap_us > 0 {
                    FaultKind::ClockAhead
                } else {
                    FaultKind::ClockBack
                };
                self.event(offset, kind, amount(leap_us));
                self.report.clock_shift_s = self.clock.offset_us() as f64 * 1e-6;
            }
            Resolved::LoneTag { offset, off_us } => {
                self.report.lone_tags_off += 1;
                self.event(offset, FaultKind::LoneTagOff, amount(off_us));
            }
        }
    }
}

/// The byte offset of the first IMU record the reader accepts for which `wanted(row,
/// sample)` holds (`row`: 0-based among the accepted IMU records, the row of the ingest's
/// IMU table it became), or `None` when none does. The log is read up to it, in the
/// reader's bounded buffer.
pub fn find_imu_record<R: Read>(
    src: R,
    mut wanted: impl FnMut(u64, &ImuSample) -> bool,
) -> Result<Option<u64>, FormatError> {
    let mut reader = RawReader::new(src)?;
    let mut row = 0u64;
    while let Some(rec) = reader.next_record()? {
        if let Accepted::Imu(sample) = rec {
            if wanted(row, &sample) {
                return Ok(Some(reader.record_offset()));
            }
            row += 1;
        }
    }
    Ok(None)
}

/// Reads until `buf` is full or the source ends; returns the bytes read.
fn read_full(src: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match src.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}
