//! A speed odometer's floor (`[odometer] speed_floor_mps`): readings at or below it in
//! magnitude are read as 0, and what that took away is counted.
//!
//! A speed sensor's noise at rest (a GNSS ground speed's few cm/s, never negative) is
//! integrated by the trapezoid into travel the vehicle never made: Kingston's speeds
//! with 0–4 cm/s where they read 0 counted 10.6 m over its 527-s stand, and its hold-out
//! errors were 25 and 37 m against 2.2 and 3.0 m. The floor is the manifest's, not a
//! default: it changes what was logged, and a vehicle creeping below it is read as
//! standing (a stop braked at 0.5 m/s² spends 0.1 s below 5 cm/s: 2.5 mm at each end).

use serde::{Deserialize, Serialize};

/// Highest floor a manifest may set, m/s: the speed of a move
/// (`unz_stages::initial::MOVED_M` over its second); a floor above it would read a
/// vehicle the stand's detection sees moving as standing.
pub const SPEED_FLOOR_MAX_MPS: f64 = 0.1;

/// What a floor took away (`ingest.json`'s `speed_floor`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeedFloorReport {
    /// The floor, m/s: readings at or below it in magnitude were read as 0.
    pub floor_mps: f64,
    /// Readings kept that were not 0 and were read as 0.
    pub readings_floored: u64,
    /// Distance the trapezoid would have integrated from them as written, m (signed:
    /// forward less backward).
    pub floored_m: f64,
}

impl SpeedFloorReport {
    /// What it did, for the run's log and its row of the campaign summary.
    pub fn said(&self) -> String {
        format!(
            "the odometer's speeds at or below {} m/s were read as 0 ([odometer] \
             speed_floor_mps): {} reading{}, {:.2} m of travel as written",
            self.floor_mps,
            self.readings_floored,
            if self.readings_floored == 1 { "" } else { "s" },
            self.floored_m
        )
    }
}

/// A floor applied to speeds in order, with its accounting.
#[derive(Debug, Clone, Copy)]
pub struct SpeedFloor {
    report: SpeedFloorReport,
    /// The last reading's time, s, and what the floor took from it, m/s.
    prev: Option<(f64, f64)>,
}

impl SpeedFloor {
    /// A floor of `floor_mps` (0: every reading as written).
    pub fn new(floor_mps: f64) -> Self {
        Self {
            report: SpeedFloorReport {
                floor_mps,
                ..SpeedFloorReport::default()
            },
            prev: None,
        }
    }

    /// The reading `v_mps` at `t_s` as read: 0 at or below the floor. Readings come in time
    /// order; one not after the last adds no distance, as the trapezoid adds none.
    pub fn read(&mut self, t_s: f64, v_mps: f64) -> f64 {
        let floored = v_mps != 0.0 && v_mps.abs() <= self.report.floor_mps;
        let taken_mps = if floored { v_mps } else { 0.0 };
        self.report.readings_floored += u64::from(floored);
        if let Some((t0_s, taken0_mps)) = self.prev
            && t_s > t0_s
        {
            self.report.floored_m += 0.5 * (taken0_mps + taken_mps) * (t_s - t0_s);
        }
        self.prev = Some((t_s, taken_mps));
        if floored { 0.0 } else { v_mps }
    }

    /// What it took away so far.
    pub fn report(&self) -> SpeedFloorReport {
        self.report
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Readings at or below the floor are 0, the rest as written, and the distance taken
    /// is the trapezoid's over what was taken: here 0.5·(0.03 + 0.04) + 0.5·0.04 −
    /// 0.5·0.04 − 0.5·0.04 m over 1-s steps.
    #[test]
    fn readings_at_or_below_the_floor_are_zero_and_their_distance_is_counted() {
        let mut f = SpeedFloor::new(0.04);
        let readings = [
            (0.0, 0.03),
            (1.0, 0.04),
            (2.0, 2.0),
            (3.0, 0.0),
            (4.0, -0.04),
            (5.0, -0.05),
        ];
        let read: Vec<f64> = readings.iter().map(|&(t, v)| f.read(t, v)).collect();
        assert_eq!(read, [0.0, 0.0, 2.0, 0.0, 0.0, -0.05]);
        let r = f.report();
        assert_eq!(r.readings_floored, 3);
        assert!((r.floored_m - 0.015).abs() < 1e-15, "{r:?}");
    }

    /// A reading not after the last adds no distance (the trapezoid adds none either).
    #[test]
    fn a_time_not_after_the_last_adds_nothing() {
        let mut f = SpeedFloor::new(0.05);
        f.read(1.0, 0.02);
        f.read(1.0, 0.02);
        assert_eq!(f.report().readings_floored, 2);
        assert_eq!(f.report().floored_m, 0.0);
    }
}
