//! The odometer's bridged failures, bridged again at each lag the joint fit tries.
//!
//! The ingest bridges a failure at the odometer's lag the readings around it show
//! ([`crate::odo_bridge::bridge`], searched about the configured lag). Readings at rest
//! on one side of a failure and at a constant speed on the other show none: the bridge is
//! then off by the lag times the change of speed across it (measured: a minute's failure
//! from a stop, the odometer 0.4 s late and no lag configured, bridged 0.3–4.5 m off on
//! seven simulated runs). The whole run shows the lag, and the joint fit estimates it
//! ([`crate::odo_lag`]) by re-deriving the odometer at each lag it tries. Here each such
//! re-derive bridges the failures again at its lag
//! ([`crate::odo_bridge::bridge_at_lag`]), from the ingested readings around them and the
//! derive's IMU increments: the route a trial scores is the one its lag makes, failures
//! included, and the corrected route is bridged at the estimated lag.
//!
//! A binary log's odometer has a row per IMU sample (its count is in the IMU's record),
//! which is what makes the rows and the samples one: a run whose rows are not (a text
//! log's odometer at its own rate, its file's gaps bridged by the ingest alone) is left
//! as ingested.

use std::ops::Range;
use std::sync::{Arc, Mutex, PoisonError};

use rayon::prelude::*;

use crate::derive::{Derived, OdoPatch, PatchSpan};
use crate::odo_bridge::{Bridge, BridgeSample, Reading, WINDOW_S, bridge_at_lag};

/// Failures bridged again at most, the longest first: each lag the joint fit tries
/// bridges each of them once (a minute's failure in about 30 M instructions, a 3-s one
/// in about as many, some twelve lags a run: 70 failures of 3 s took the disupt process
/// from 0.34 to 1.42 s). The others stay as the ingest bridged them.
pub const MAX_REBRIDGED: usize = 64;

/// The IMU's velocity increments over each of some windows' samples, body FRD, m/s.
pub type WindowVelocities = Vec<Vec<[f64; 3]>>;

/// Consecutive odometer rows whose distances are not the odometer's readings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FailedRows {
    /// The first row.
    pub first: usize,
    /// Rows.
    pub len: usize,
    /// Bridged; else the distance held.
    pub bridged: bool,
}

/// A failure's bridge window, in rows (= IMU samples): readings before it from `start`,
/// failed rows from `first` to `end_failed`, readings after it to `end`.
#[derive(Debug, Clone, PartialEq)]
struct Window {
    start: usize,
    first: usize,
    end_failed: usize,
    end: usize,
    /// The IMU's velocity increments over the window, body FRD, m/s (the disupt stage's
    /// derive holds none).
    dvel_mps: Vec<[f64; 3]>,
}

/// A run's bridged failures, to bridge again at any odometer lag.
#[derive(Debug)]
pub struct Rebridges<'a> {
    derived: &'a Derived,
    /// The ingested distances, one per IMU sample of `derived`, m.
    odo_distance_m: &'a [f64],
    windows: Vec<Window>,
    g_mps2: f64,
    /// The odometer's lag behind its own tags at the joint's lag zero, s: the
    /// configured time offset, negated.
    lag_at_zero_s: f64,
    /// Bridged failures beyond [`MAX_REBRIDGED`], left as the ingest bridged them.
    left: usize,
    /// The last lag bridged, and its patch: the joint's estimated lag is bridged for its
    /// derive and again for its report.
    last: Mutex<Option<(f64, Arc<OdoPatch>)>>,
}

/// What bridging again at a lag changed.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Rebridged {
    /// Failures bridged again.
    pub failures: usize,
    /// Bridged failures left as the ingest bridged them (beyond [`MAX_REBRIDGED`], or
    /// whose fit at the lag failed).
    pub left: usize,
    /// The largest change of a failure's distance across it against the ingest's
    /// bridge, m, with its sign (to its last sample, for a failure the log ends in).
    pub largest_change_m: f64,
}

impl<'a> Rebridges<'a> {
    /// The bridged failures among `failed` (in row order), whose windows are in the
    /// ingested odometer `odo_distance_m` and the IMU samples of `derived` (its velocity
    /// increments over the windows' samples given by `velocity`); gravity is `g_mps2`,
    /// and the odometer is `lag_at_zero_s` late at the joint's lag zero. `None` without a
    /// bridged failure, or when the odometer's rows are not the IMU's samples.
    pub fn new<E>(
        derived: &'a Derived,
        odo_distance_m: &'a [f64],
        failed: &[FailedRows],
        g_mps2: f64,
        lag_at_zero_s: f64,
        velocity: impl FnOnce(&[Range<usize>]) -> Result<WindowVelocities, E>,
    ) -> Result<Option<Self>, E> {
        let n = derived.t_s.len();
        if odo_distance_m.len() != n || !lag_at_zero_s.is_finite() {
            return Ok(None);
        }
        let t = |k: usize| derived.t_s.get(k);
        let mut windows = Vec::new();
        for (i, f) in failed.iter().enumerate() {
            let end_failed = f.first.saturating_add(f.len);
            if !f.bridged || f.len == 0 || end_failed > n {
                continue;
            }
            // Readings up to WINDOW_S each side, not across another failure.
            let floor = i
                .checked_sub(1)
                .map_or(0, |j| failed[j].first + failed[j].len);
            let ceiling = failed.get(i + 1).map_or(n, |g| g.first.min(n));
            let mut start = f.first;
            while start > floor && t(f.first) - t(start - 1) <= WINDOW_S {
                start -= 1;
            }
            let mut end = end_failed;
            while end < ceiling && t(end) - t(end_failed.min(n - 1)) <= WINDOW_S {
                end += 1;
            }
            windows.push(Window {
                start,
                first: f.first,
                end_failed,
                end,
                dvel_mps: Vec::new(),
            });
        }
        if windows.is_empty() {
            return Ok(None);
        }
        let left = windows.len().saturating_sub(MAX_REBRIDGED);
        if left > 0 {
            // The longest, in row order again.
            windows.sort_by_key(|w| (std::cmp::Reverse(w.end_failed - w.first), w.first));
            windows.truncate(MAX_REBRIDGED);
            windows.sort_by_key(|w| w.first);
        }
        let rows: Vec<Range<usize>> = windows.iter().map(|w| w.start..w.end).collect();
        for (w, v) in windows.iter_mut().zip(velocity(&rows)?) {
            if v.len() != w.end - w.start {
                return Ok(None);
            }
            w.dvel_mps = v;
        }
        Ok(Some(Self {
            derived,
            odo_distance_m,
            windows,
            g_mps2,
            lag_at_zero_s,
            left,
            last: Mutex::new(None),
        }))
    }

    /// The distances of the failures bridged at the joint's `lag_s`, and what the change
    /// of each moves the rows after it by.
    pub fn patch_at(&self, lag_s: f64) -> Arc<OdoPatch> {
        let last = || self.last.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((at, patch)) = &*last()
            && at.to_bits() == lag_s.to_bits()
        {
            return patch.clone();
        }
        // Bridged without the lock held (the fits run on the pool).
        let patch = Arc::new(self.bridged_at(lag_s));
        *last() = Some((lag_s, patch.clone()));
        patch
    }

    /// What bridging at the joint's `lag_s` changes against the ingest's bridges.
    pub fn changes_at(&self, lag_s: f64) -> Rebridged {
        let patch = self.patch_at(lag_s);
        let odo = self.odo_distance_m;
        let mut windows = self.windows.iter();
        let mut shift_before = 0.0;
        let mut largest_change_m: f64 = 0.0;
        for s in &patch.spans {
            let end = s.first + s.distance_m.len();
            // Each span is a window's (those whose fit failed have none).
            let after = windows
                .find(|w| w.first == s.first)
                .is_some_and(|w| w.end > w.end_failed);
            let change = if after {
                // The rows after it move by the change across.
                s.shift_after_m - shift_before
            } else {
                s.distance_m.last().copied().unwrap_or(0.0) - shift_before - odo[end - 1]
            };
            if change.abs() > largest_change_m.abs() {
                largest_change_m = change;
            }
            shift_before = s.shift_after_m;
        }
        Rebridged {
            failures: patch.spans.len(),
            // With the failures whose fit failed at the lag.
            left: self.left + self.windows.len() - patch.spans.len(),
            largest_change_m,
        }
    }

    /// The failures bridged at the joint's `lag_s`: each on its own (side by side), then
    /// in order, each moving the rows after it.
    fn bridged_at(&self, lag_s: f64) -> OdoPatch {
        let (d, odo) = (self.derived, self.odo_distance_m);
        let lag_s = self.lag_at_zero_s + lag_s;
        let bridges: Vec<Option<Bridge>> = self
            .windows
            .par_iter()
            .map(|w| {
                let window: Vec<BridgeSample> = (w.start..w.end)
                    .zip(&w.dvel_mps)
                    .map(|(k, dvel_mps)| BridgeSample {
                        t_s: d.t_s.get(k),
                        dtheta_rad: d.dtheta_rad.get(k),
                        dvel_mps: *dvel_mps,
                        reading: if k < w.first {
                            Reading::Before(odo[k])
                        } else if k < w.end_failed {
                            Reading::Failed
                        } else {
                            Reading::After(odo[k])
                        },
                    })
                    .collect();
                bridge_at_lag(&window, self.g_mps2, lag_s)
            })
            .collect();
        let mut shift_m = 0.0;
        let mut spans = Vec::with_capacity(self.windows.len());
        for (w, b) in self.windows.iter().zip(bridges) {
            // A failure whose fit failed stays as the ingest bridged it.
            let Some(b) = b else {
                continue;
            };
            // Without readings before, the bridge starts where the ingest's did.
            let anchor_m = if w.start == w.first {
                odo[w.first]
            } else {
                0.0
            };
            let distance_m = b
                .failed_distance_m
                .iter()
                .map(|x| x + anchor_m + shift_m)
                .collect();
            shift_m += b.after_offset_m + anchor_m;
            spans.push(PatchSpan {
                first: w.first,
                distance_m,
                shift_after_m: shift_m,
            });
        }
        OdoPatch { spans }
    }
}
