//! Which way the odometer's distance runs: a vehicle drives ahead, and reverses metres
//! in kilometres (a parking manoeuvre).
//!
//! An odometer whose distance runs backward over most of the log counts with its sign
//! reversed. Its accelerations are then the accelerometers' turned by 180°, exactly as an
//! IMU mounted facing backwards makes them: the axes' check alone would name the IMU's
//! axes. One that runs backward about as much as ahead is no distance a vehicle drives:
//! a file of speeds read as distances (it rises as the vehicle speeds up, falls as it
//! slows, and ends where it began), whose accelerations are the vehicle's jerk.

use crate::derive::Derived;

/// Least travel, ahead and back, for the log to be judged, m.
pub const MIN_TRAVEL_M: f64 = 50.0;

/// Largest share of the travel backward in a log that is driven ahead: a parking
/// manoeuvre is metres in kilometres; a third of the travel is no field run's.
pub const MAX_BACKWARD_SHARE: f64 = 1.0 / 3.0;

/// The odometer's travel over a log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Travel {
    /// Sum of the distance's increments ahead, m.
    pub ahead_m: f64,
    /// Sum of its increments backward, m (positive).
    pub back_m: f64,
}

/// What the travel says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TravelVerdict {
    /// Driven ahead, or too little travel to tell.
    Ahead,
    /// Backward over most of it (more than 1 − [`MAX_BACKWARD_SHARE`]): the sign is
    /// reversed.
    Reversed,
    /// Backward over [`MAX_BACKWARD_SHARE`] or more, ahead over as much: not a distance.
    BackAndForth,
}

impl Travel {
    /// The travel of `d`'s odometer.
    pub fn of(d: &Derived) -> Self {
        let (mut ahead_m, mut back_m) = (0.0, 0.0);
        for &dd in d.odo_dist_m.iter().filter(|v| v.is_finite()) {
            if dd > 0.0 {
                ahead_m += dd;
            } else {
                back_m -= dd;
            }
        }
        Self { ahead_m, back_m }
    }

    /// The share of the travel backward (0–1).
    pub fn backward_share(&self) -> f64 {
        self.back_m / (self.ahead_m + self.back_m).max(f64::MIN_POSITIVE)
    }

    /// The verdict.
    pub fn verdict(&self) -> TravelVerdict {
        let share = self.backward_share();
        if self.ahead_m + self.back_m < MIN_TRAVEL_M {
            TravelVerdict::Ahead
        } else if share > 1.0 - MAX_BACKWARD_SHARE {
            TravelVerdict::Reversed
        } else if share >= MAX_BACKWARD_SHARE {
            TravelVerdict::BackAndForth
        } else {
            TravelVerdict::Ahead
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn travel(steps: &[f64]) -> Travel {
        Travel::of(&Derived {
            odo_dist_m: steps.to_vec(),
            ..Derived::default()
        })
    }

    #[test]
    fn a_drive_with_a_manoeuvre_is_ahead() {
        let mut steps = vec![0.5; 4000];
        steps.extend([-0.2; 100]);
        let t = travel(&steps);
        assert!(
            (t.ahead_m - 2000.0).abs() < 1e-9 && (t.back_m - 20.0).abs() < 1e-9,
            "{t:?}"
        );
        assert_eq!(t.verdict(), TravelVerdict::Ahead);
    }

    #[test]
    fn a_count_running_backward_is_reversed() {
        let mut steps = vec![-0.5; 4000];
        steps.extend([0.2; 100]);
        assert_eq!(travel(&steps).verdict(), TravelVerdict::Reversed);
    }

    /// Speeds read as distances: up as the vehicle speeds up, down as it slows.
    #[test]
    fn speeds_read_as_distances_run_back_and_forth() {
        let speeds: Vec<f64> = (0..2000)
            .map(|i| 15.0 * (i as f64 * 0.01).sin().abs())
            .collect();
        let steps: Vec<f64> = speeds.windows(2).map(|w| w[1] - w[0]).collect();
        let t = travel(&steps);
        assert!((t.backward_share() - 0.5).abs() < 0.05, "{t:?}");
        assert_eq!(t.verdict(), TravelVerdict::BackAndForth);
    }

    /// Too little travel is not judged, nor are non-finite steps counted.
    #[test]
    fn a_log_at_rest_is_not_judged() {
        assert_eq!(travel(&[-0.1; 400]).verdict(), TravelVerdict::Ahead);
        assert_eq!(travel(&[f64::NAN; 10]).ahead_m, 0.0);
    }
}
