//! The odometer's steps against a land vehicle's speed: a corrupt count or reading (a
//! pulse counter that jumps by a million, a distance of 1e300) would otherwise move the
//! dead reckoning by kilometres in one sample under an "ok" status.

use unz_formats::kfgins::LAND_SPEED_RANGE_MPS;

/// Shortest interval the range is taken over, s: two samples whose time tags jitter close
/// together may step a few pulses without the vehicle being fast (5 m over it).
const MIN_INTERVAL_S: f64 = 0.05;

/// Cumulative distances streamed through the range check: a step beyond
/// [`LAND_SPEED_RANGE_MPS`] is replaced by the previous in-range speed over its interval,
/// and the route after it keeps its own steps. Until the first replaced step the
/// distances pass through bit for bit.
#[derive(Debug, Default)]
pub struct OdometerRange {
    /// Time tag (ns) and distance as given of the last sample.
    last: Option<(i64, f64)>,
    /// The distance kept for it, m.
    kept_m: f64,
    /// Speed of the last in-range step, m/s.
    speed_mps: f64,
    /// Steps replaced.
    pub out_of_range: u64,
    /// Time tag (ns) of the first step replaced, or of the first reading refused
    /// ([`Self::refuse`]).
    pub first_ns: Option<i64>,
}

impl OdometerRange {
    /// The distance to keep for the sample at `t_ns` whose distance is `distance_m` as
    /// given. A time tag not after the last one is taken as no time at all (the derive
    /// repairs and counts those).
    pub fn step(&mut self, t_ns: i64, distance_m: f64) -> f64 {
        let Some((t0_ns, d0_m)) = self.last.replace((t_ns, distance_m)) else {
            self.kept_m = distance_m;
            return distance_m;
        };
        let dt_s = t_ns.saturating_sub(t0_ns).max(0) as f64 * 1e-9;
        let step_m = distance_m - d0_m;
        if step_m.abs() <= LAND_SPEED_RANGE_MPS * dt_s.max(MIN_INTERVAL_S) {
            if dt_s > 0.0 {
                self.speed_mps = step_m / dt_s;
            }
            self.kept_m += step_m;
        } else {
            self.refuse(t_ns);
            self.kept_m += self.speed_mps * dt_s;
        }
        if self.out_of_range == 0 {
            distance_m
        } else {
            self.kept_m
        }
    }

    /// Counts the reading at `t_ns` as beyond a land vehicle's (a speed no step was made
    /// of), with the steps replaced.
    pub fn refuse(&mut self, t_ns: i64) {
        self.out_of_range += 1;
        self.first_ns.get_or_insert(t_ns);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pulse counter at 100 Hz jumping by 12.5 km, and a distance log with a 1e300
    /// line: replaced by the speed before them, the route after them keeps its steps;
    /// in-range distances (a stop, reversing, jittered and repeated tags) pass unchanged.
    #[test]
    fn steps_no_land_vehicle_makes_are_replaced_and_counted() {
        let mut r = OdometerRange::default();
        let given: Vec<f64> = (0..10)
            .map(|k| 0.1 * k as f64 + if k >= 5 { 12_500.0 } else { 0.0 })
            .collect();
        let kept: Vec<f64> = (0..10)
            .map(|k| r.step(k * 10_000_000, given[k as usize]))
            .collect();
        assert_eq!((r.out_of_range, r.first_ns), (1, Some(50_000_000)));
        for (k, d) in kept.iter().enumerate() {
            assert!((d - 0.1 * k as f64).abs() < 1e-9, "{k}: {d}");
        }

        let mut r = OdometerRange::default();
        let plain = [0.0, 0.0, -0.2, -0.1, 3.0, 3.001, 3.001];
        let times = [
            0,
            1_000_000_000,
            2_000_000_000,
            2_000_100_000,
            3_000_000_000,
            3_000_000_001,
            3_000_000_001,
        ];
        for (&t_ns, &d) in times.iter().zip(&plain) {
            assert_eq!(r.step(t_ns, d).to_bits(), d.to_bits());
        }
        assert_eq!((r.out_of_range, r.first_ns), (0, None));

        let mut r = OdometerRange::default();
        let given = [0.0, 10.0, 1e300, 30.0, 40.0];
        let kept: Vec<f64> = given
            .iter()
            .enumerate()
            .map(|(k, &d)| r.step(k as i64 * 1_000_000_000, d))
            .collect();
        assert_eq!((r.out_of_range, r.first_ns), (2, Some(2_000_000_000)));
        assert_eq!(kept, [0.0, 10.0, 20.0, 30.0, 40.0]);
    }
}
