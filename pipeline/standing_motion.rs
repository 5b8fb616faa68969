//! Whether a vehicle whose odometer count stands is moving, from the IMU: a count that
//! stops while the vehicle stands (a sensor or cable that fails at a stop) stays stopped
//! as it drives off, and no braking tells it from a stop.
//!
//! While the count stands, the specific force over a reference of [`REFERENCE_S`] is
//! gravity's (the vehicle at rest) plus the accelerometers' biases. Over the
//! [`WATCH_S`] after it, the along-track speed is the x specific force less the
//! reference's, less gravity's part along x as the gyros turn the body from the
//! reference's attitude (a pitch at rest, someone climbing in, is not motion). Once
//! that speed and the distance it gives pass [`MOVING_MPS`] and [`MOVED_M`], the vehicle
//! moves while the count stands: the count is stuck since the reference's end. The
//! reference then slides with the watch, so a stop of any length is watched.
//!
//! The Earth's rate turns the gyros' attitude by 0.3 mrad over the watch (0.003 m/s²
//! along x), an LN-200's velocity noise integrates to millimetres: a metre is far
//! beyond both. A vehicle carried while its wheels stand (a ferry, a train) is taken as
//! moving, as it is.

use std::collections::VecDeque;

use nalgebra::Vector3;

/// The reference taken as at rest, s.
pub const REFERENCE_S: f64 = 2.0;
/// The motion watched after the reference, s.
pub const WATCH_S: f64 = 5.0;
/// Along-track speed that is motion, m/s.
pub const MOVING_MPS: f64 = 0.5;
/// Along-track distance that is motion, m: some 80 pulses of 12.5 mm the count did not
/// give. A vehicle pulling away at 1 m/s² is found 1.4 s after it starts, at 0.2 m/s² in
/// 3.2 s.
pub const MOVED_M: f64 = 1.0;
/// The watch is judged every this many samples (0.1 s at 100 Hz).
const JUDGE_EVERY: usize = 10;

/// One IMU sample of the watch.
#[derive(Debug, Clone, Copy)]
struct Step {
    t_s: f64,
    dt_s: f64,
    dvel_mps: Vector3<f64>,
    dtheta_rad: Vector3<f64>,
}

/// What the IMU says of a sample while the count stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Motion {
    /// Taken into the reference: nothing to hold.
    Reference,
    /// Watched: hold it (a stuck count would fail it); samples before `release_before_s`
    /// have left the watch.
    Watching {
        /// The reference's end, s.
        release_before_s: f64,
    },
    /// Moving: this sample and the `watched` before it in the watch fail.
    Moving {
        /// Samples of the watch before this one.
        watched: usize,
    },
}

/// The IMU's samples while the count stands: a reference, then a watch.
#[derive(Debug)]
pub struct StandingMotion {
    g_mps2: f64,
    period_s: f64,
    steps: VecDeque<Step>,
    since_judged: usize,
}

impl StandingMotion {
    /// Where gravity is `g_mps2`, samples every `period_s`.
    pub fn new(g_mps2: f64, period_s: f64) -> Self {
        Self {
            g_mps2,
            period_s: period_s.abs(),
            steps: VecDeque::new(),
            since_judged: 0,
        }
    }

    /// The count moved (or failed): the next stand starts afresh.
    pub fn reset(&mut self) {
        self.steps.clear();
        self.since_judged = 0;
    }

    /// Takes the next sample while the count stands (its increments within the IMU's
    /// range: [`crate::odometer_bridge`] replaces those beyond).
    pub fn push(&mut self, t_s: f64, dvel_mps: [f64; 3], dtheta_rad: [f64; 3]) -> Motion {
        // A tag step beyond two periods (a clock that jumps) counts as two.
        let dt_s = self.steps.back().map_or(self.period_s, |b| {
            (t_s - b.t_s).clamp(0.0, 2.0 * self.period_s)
        });
        self.steps.push_back(Step {
            t_s,
            dt_s,
            dvel_mps: Vector3::from(dvel_mps),
            dtheta_rad: Vector3::from(dtheta_rad),
        });
        while self
            .steps
            .front()
            .is_some_and(|f| f.t_s < t_s - REFERENCE_S - WATCH_S)
        {
            self.steps.pop_front();
        }
        let reference_end_s = self.steps.front().map_or(t_s, |f| f.t_s) + REFERENCE_S;
        if t_s < reference_end_s {
            return Motion::Reference;
        }
        self.since_judged += 1;
        if self.since_judged >= JUDGE_EVERY {
            self.since_judged = 0;
            if let Some(watched) = self.moving(reference_end_s) {
                self.reset();
                return Motion::Moving { watched };
            }
        }
        Motion::Watching {
            release_before_s: reference_end_s,
        }
    }

    /// The samples of the watch before the last, if the vehicle moved over it. Forces
    /// and gravity are taken in the body's axes at the reference's start (the gyros'
    /// turn since then, small over seconds), so a body that turns during the reference
    /// does not tilt it.
    fn moving(&self, reference_end_s: f64) -> Option<usize> {
        let (mut force, mut time_s) = (Vector3::zeros(), 0.0);
        let mut turned = Vector3::zeros();
        for s in self.steps.iter().take_while(|s| s.t_s < reference_end_s) {
            let half = turned + 0.5 * s.dtheta_rad;
            force += s.dvel_mps + half.cross(&s.dvel_mps);
            turned += s.dtheta_rad;
            time_s += s.dt_s;
        }
        if time_s <= 0.0 {
            return None;
        }
        let force_mps2 = force / time_s;
        let down = -force_mps2.try_normalize(f64::MIN_POSITIVE)?;
        let (mut speed_mps, mut distance_m) = (0.0, 0.0);
        let mut watched = 0;
        for s in self.steps.iter().filter(|s| s.t_s >= reference_end_s) {
            let half = turned + 0.5 * s.dtheta_rad;
            turned += s.dtheta_rad;
            // Along x: the specific force less the reference's (gravity and the
            // accelerometers' biases), less gravity's turn into x with the body.
            let dv =
                s.dvel_mps.x - force_mps2.x * s.dt_s - self.g_mps2 * half.cross(&down).x * s.dt_s;
            distance_m += (speed_mps + 0.5 * dv) * s.dt_s;
            speed_mps += dv;
            watched += 1;
        }
        let moving = speed_mps.abs() >= MOVING_MPS
            && distance_m.abs() >= MOVED_M
            && speed_mps.signum() == distance_m.signum();
        moving.then(|| watched - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const G: f64 = 9.81;
    const DT_S: f64 = 0.01;

    /// Feeds `n` samples of a vehicle pitched 2° nose up, accelerating along x at
    /// `accel_mps2(t)` and pitching at `pitch_rate_rad_s(t)`, to a watch begun at 0;
    /// returns the judgements.
    fn feed(
        n: usize,
        accel_mps2: impl Fn(f64) -> f64,
        pitch_rate_rad_s: impl Fn(f64) -> f64,
    ) -> Vec<Motion> {
        let mut m = StandingMotion::new(G, DT_S);
        let mut pitch: f64 = 2f64.to_radians();
        (0..n)
            .map(|k| {
                let t = k as f64 * DT_S;
                let q = pitch_rate_rad_s(t);
                pitch += q * DT_S;
                // FRD at rest: f = −g·down; nose up, gravity pulls back along x.
                let f = [accel_mps2(t) + G * pitch.sin(), 0.0, -G * pitch.cos()];
                m.push(t, f.map(|x| x * DT_S), [0.0, q * DT_S, 0.0])
            })
            .collect()
    }

    #[test]
    fn a_vehicle_pulling_away_is_found_and_one_at_rest_is_not() {
        // Standing a minute, pitching by 3° over 2 s at 40 s (a load): never moving.
        let out = feed(
            6000,
            |_| 0.0,
            |t| {
                if (40.0..42.0).contains(&t) {
                    1.5f64.to_radians()
                } else {
                    0.0
                }
            },
        );
        assert!(out.iter().all(|m| !matches!(m, Motion::Moving { .. })));
        assert!(out[..200].iter().all(|m| *m == Motion::Reference));
        // Pulling away at 1 m/s² at 30 s: found within 1.6 s.
        let out = feed(4000, |t| if t >= 30.0 { 1.0 } else { 0.0 }, |_| 0.0);
        let k = out
            .iter()
            .position(|m| matches!(m, Motion::Moving { .. }))
            .unwrap();
        let t = k as f64 * DT_S;
        assert!((31.3..31.6).contains(&t), "{t}");
        let Motion::Moving { watched } = out[k] else {
            unreachable!()
        };
        assert!((499..=501).contains(&watched), "{watched}");
        let Motion::Watching { release_before_s } = out[k - 1] else {
            panic!("{:?}", out[k - 1])
        };
        // The watch is the last 5 s.
        assert!(
            (release_before_s - (t - WATCH_S)).abs() < 0.02,
            "{release_before_s}"
        );
        // Gently, 0.2 m/s²: found within 3.3 s.
        let out = feed(4000, |t| if t >= 30.0 { 0.2 } else { 0.0 }, |_| 0.0);
        let k = out
            .iter()
            .position(|m| matches!(m, Motion::Moving { .. }))
            .unwrap();
        assert!((k as f64 * DT_S) < 33.3, "{k}");
    }
}
