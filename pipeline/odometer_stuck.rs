//! An odometer count that stands while the vehicle moves: a broken wheel sensor or cable
//! gives no pulses, and the log does not flag it. After a step at speed v, a
//! vehicle braking at its hardest ([`MAX_DECEL_MPS2`]) still covers v·T − a·T²/2 in T
//! (v²/2a once stopped). Once that is more than a pulse and a margin, and the count has
//! not moved for [`MIN_STUCK_S`], the count is stuck from its last step on, until it moves
//! again.
//!
//! That is judged on the counts alone, so no assumption about the IMU enters. A count
//! that stops below about 2.3 m/s (12.5-mm pulses: a stop from there fits within 6 cm),
//! or while the vehicle stands, is found by the IMU instead, once the vehicle moves while
//! it stands ([`crate::standing_motion`]), from [`SETTLE_S`] after the count's last step
//! on.

use std::collections::VecDeque;

use crate::standing_motion::{Motion, StandingMotion};

/// The hardest a land vehicle slows, m/s² (1.5 g: beyond any braking on tyres or
/// tracks; only a collision stops it faster).
pub const MAX_DECEL_MPS2: f64 = 15.0;
/// A count not moved for this long at least is stuck, s: a latch that repeats a count
/// for a sample or two and then catches up loses nothing.
pub const MIN_STUCK_S: f64 = 0.1;
/// The speed at a step is taken over at least this long before it, s.
const SPEED_WINDOW_S: f64 = 0.1;
/// The longest time tag step counted while the count stands, in sample periods: a clock
/// that jumps is not time passing (and a gap of lost samples is counted short).
const MAX_TAG_STEP_PERIODS: f64 = 2.0;
/// What the least distance covered must exceed beyond a pulse, m.
const MARGIN_M: f64 = 0.05;
/// After a plausible stop, the IMU watches the standing count from this long after its
/// last step, s: the vehicle has come to rest within a pulse by then.
pub const SETTLE_S: f64 = 0.5;

/// What a working sample's count says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Count {
    /// Nothing impossible: moving, or standing as the vehicle may.
    Plausible,
    /// Standing since a step at a speed a stop would soon show: not judged yet.
    Suspect,
    /// Standing as a vehicle at rest may, watched by the IMU: hold it (it fails if the
    /// vehicle is found moving); samples before `release_before_s` are no longer
    /// watched.
    Standing {
        /// The IMU's watch's start, s.
        release_before_s: f64,
    },
    /// Found stuck at this sample: it and the `standing` samples before it (since the
    /// count's last step, or the IMU's watch of it) are a failure.
    Found {
        /// Samples of the count's stand before this one that fail with it.
        standing: usize,
    },
    /// Still stuck at the value it was found stuck at.
    Stuck,
}

/// Where the count stands since its last step.
#[derive(Debug, Clone, Copy)]
struct Standing {
    /// The tag of the last sample counted, s.
    last_t_s: f64,
    /// Time since the step, tag steps clamped to [`MAX_TAG_STEP_PERIODS`], s.
    elapsed_s: f64,
    /// The least speed the vehicle can have had at the step, m/s.
    v_min_mps: f64,
    /// Samples since the step.
    samples: usize,
}

/// The odometer's count, judged sample by sample against a land vehicle's braking.
#[derive(Debug)]
pub struct StuckCount {
    /// A pulse, m: the count's resolution.
    pulse_m: f64,
    /// The longest tag step counted, s.
    max_tag_step_s: f64,
    /// The working samples' time tags and distances (s, m) since about [`SPEED_WINDOW_S`]
    /// before the last step.
    recent: VecDeque<(f64, f64)>,
    standing: Option<Standing>,
    /// The distance the count is stuck at, m.
    stuck_m: Option<f64>,
    /// The IMU while the count stands.
    motion: StandingMotion,
}

impl StuckCount {
    /// A count of `pulse_m` metres per pulse, sampled every `period_s`, where gravity is
    /// `g_mps2`.
    pub fn new(pulse_m: f64, period_s: f64, g_mps2: f64) -> Self {
        Self {
            pulse_m: pulse_m.abs(),
            max_tag_step_s: MAX_TAG_STEP_PERIODS * period_s.abs(),
            recent: VecDeque::new(),
            standing: None,
            stuck_m: None,
            motion: StandingMotion::new(g_mps2, period_s),
        }
    }

    /// A sample the log flags failed: the speed before it is not the speed after.
    pub fn flagged(&mut self) {
        self.recent.clear();
        self.standing = None;
        self.motion.reset();
    }

    /// Judges the working sample at `t_s` whose distance is `distance_m`, with its
    /// velocity and angle increments (body FRD).
    pub fn judge(
        &mut self,
        t_s: f64,
        distance_m: f64,
        dvel_mps: [f64; 3],
        dtheta_rad: [f64; 3],
    ) -> Count {
        if let Some(m) = self.stuck_m {
            if distance_m == m {
                return Count::Stuck;
            }
            // Moving again: its speed is taken afresh.
            self.stuck_m = None;
            self.recent.clear();
        }
        let Some(&(step_t_s, step_m)) = self.recent.back() else {
            self.recent.push_back((t_s, distance_m));
            return Count::Plausible;
        };
        if distance_m != step_m {
            self.standing = None;
            self.motion.reset();
            self.recent.push_back((t_s, distance_m));
            while self.recent.len() > 2 && self.recent[1].0 <= t_s - SPEED_WINDOW_S {
                self.recent.pop_front();
            }
            return Count::Plausible;
        }
        let v_min_mps = match self.standing {
            Some(s) => s.v_min_mps,
            None => self.least_speed_at_step(),
        };
        let s = self.standing.get_or_insert(Standing {
            last_t_s: step_t_s,
            elapsed_s: 0.0,
            v_min_mps,
            samples: 0,
        });
        s.elapsed_s += (t_s - s.last_t_s).clamp(0.0, self.max_tag_step_s);
        s.last_t_s = t_s;
        s.samples += 1;
        let (v, t, a) = (s.v_min_mps, s.elapsed_s, MAX_DECEL_MPS2);
        let enough_m = self.pulse_m + MARGIN_M;
        if v * v / (2.0 * a) <= enough_m {
            if t < SETTLE_S {
                return Count::Plausible;
            }
            return match self.motion.push(t_s, dvel_mps, dtheta_rad) {
                Motion::Reference => Count::Plausible,
                Motion::Watching { release_before_s } => Count::Standing { release_before_s },
                Motion::Moving { watched } => {
                    self.standing = None;
                    self.stuck_m = Some(distance_m);
                    Count::Found { standing: watched }
                }
            };
        }
        let least_m = if t < v / a {
            v * t - 0.5 * a * t * t
        } else {
            v * v / (2.0 * a)
        };
        if least_m <= enough_m || t < MIN_STUCK_S {
            return Count::Suspect;
        }
        let standing = s.samples - 1;
        self.standing = None;
        self.stuck_m = Some(distance_m);
        Count::Found { standing }
    }

    /// The least speed the vehicle can have had at the count's last step, m/s: the
    /// distance over the window before it, less a pulse of quantisation at its ends,
    /// less what the hardest braking takes off over half the window. Zero without a
    /// window.
    fn least_speed_at_step(&self) -> f64 {
        let (Some(&(t0_s, d0_m)), Some(&(t1_s, d1_m))) = (self.recent.front(), self.recent.back())
        else {
            return 0.0;
        };
        let dt_s = t1_s - t0_s;
        // Less than about a window (a log's first samples, the first after a flag).
        if dt_s < 0.5 * SPEED_WINDOW_S {
            return 0.0;
        }
        let v = ((d1_m - d0_m).abs() - self.pulse_m) / dt_s - 0.5 * MAX_DECEL_MPS2 * dt_s;
        v.max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PULSE_M: f64 = 0.0125;
    const DT_S: f64 = 0.01;
    const G: f64 = 9.81;
    /// A level vehicle's increments at rest or at a constant speed.
    const DVEL: [f64; 3] = [0.0, 0.0, -G * DT_S];

    /// Judges a count of 12.5-mm pulses sampled at 100 Hz along `distance_m(t)`, stuck
    /// from `stuck_s` on if given; returns every judgement.
    fn judge(n: usize, distance_m: impl Fn(f64) -> f64, stuck_s: Option<f64>) -> Vec<Count> {
        let mut c = StuckCount::new(PULSE_M, DT_S, G);
        let pulses = |t: f64| (distance_m(t) / PULSE_M).floor() * PULSE_M;
        (0..n)
            .map(|k| {
                let t = k as f64 * DT_S;
                let t_read = stuck_s.map_or(t, |s| t.min(s));
                c.judge(t, pulses(t_read), DVEL, [0.0; 3])
            })
            .collect()
    }

    /// The hardest braking the detector allows, and beyond a stop the count standing for
    /// minutes: nothing found.
    #[test]
    fn a_stop_at_the_hardest_braking_is_not_a_stuck_count() {
        for decel in [3.0, 8.0, MAX_DECEL_MPS2] {
            // 20 m/s for 2 s, then braking to a stop, then standing.
            let stop_s = 2.0 + 20.0 / decel;
            let d = |t: f64| {
                let tb = (t.min(stop_s) - 2.0).max(0.0);
                20.0 * t.min(2.0) + 20.0 * tb - 0.5 * decel * tb * tb
            };
            let out = judge(30_000, d, None);
            assert!(
                out.iter().all(|c| matches!(
                    c,
                    Count::Plausible | Count::Suspect | Count::Standing { .. }
                )),
                "{decel} m/s²"
            );
        }
        // Slow movement (a step every few samples) is plausible throughout.
        let out = judge(3000, |t| 0.3 * t, None);
        assert!(out.iter().all(|c| *c == Count::Plausible));
    }

    /// A count stopping at 10 m/s is found after [`MIN_STUCK_S`], with the samples
    /// since its last step; it stays stuck until it moves.
    #[test]
    fn a_count_stopping_at_speed_is_found_and_stays_stuck() {
        let out = judge(1000, |t| 10.0 * t, Some(3.0));
        let found: Vec<usize> = (0..out.len())
            .filter(|&k| matches!(out[k], Count::Found { .. }))
            .collect();
        assert_eq!(found.len(), 1);
        let k = found[0];
        let Count::Found { standing } = out[k] else {
            unreachable!()
        };
        // The last step is at or just before 3.00 s; found 0.1 s on.
        assert!((k as f64 * DT_S - 3.1).abs() < 0.015, "{k}");
        assert!((300..=301).contains(&(k - standing)), "{k} {standing}");
        assert!(out[k + 1..].iter().all(|c| *c == Count::Stuck));
        assert!(out[k - standing..k].iter().all(|c| *c == Count::Suspect));

        // A latch that repeats a count for 5 samples and catches up: nothing found.
        let mut c = StuckCount::new(PULSE_M, DT_S, G);
        let mut held = None;
        for k in 0..1000 {
            let d = (10.0 * k as f64 * DT_S / PULSE_M).floor() * PULSE_M;
            let read = if (500..505).contains(&k) {
                *held.get_or_insert(d)
            } else {
                d
            };
            assert!(
                matches!(
                    c.judge(k as f64 * DT_S, read, DVEL, [0.0; 3]),
                    Count::Plausible | Count::Suspect
                ),
                "{k}"
            );
        }

        // Moving again ends it; a later stop at speed is found again.
        let mut c = StuckCount::new(PULSE_M, DT_S, G);
        let mut counts = Vec::new();
        for k in 0..3000 {
            let t = k as f64 * DT_S;
            let d = if (5.0..10.0).contains(&t) {
                50.0
            } else if t >= 10.0 {
                50.0 + 10.0 * (t - 10.0)
            } else {
                10.0 * t
            };
            counts.push(c.judge(t, (d / PULSE_M).floor() * PULSE_M, DVEL, [0.0; 3]));
        }
        let found = counts
            .iter()
            .filter(|c| matches!(c, Count::Found { .. }))
            .count();
        assert_eq!(found, 1);
        assert!(counts[1001..].iter().all(|c| *c == Count::Plausible));
    }

    /// A count that stops while the vehicle stands and stays stopped as it drives off
    /// at 1 m/s² is found by the IMU 1.4–1.7 s on, with the samples of its watch; one
    /// that counts as it drives off is not.
    #[test]
    fn a_count_stopped_at_rest_is_found_when_the_vehicle_drives_off() {
        for counting in [false, true] {
            let mut c = StuckCount::new(PULSE_M, DT_S, G);
            let mut found = None;
            for k in 0..4000 {
                let t = k as f64 * DT_S;
                let driving_s = (t - 20.0).max(0.0);
                let d = 0.5 * driving_s * driving_s;
                let read = if counting {
                    (d / PULSE_M).floor() * PULSE_M
                } else {
                    0.0
                };
                let accel = if t >= 20.0 { 1.0 } else { 0.0 };
                let dvel = [accel * DT_S, 0.0, -G * DT_S];
                match c.judge(t, read, dvel, [0.0; 3]) {
                    Count::Found { standing } => {
                        assert!(found.is_none());
                        found = Some((t, standing));
                    }
                    Count::Stuck => assert!(found.is_some()),
                    Count::Suspect => panic!("{t}"),
                    _ => assert!(found.is_none(), "{t}"),
                }
            }
            if counting {
                assert_eq!(found, None);
            } else {
                let (t, standing) = found.unwrap();
                assert!((21.4..21.7).contains(&t), "{t}");
                // The watch: the 5 s before.
                assert!((499..=501).contains(&standing), "{standing}");
            }
        }
    }

    /// Time tags that jump while the count stands do not make a stop impossible, and a
    /// reading after a flagged sample has no speed before it.
    #[test]
    fn jumping_tags_and_flags_do_not_find_a_stuck_count() {
        let mut c = StuckCount::new(PULSE_M, DT_S, G);
        for k in 0..100 {
            c.judge(k as f64 * DT_S, 0.1 * k as f64, DVEL, [0.0; 3]);
        }
        // 3 standing samples, tags 10 s apart: counted as two periods each.
        for j in 1..=3 {
            assert_eq!(
                c.judge(0.99 + 10.0 * j as f64, 0.1 * 99.0, DVEL, [0.0; 3]),
                Count::Suspect
            );
        }
        let mut c = StuckCount::new(PULSE_M, DT_S, G);
        for k in 0..100 {
            c.judge(k as f64 * DT_S, 0.1 * k as f64, DVEL, [0.0; 3]);
        }
        c.flagged();
        for k in 100..200 {
            assert!(matches!(
                c.judge(k as f64 * DT_S, 50.0, DVEL, [0.0; 3]),
                Count::Plausible | Count::Standing { .. }
            ));
        }
    }
}
