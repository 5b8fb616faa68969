//! How many passes over one run hold their Kryt1 blocks at once, so that the searches'
//! fan-out across many threads stays within a memory budget.
//!
//! Each pass of the criteria keeps its blocks' pitch and roll for the whole run
//! ([`super::CriteriaSink`]: F runs forward, then back over them), 16 bytes a block: 6.9
//! MB a pass over a 12-hour run at 100 Hz in blocks of 10 samples. A search that gives
//! each of its few points a thread of its own holds one such sink per thread: on 16
//! threads a 12-hour run's methods held 15 at once (103 MB) where two threads hold 8.
//! The passes count themselves here ([`LanesInFlight::hold`]), and the fan-outs and the
//! walks in batches ask how many more fit ([`LanesInFlight::room`]) before they start a
//! wave ([`wave_len`]) or a batch ([`batch_within`]).

use std::sync::atomic::{AtomicUsize, Ordering};

use super::batch_lanes;

/// Kryt1 block memory the passes over one run may hold at once before a fan-out runs
/// its points in waves and a walk its batches smaller, bytes: nine passes of a 12-hour run,
/// more than two threads ever hold (eight), so a two-core machine is never held back;
/// 174 of a 40-minute run's, which no search reaches.
pub const BLOCKS_IN_FLIGHT_BUDGET_BYTES: usize = 64 << 20;

/// Bytes a pass's Kryt1 blocks take (pitch and roll in f64 per block).
pub const BLOCK_BYTES: usize = 2 * std::mem::size_of::<f64>();

/// The passes over one run in flight (shared by the problems on the run and its
/// re-derives), counted in lanes: one lane, one sink of the run's blocks.
#[derive(Debug, Default)]
pub struct LanesInFlight {
    lanes: AtomicUsize,
    peak: AtomicUsize,
}

/// Lanes held by passes in flight, given back when dropped.
#[derive(Debug)]
#[must_use = "the lanes are given back when this is dropped"]
pub struct HeldLanes<'a> {
    of: &'a LanesInFlight,
    lanes: usize,
}

impl Drop for HeldLanes<'_> {
    fn drop(&mut self) {
        self.of.lanes.fetch_sub(self.lanes, Ordering::AcqRel);
    }
}

impl LanesInFlight {
    /// Counts `lanes` passes in flight until the guard is dropped. Never waits: a batch
    /// already decided on runs; the budget is kept by the fan-outs asking
    /// [`Self::room`] first.
    pub fn hold(&self, lanes: usize) -> HeldLanes<'_> {
        let now = self.lanes.fetch_add(lanes, Ordering::AcqRel) + lanes;
        self.peak.fetch_max(now, Ordering::Relaxed);
        HeldLanes { of: self, lanes }
    }

    /// How many more lanes fit in `cap` lanes beside those in flight now.
    pub fn room(&self, cap: usize) -> usize {
        cap.saturating_sub(self.lanes.load(Ordering::Acquire))
    }

    /// Lanes in flight now.
    pub fn now(&self) -> usize {
        self.lanes.load(Ordering::Acquire)
    }

    /// The most lanes in flight at once so far.
    pub fn peak(&self) -> usize {
        self.peak.load(Ordering::Relaxed)
    }

    /// `items` in consecutive slices, each `size(left, room)` long (at least one item):
    /// `left` the items not yet taken, `room` what `cap` lanes leave beside those in
    /// flight when the slice is taken. Taken in turn, each slice's room is read once the
    /// passes of the one before are done ([`wave_len`], [`batch_within`]).
    pub fn slices<'s, T>(
        &'s self,
        items: &'s [T],
        cap: usize,
        size: fn(usize, usize) -> usize,
    ) -> Slices<'s, T> {
        Slices {
            of: self,
            left: items,
            cap,
            size,
        }
    }
}

/// The slices of [`LanesInFlight::slices`].
pub struct Slices<'s, T> {
    of: &'s LanesInFlight,
    left: &'s [T],
    cap: usize,
    size: fn(usize, usize) -> usize,
}

impl<'s, T> Iterator for Slices<'s, T> {
    type Item = &'s [T];

    fn next(&mut self) -> Option<&'s [T]> {
        if self.left.is_empty() {
            return None;
        }
        let n = (self.size)(self.left.len(), self.of.room(self.cap)).clamp(1, self.left.len());
        let (slice, rest) = self.left.split_at(n);
        self.left = rest;
        Some(slice)
    }
}

/// The lanes whose blocks fit in `budget_bytes` for passes over `samples` samples in
/// blocks of `block`: at least `least` (a fan-out's one batch, whatever the budget).
pub fn lanes_within(budget_bytes: usize, samples: usize, block: usize, least: usize) -> usize {
    let lane_bytes = samples.div_ceil(block.max(1)).max(1) * BLOCK_BYTES;
    (budget_bytes / lane_bytes).max(least)
}

/// The next wave of a fan-out over `left` points, `room` lanes free: all that fit, at
/// least one (a fan-out always moves on; its passes wait for none of the others).
pub fn wave_len(left: usize, room: usize) -> usize {
    left.min(room.max(1))
}

/// The points of the next batch of a walk over `left` points in batches of at most
/// `most`, `room` lanes free: a full batch when its lanes ([`batch_lanes`]) fit, else one
/// of four lanes when those do, else a single point (a walk always moves on).
pub fn batch_within(left: usize, room: usize, most: usize) -> usize {
    let want = left.min(most);
    if batch_lanes(want) <= room {
        want
    } else if batch_lanes(want.min(4)) <= room {
        want.min(4)
    } else {
        want.min(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn held_lanes_are_counted_until_dropped_and_the_peak_kept() {
        let f = LanesInFlight::default();
        let a = f.hold(4);
        {
            let _b = f.hold(3);
            assert_eq!(f.now(), 7);
            assert_eq!(f.room(9), 2);
            assert_eq!(f.room(5), 0);
        }
        assert_eq!(f.now(), 4);
        drop(a);
        assert_eq!(f.now(), 0);
        assert_eq!(f.peak(), 7);
    }

    #[test]
    fn a_twelve_hour_runs_budget_holds_nine_passes_and_a_short_runs_many() {
        // 12 h at 100 Hz in blocks of 10: 432 000 blocks, 6.912 MB a pass.
        assert_eq!(
            lanes_within(BLOCKS_IN_FLIGHT_BUDGET_BYTES, 4_320_000, 10, 1),
            9
        );
        // 40 min: 24 000 blocks, 384 kB.
        assert_eq!(
            lanes_within(BLOCKS_IN_FLIGHT_BUDGET_BYTES, 240_000, 10, 1),
            174
        );
        // Never fewer than a batch, nor none for an empty run.
        assert_eq!(lanes_within(1 << 20, 4_320_000, 10, 4), 4);
        assert!(lanes_within(BLOCKS_IN_FLIGHT_BUDGET_BYTES, 0, 0, 1) > 1_000_000);
    }

    #[test]
    fn a_batch_takes_the_lanes_that_fit_and_never_nothing() {
        // Room for a whole batch.
        assert_eq!(batch_within(10, 9, 8), 8);
        assert_eq!(batch_within(3, 9, 4), 3);
        // Room for four lanes only: a batch of four points (or of two or three, run in
        // four lanes).
        assert_eq!(batch_within(10, 5, 8), 4);
        assert_eq!(batch_within(3, 4, 4), 3);
        // Room for fewer than four: one point at a time, even with none free.
        assert_eq!(batch_within(3, 3, 4), 1);
        assert_eq!(batch_within(10, 0, 8), 1);
        assert_eq!(batch_within(0, 9, 8), 0);
    }

    #[test]
    fn a_wave_takes_what_fits_and_never_nothing() {
        assert_eq!(wave_len(12, 9), 9);
        assert_eq!(wave_len(3, 9), 3);
        assert_eq!(wave_len(5, 0), 1);
        assert_eq!(wave_len(0, 4), 0);
    }
}
