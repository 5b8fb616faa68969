//! A damaged copy of a log, with the exact accounting a reader must report (the
//! simulator's faulty runs and the reader's tests).
//!
//! Faults are placed at least [`SPACING`] records apart and away from control-point
//! marks, so each is accounted on its own (two faults in one spot would be
//! indistinguishable to any reader): bad CRCs, garbage between records, retransmitted
//! duplicates, lost records, reserved record types, time going back, a truncated final
//! record, and `seq` / `odo_count` counters that wrap around 2^32.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::header::FileHeader;
use super::record::{ImuRecord, MarkRecord, SYNC, TYPE_IMU, TYPE_MARK, encode_frame};
use crate::report::IngestReport;

/// Minimum distance, in records, between two faults.
pub const SPACING: usize = 8;
/// `seq` of the first record: the counter wraps about ten seconds in.
pub const SEQ_START: u32 = u32::MAX - 999;
/// Odometer count of the first record: it wraps after 40 000 pulses (500 m).
pub const ODO_START: u32 = u32::MAX - 39_999;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Fault {
    BadCrc,
    Garbage,
    Duplicate,
    Drop(usize),
    Unknown,
    TimeBack,
}

/// The damaged log bytes and the accounting its reader must produce.
#[derive(Debug, Clone)]
pub struct DamagedLog {
    /// The whole file.
    pub bytes: Vec<u8>,
    /// The exact expected ingest report.
    pub expected: IngestReport,
}

/// A whole log: header, IMU records in order, and marks with the index of the IMU
/// record each follows.
#[derive(Debug, Clone, PartialEq)]
pub struct RawLog {
    /// Header.
    pub header: FileHeader,
    /// IMU records in order.
    pub records: Vec<ImuRecord>,
    /// Marks, each with the index of the IMU record it follows.
    pub marks: Vec<(usize, MarkRecord)>,
}

fn push_imu(out: &mut Vec<u8>, r: &ImuRecord) {
    encode_frame(TYPE_IMU, &r.encode_payload(), out);
}

impl RawLog {
    /// The file's bytes, undamaged.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.records.len() * 48 + 256);
        out.extend_from_slice(&self.header.encode());
        let mut marks = self.marks.iter().peekable();
        for (k, r) in self.records.iter().enumerate() {
            push_imu(&mut out, r);
            while let Some((_, m)) = marks.next_if(|(mk, _)| *mk == k) {
                encode_frame(TYPE_MARK, &m.encode_payload(), &mut out);
            }
        }
        out
    }

    /// The file with faults injected (deterministic in `seed`), and its accounting.
    pub fn damage(&self, seed: u64) -> DamagedLog {
        damage(self, seed)
    }
}

fn damage(run: &RawLog, seed: u64) -> DamagedLog {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xFA17_5EED);
    let n = run.records.len();
    let mut plan: Vec<Option<Fault>> = vec![None; n];
    let mut blocked = vec![false; n];
    let block = |blocked: &mut Vec<bool>, from: usize, to: usize| {
        for b in blocked.iter_mut().take(to.min(n)).skip(from) {
            *b = true;
        }
    };
    for (k, _) in &run.marks {
        block(&mut blocked, k.saturating_sub(SPACING), k + SPACING + 1);
    }
    block(&mut blocked, 0, 100.min(n));
    block(&mut blocked, n.saturating_sub(2 * SPACING), n);
    let wanted = [
        (Fault::BadCrc, 6),
        (Fault::Garbage, 6),
        (Fault::Duplicate, 5),
        (Fault::Drop(0), 4),
        (Fault::Unknown, 4),
        (Fault::TimeBack, 3),
    ];
    for (kind, count) in wanted {
        let mut placed = 0;
        let mut tries = 0;
        while placed < count && tries < 10_000 && n > 0 {
            tries += 1;
            let k = rng.random_range(0..n);
            let fault = match kind {
                Fault::Drop(_) => Fault::Drop(rng.random_range(1..=50)),
                other => other,
            };
            let len = if let Fault::Drop(m) = fault { m } else { 1 };
            let from = k.saturating_sub(SPACING);
            let to = (k + len + SPACING).min(n);
            if k + len > n || blocked[from..to].iter().any(|&b| b) {
                continue;
            }
            plan[k] = Some(fault);
            block(&mut blocked, from, to);
            placed += 1;
        }
    }

    let mut e = IngestReport::default();
    let mut w = Vec::with_capacity(n * 48 + 4096);
    w.extend_from_slice(&run.header.encode());
    let mut marks = run.marks.iter().peekable();
    let mut skip = 0usize;
    let mut lost_pending = 0u64;
    let mut prev_t = 0u64;
    for (k, rec) in run.records.iter().enumerate() {
        let mut r = *rec;
        r.seq = SEQ_START.wrapping_add(rec.seq);
        r.odo_count = ODO_START.wrapping_add(rec.odo_count);
        let last = k + 1 == n;
        if skip > 0 {
            skip -= 1;
        } else if last {
            // The final record, cut short by a power loss.
            let mut full = Vec::with_capacity(48);
            push_imu(&mut full, &r);
            let cut = rng.random_range(1..48);
            w.extend_from_slice(&full[..cut]);
            e.records_read += 1;
            e.rejected.truncated += 1;
            e.truncated_bytes += cut as u64;
        } else {
            match plan[k] {
                None => accept(&mut w, &r, &mut e, &mut lost_pending, &mut prev_t),
                Some(Fault::BadCrc) => {
                    let mut bytes = Vec::with_capacity(48);
                    push_imu(&mut bytes, &r);
                    let at = rng.random_range(4..46);
                    bytes[at] ^= rng.random_range(1..=255u8);
                    w.extend_from_slice(&bytes);
                    e.records_read += 1;
                    e.rejected.bad_crc += 1;
                    e.bytes_skipped += bytes.len() as u64;
                    e.resync_events += 1;
                    lost_pending += 1;
                }
                Some(Fault::Garbage) => {
                    let len = rng.random_range(1..=40);
                    let junk: Vec<u8> = (0..len)
                        .map(|_| {
                            loop {
                                let b: u8 = rng.random();
                                if b != SYNC[0] {
                                    break b;
                                }
                            }
                        })
                        .collect();
                    w.extend_from_slice(&junk);
                    e.bytes_skipped += len as u64;
                    e.resync_events += 1;
                    accept(&mut w, &r, &mut e, &mut lost_pending, &mut prev_t);
                }
                Some(Fault::Duplicate) => {
                    accept(&mut w, &r, &mut e, &mut lost_pending, &mut prev_t);
                    push_imu(&mut w, &r);
                    e.records_read += 1;
                    e.rejected.duplicate_seq += 1;
                }
                Some(Fault::Drop(m)) => {
                    lost_pending += m as u64;
                    skip = m - 1;
                }
                Some(Fault::Unknown) => {
                    let len = rng.random_range(0..=64);
                    let payload: Vec<u8> = (0..len).map(|_| rng.random()).collect();
                    encode_frame(rng.random_range(0x10..=0x7F), &payload, &mut w);
                    e.records_read += 1;
                    e.rejected.unknown_type += 1;
                    accept(&mut w, &r, &mut e, &mut lost_pending, &mut prev_t);
                }
                Some(Fault::TimeBack) => {
                    r.t_us = prev_t.saturating_sub(rng.random_range(1..5000));
                    accept(&mut w, &r, &mut e, &mut lost_pending, &mut prev_t);
                    // More than a period off its `seq`'s time, past the first 100 records
                    // (the recorder's clock has learnt its period and jitter): the reader
                    // gives it that time.
                    e.lone_tags_off += 1;
                }
            }
        }
        while let Some((_, mark)) = marks.next_if(|(mk, _)| *mk == k) {
            if !last {
                encode_frame(TYPE_MARK, &mark.encode_payload(), &mut w);
                e.records_read += 1;
                e.records_accepted += 1;
                e.marks_accepted += 1;
            }
        }
    }
    e.lost_duration_s = e.lost_samples as f64 * run.header.sample_period_s();
    DamagedLog {
        bytes: w,
        expected: e,
    }
}

fn accept(
    w: &mut Vec<u8>,
    r: &ImuRecord,
    e: &mut IngestReport,
    lost_pending: &mut u64,
    prev_t: &mut u64,
) {
    push_imu(w, r);
    e.records_read += 1;
    e.records_accepted += 1;
    e.imu_accepted += 1;
    if *lost_pending > 0 {
        e.seq_gaps += 1;
        e.lost_samples += *lost_pending;
        *lost_pending = 0;
    }
    if e.imu_accepted > 1 && r.t_us <= *prev_t {
        e.t_non_increasing += 1;
    }
    *prev_t = r.t_us;
}
