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
/// give. A vehicle pulling away at 1 m/s² is found 1.4–1.7 s after it starts, at
/// 0.2 m/s² within 3.5 s.
pub const MOVED_M: f64 = 1.0;
/// Samples summed into one block of the reference and the watch (0.1 s at 100 Hz): over
/// a block the body of a vehicle at rest does not turn, and a block's trapezoid is within
/// centimetres of the samples' over the watch.
const BLOCK_SAMPLES: usize = 10;
/// Shortest sample period taken, s (10 kHz, beyond any navigation IMU's rate): a log
/// whose tags say a shorter one (a damaged text log's, tags that stand) would ask for
/// reference and watch blocks without bound; from a period of zero, more than a usize
/// holds.
const MIN_PERIOD_S: f64 = 1e-4;
/// The watch is judged every this many blocks (0.2 s at 100 Hz): each judgement
/// integrates the reference and the watch whole.
const JUDGE_EVERY: usize = 2;

/// Samples of the IMU summed.
#[derive(Debug, Clone, Copy)]
struct Block {
    /// The first sample's time tag, s.
    first_t_s: f64,
    /// The samples' intervals, s.
    dt_s: f64,
    dvel_mps: Vector3<f64>,
    dtheta_rad: Vector3<f64>,
    samples: usize,
}

/// What the IMU says of a sample while the count stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Motion {
    /// Taken into the reference: nothing to hold.
    Reference,
    /// Watched: hold it (a stuck count would fail it); samples before `release_before_s`
    /// have left the watch.
    Watching {
        /// The watch's start, s.
        release_before_s: f64,
    },
    /// Moving: this sample and the `watched` before it in the watch fail.
    Moving {
        /// Samples of the watch before this one.
        watched: usize,
    },
}

/// The IMU's samples while the count stands, in blocks: a reference, then a watch.
#[derive(Debug)]
pub struct StandingMotion {
    g_mps2: f64,
    period_s: f64,
    /// Blocks of the reference, then of the watch.
    blocks: VecDeque<Block>,
    /// The block being summed.
    current: Option<Block>,
    /// The last sample's time tag, s.
    last_t_s: Option<f64>,
    /// Blocks since the last judgement.
    since_judged: usize,
    /// Blocks of the reference and of the watch.
    reference_blocks: usize,
    watch_blocks: usize,
}

impl StandingMotion {
    /// Where gravity is `g_mps2`, samples every `period_s`.
    pub fn new(g_mps2: f64, period_s: f64) -> Self {
        let period_s = period_s.abs().max(MIN_PERIOD_S);
        let blocks = |s: f64| ((s / (period_s * BLOCK_SAMPLES as f64)).round() as usize).max(1);
        Self {
            g_mps2,
            period_s,
            blocks: VecDeque::new(),
            current: None,
            last_t_s: None,
            since_judged: 0,
            reference_blocks: blocks(REFERENCE_S),
            watch_blocks: blocks(WATCH_S),
        }
    }

    /// The count moved (or failed): the next stand starts afresh.
    pub fn reset(&mut self) {
        self.blocks.clear();
        self.current = None;
        self.last_t_s = None;
        self.since_judged = 0;
    }

    /// Takes the next sample while the count stands (its increments within the IMU's
    /// range: [`crate::odometer_bridge`] replaces those beyond).
    pub fn push(&mut self, t_s: f64, dvel_mps: [f64; 3], dtheta_rad: [f64; 3]) -> Motion {
        // A tag step beyond two periods (a clock that jumps) counts as two.
        let dt_s = self.last_t_s.map_or(self.period_s, |last| {
            (t_s - last).clamp(0.0, 2.0 * self.period_s)
        });
        self.last_t_s = Some(t_s);
        let b = self.current.get_or_insert(Block {
            first_t_s: t_s,
            dt_s: 0.0,
            dvel_mps: Vector3::zeros(),
            dtheta_rad: Vector3::zeros(),
            samples: 0,
        });
        b.dt_s += dt_s;
        b.dvel_mps += Vector3::from(dvel_mps);
        b.dtheta_rad += Vector3::from(dtheta_rad);
        b.samples += 1;
        let watch_start_s = match self.blocks.get(self.reference_blocks) {
            Some(w) => Some(w.first_t_s),
            None if self.blocks.len() == self.reference_blocks => Some(b.first_t_s),
            None => None,
        };
        let full = b.samples >= BLOCK_SAMPLES;
        if full {
            self.blocks.extend(self.current.take());
            if self.blocks.len() > self.reference_blocks + self.watch_blocks {
                self.blocks.pop_front();
            }
        }
        let Some(watch_start_s) = watch_start_s else {
            return Motion::Reference;
        };
        if full && self.blocks.len() > self.reference_blocks {
            self.since_judged += 1;
            if self.since_judged >= JUDGE_EVERY {
                self.since_judged = 0;
                if let Some(watched) = self.moving() {
                    self.reset();
                    return Motion::Moving { watched };
                }
            }
        }
        // The watch slid on by a block: its first is now the reference's last.
        Motion::Watching {
            release_before_s: self
                .blocks
                .get(self.reference_blocks)
                .map_or(watch_start_s, |w| w.first_t_s),
        }
    }

    /// The samples of the watch before the last, if the vehicle moved over it (judged
    /// when a block is complete). Forces and gravity are taken in the body's axes at the
    /// reference's start (the gyros' turn since then, small over seconds), so a body
    /// that turns during the reference does not tilt it.
    fn moving(&self) -> Option<usize> {
        let n = self.reference_blocks.min(self.blocks.len());
        let (reference, watch) = (self.blocks.range(..n), self.blocks.range(n..));
        let (mut force, mut time_s) = (Vector3::zeros(), 0.0);
        let mut turned = Vector3::zeros();
        for b in reference {
            let half = turned + 0.5 * b.dtheta_rad;
            force += b.dvel_mps + half.cross(&b.dvel_mps);
            turned += b.dtheta_rad;
            time_s += b.dt_s;
        }
        if time_s <= 0.0 {
            return None;
        }
        let force_mps2 = force / time_s;
        let down = -force_mps2.try_normalize(f64::MIN_POSITIVE)?;
        let (mut speed_mps, mut distance_m) = (0.0, 0.0);
        let mut watched = 0;
        for b in watch {
            let half = turned + 0.5 * b.dtheta_rad;
            turned += b.dtheta_rad;
            // Along x: the specific force less the reference's (gravity and the
            // accelerometers' biases), less gravity's turn into x with the body.
            let turn_x = half.y * down.z - half.z * down.y;
            let dv = b.dvel_mps.x - (force_mps2.x + self.g_mps2 * turn_x) * b.dt_s;
            distance_m += (speed_mps + 0.5 * dv) * b.dt_s;
            speed_mps += dv;
            watched += b.samples;
        }
        let moving = speed_mps.abs() >= MOVING_MPS
            && distance_m.abs() >= MOVED_M
            && speed_mps.signum() == distance_m.signum();
        moving.then(|| watched.saturating_sub(1))
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

    /// Regression (fuzzing the text ingest): a period of zero (tags that stand) asked for
    /// more reference and watch blocks than a usize holds, and their sum overflowed (a
    /// panic in a debug build; in a release one the wrapped bound let the blocks go).
    /// The blocks stay within what a 10-kHz IMU's reference and watch take.
    #[test]
    fn a_period_of_zero_keeps_its_blocks_bounded() {
        for period_s in [0.0, 1e-300, f64::NAN] {
            let mut m = StandingMotion::new(G, period_s);
            for _ in 0..200_000 {
                m.push(0.0, [0.0, 0.0, -G * DT_S], [0.0; 3]);
            }
            let bound = ((REFERENCE_S + WATCH_S) / (MIN_PERIOD_S * BLOCK_SAMPLES as f64)) as usize;
            assert_eq!(m.reference_blocks + m.watch_blocks, bound, "{period_s}");
            assert!(m.blocks.len() <= bound, "{period_s}: {}", m.blocks.len());
        }
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
        // Pulling away at 1 m/s² at 30 s: found within 1.7 s (judged every 0.25 s).
        let out = feed(4000, |t| if t >= 30.0 { 1.0 } else { 0.0 }, |_| 0.0);
        let k = out
            .iter()
            .position(|m| matches!(m, Motion::Moving { .. }))
            .unwrap();
        let t = k as f64 * DT_S;
        assert!((31.4..31.7).contains(&t), "{t}");
        let Motion::Moving { watched } = out[k] else {
            unreachable!()
        };
        assert!((499..=501).contains(&watched), "{watched}");
        let Motion::Watching { release_before_s } = out[k - 1] else {
            panic!("{:?}", out[k - 1])
        };
        // The watch is the last 5 s, in blocks of 0.1 s.
        assert!(
            (release_before_s - (t - WATCH_S)).abs() < 0.11,
            "{release_before_s} {t}"
        );
        // Gently, 0.2 m/s²: found within 3.5 s.
        let out = feed(4000, |t| if t >= 30.0 { 0.2 } else { 0.0 }, |_| 0.0);
        let k = out
            .iter()
            .position(|m| matches!(m, Motion::Moving { .. }))
            .unwrap();
        assert!((k as f64 * DT_S) < 33.5, "{k}");
    }
}
