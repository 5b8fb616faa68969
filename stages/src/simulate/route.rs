//! Smooth, analytic vehicle motion: each profile is a sum of non-overlapping raised-cosine
//! pulses, so values, rates and integrals are exact at any time (no numerical
//! differentiation anywhere in the simulator).

use std::f64::consts::TAU;

/// A raised-cosine pulse `amp·(1 − cos(2π(t−t0)/T))/2` on `[t0, t0+T]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pulse {
    /// Start, s.
    pub t0_s: f64,
    /// Duration, s.
    pub dur_s: f64,
    /// Peak value.
    pub amp: f64,
}

impl Pulse {
    fn phase(&self, t: f64) -> f64 {
        TAU * (t - self.t0_s) / self.dur_s
    }

    /// Value at `t`.
    pub fn value(&self, t: f64) -> f64 {
        if t <= self.t0_s || t >= self.t0_s + self.dur_s {
            return 0.0;
        }
        0.5 * self.amp * (1.0 - self.phase(t).cos())
    }

    /// Time derivative at `t`.
    pub fn rate(&self, t: f64) -> f64 {
        if t <= self.t0_s || t >= self.t0_s + self.dur_s {
            return 0.0;
        }
        self.amp * std::f64::consts::PI / self.dur_s * self.phase(t).sin()
    }

    /// Integral from `t0` to `t` (clamped to the pulse).
    pub fn integral(&self, t: f64) -> f64 {
        let tau = (t - self.t0_s).clamp(0.0, self.dur_s);
        0.5 * self.amp * (tau - self.dur_s / TAU * (TAU * tau / self.dur_s).sin())
    }

    /// Integral over the whole pulse.
    pub fn area(&self) -> f64 {
        0.5 * self.amp * self.dur_s
    }
}

/// A sequence of non-overlapping pulses, sorted by start time.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Profile {
    pulses: Vec<Pulse>,
    /// Sum of the areas of the pulses before index i.
    areas_before: Vec<f64>,
}

impl Profile {
    /// Builds a profile; pulses are sorted and must not overlap.
    pub fn new(mut pulses: Vec<Pulse>) -> Self {
        pulses.sort_by(|a, b| a.t0_s.total_cmp(&b.t0_s));
        debug_assert!(
            pulses
                .windows(2)
                .all(|w| w[0].t0_s + w[0].dur_s <= w[1].t0_s + 1e-9)
        );
        let mut acc = 0.0;
        let areas_before = pulses
            .iter()
            .map(|p| {
                let a = acc;
                acc += p.area();
                a
            })
            .collect();
        Self {
            pulses,
            areas_before,
        }
    }

    /// The pulses.
    pub fn pulses(&self) -> &[Pulse] {
        &self.pulses
    }

    /// Index of the last pulse starting at or before `t`.
    fn index(&self, t: f64) -> Option<usize> {
        self.pulses.partition_point(|p| p.t0_s <= t).checked_sub(1)
    }

    /// Value at `t` (the pulses as a function).
    pub fn value(&self, t: f64) -> f64 {
        self.index(t).map_or(0.0, |i| self.pulses[i].value(t))
    }

    /// Derivative at `t`.
    pub fn rate(&self, t: f64) -> f64 {
        self.index(t).map_or(0.0, |i| self.pulses[i].rate(t))
    }

    /// Integral from −∞ to `t`.
    pub fn integral(&self, t: f64) -> f64 {
        self.index(t)
            .map_or(0.0, |i| self.areas_before[i] + self.pulses[i].integral(t))
    }
}

/// The vehicle's motion: speed is the integral of the acceleration profile, heading the
/// integral of the yaw-rate profile; pitch and roll are profiles themselves.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Motion {
    /// Heading at t = 0, rad.
    pub heading0_rad: f64,
    /// Longitudinal acceleration along the path, m/s².
    pub accel: Profile,
    /// Heading rate, rad/s.
    pub yaw_rate: Profile,
    /// Pitch, rad.
    pub pitch: Profile,
    /// Roll, rad.
    pub roll: Profile,
    /// Constant pitch added to the profile, rad.
    pub pitch0_rad: f64,
    /// Constant roll added to the profile, rad.
    pub roll0_rad: f64,
}

/// Kinematic state of the vehicle at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kinematics {
    /// Speed along body x, m/s.
    pub speed_mps: f64,
    /// Its derivative, m/s².
    pub accel_mps2: f64,
    /// Euler angles, rad.
    pub euler: crate::attitude::Euler,
    /// Euler angle rates (roll, pitch, heading), rad/s.
    pub euler_rates: [f64; 3],
}

impl Motion {
    /// The state at `t`.
    pub fn at(&self, t: f64) -> Kinematics {
        Kinematics {
            speed_mps: self.accel.integral(t),
            accel_mps2: self.accel.value(t),
            euler: crate::attitude::Euler {
                roll_rad: self.roll0_rad + self.roll.value(t),
                pitch_rad: self.pitch0_rad + self.pitch.value(t),
                heading_rad: self.heading0_rad + self.yaw_rate.integral(t),
            },
            euler_rates: [
                self.roll.rate(t),
                self.pitch.rate(t),
                self.yaw_rate.value(t),
            ],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pulse_integral_and_rate_are_consistent() {
        let p = Pulse {
            t0_s: 1.0,
            dur_s: 3.0,
            amp: 2.0,
        };
        let h = 1e-6;
        for t in [1.3, 2.0, 2.5, 3.9] {
            let num_rate = (p.value(t + h) - p.value(t - h)) / (2.0 * h);
            assert!((num_rate - p.rate(t)).abs() < 1e-6);
            let num_int = (p.integral(t + h) - p.integral(t - h)) / (2.0 * h);
            assert!((num_int - p.value(t)).abs() < 1e-6);
        }
        assert!((p.integral(10.0) - p.area()).abs() < 1e-12);
        let prof = Profile::new(vec![
            p,
            Pulse {
                t0_s: 5.0,
                dur_s: 1.0,
                amp: -1.0,
            },
        ]);
        assert!((prof.integral(100.0) - (3.0 - 0.5)).abs() < 1e-12);
    }
}
