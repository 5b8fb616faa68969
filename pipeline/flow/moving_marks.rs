//! Control points passed, not stopped at. A point is surveyed where the vehicle stands,
//! and its time (a binary log's mark, a text log's `t_s`) is the stop's. A time while
//! the vehicle drives compares the point with a place the vehicle passed on the way:
//! Kingston's second point timed 6 s before its stop (4.4 m/s) ran "ok" with hold-out
//! errors of 7.0 and 9.9 m (2.2 and 3.0 m as surveyed), and nothing said.

use serde::{Deserialize, Serialize};
use unz_stages::criteria::ControlPointFix;
use unz_stages::derive::Derived;

use super::marks::{AT_REST_MPS, SPEED_HALF_WINDOW_S};

/// Least path between a point's time and the nearest stop for it to be said, m: a
/// vehicle creeping up to its point and stopping within a metre or two is at it (the
/// joint fit's residuals at Kingston's points are 0.4 m; its hold-out errors 2–3 m).
pub const MOVING_MARK_PATH_M: f64 = 2.0;

/// How far from a point's time a stop is looked for, s.
pub const STOP_SEARCH_S: f64 = 120.0;

/// A control point passed at speed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MovingMark {
    /// Control-point id.
    pub id: u32,
    /// Its time, s in the log's time base.
    pub t_s: f64,
    /// The odometer's mean speed over ±[`SPEED_HALF_WINDOW_S`] about it, m/s.
    pub speed_mps: f64,
    /// The nearest moment at rest within ±[`STOP_SEARCH_S`] (none when the vehicle
    /// stood nowhere there).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nearest_stop: Option<NearestStop>,
}

/// The moment at rest nearest a point's time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NearestStop {
    /// Its time, s in the log's time base.
    pub t_s: f64,
    /// The odometer's path from the point's time to it, m (positive: ahead).
    pub path_m: f64,
}

impl MovingMark {
    /// What the run's log and the campaign's note say of it.
    pub fn said(&self) -> String {
        let passed = format!(
            "control point {} at t_s = {:.2} was passed at {:.1} m/s (the odometer's mean \
             over ±{SPEED_HALF_WINDOW_S} s), not stood at",
            self.id, self.t_s, self.speed_mps
        );
        match self.nearest_stop {
            Some(stop) => {
                let dt = stop.t_s - self.t_s;
                format!(
                    "{passed}: the vehicle stood {:.1} s {}, {:.1} m along the odometer's \
                     path (t_s = {:.2}); a point is surveyed where the vehicle stands: \
                     check its time or mark",
                    dt.abs(),
                    if dt > 0.0 { "later" } else { "earlier" },
                    stop.path_m.abs(),
                    stop.t_s
                )
            }
            None => format!(
                "{passed}, and the vehicle stood nowhere within {STOP_SEARCH_S} s of it; a \
                 point is surveyed where the vehicle stands: check its time or mark"
            ),
        }
    }
}

/// The points of `fixes` passed at speed in `d` (more than [`AT_REST_MPS`] about their
/// time, and more than [`MOVING_MARK_PATH_M`] of path from the nearest stop), but those
/// `said_already` (a repeated id whose marks were none at rest). A point visited more
/// than once is judged at each visit.
pub fn moving_marks(
    fixes: &[ControlPointFix],
    d: &Derived,
    said_already: impl Fn(u32) -> bool,
) -> Vec<MovingMark> {
    let n = d.t_s.len().min(d.odo_dist_m.len()).min(d.dt_s.len());
    if n == 0 || d.nominal_dt_s.is_nan() || d.nominal_dt_s <= 0.0 {
        return Vec::new();
    }
    let samples = |s: f64| ((s / d.nominal_dt_s).round() as usize).max(1);
    let (w, search) = (samples(SPEED_HALF_WINDOW_S), samples(STOP_SEARCH_S));
    fixes
        .iter()
        .filter(|f| !said_already(f.id))
        .filter_map(|f| {
            let k = f.sample.min(n - 1);
            let (lo, hi) = (k.saturating_sub(search + w), (k + search + w + 1).min(n));
            // Path and time from `lo`'s interval's start to each sample's end.
            let mut path = Vec::with_capacity(hi - lo + 1);
            let mut time = Vec::with_capacity(hi - lo + 1);
            let (mut p, mut t) = (0.0, 0.0);
            path.push(p);
            time.push(t);
            for j in lo..hi {
                p += d.odo_dist_m[j];
                t += d.dt_s[j];
                path.push(p);
                time.push(t);
            }
            // The mean speed over ±w samples about j (clipped to the span).
            let speed = |j: usize| {
                let (a, b) = (j.saturating_sub(w).max(lo), (j + w).min(hi - 1));
                let dt = time[b + 1 - lo] - time[a - lo];
                (path[b + 1 - lo] - path[a - lo]).abs() / dt
            };
            let at_k = speed(k);
            // At rest, or no speed (NaN).
            if at_k.is_nan() || at_k <= AT_REST_MPS {
                return None;
            }
            // The nearest sample at rest, the later on a tie.
            let stop = (1..=search).find_map(|off| {
                [k + off, k.wrapping_sub(off)]
                    .into_iter()
                    .filter(|&j| (lo..hi).contains(&j))
                    .find(|&j| speed(j) <= AT_REST_MPS)
            });
            let nearest_stop = stop.map(|j| NearestStop {
                t_s: f.t_s + d.t_s.get(j) - d.t_s.get(k),
                path_m: path[j + 1 - lo] - path[k + 1 - lo],
            });
            let far = nearest_stop.is_none_or(|s| s.path_m.abs() > MOVING_MARK_PATH_M);
            far.then_some(MovingMark {
                id: f.id,
                t_s: f.t_s,
                speed_mps: at_k,
                nearest_stop,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;

    /// 10 Hz: standing 20 s, driving at 5 m/s for 40 s, braking to a stop over 5 s (at
    /// 1 m/s²), standing 30 s.
    fn drive() -> Derived {
        let dt = 0.1;
        let speed = |t: f64| match t {
            t if t < 20.0 => 0.0,
            t if t < 60.0 => 5.0,
            t if t < 65.0 => 5.0 - (t - 60.0),
            _ => 0.0,
        };
        let n = 950;
        Derived {
            nominal_dt_s: dt,
            t_s: (0..n).map(|k| k as f64 * dt).collect::<Vec<_>>().into(),
            dt_s: Arc::new(vec![dt; n]),
            odo_dist_m: (0..n).map(|k| speed((k as f64 - 0.5) * dt) * dt).collect(),
            ..Derived::default()
        }
    }

    fn fix(id: u32, sample: usize) -> ControlPointFix {
        ControlPointFix {
            id,
            sample,
            t_s: 1000.0 + sample as f64 * 0.1,
            lat_rad: 0.0,
            lon_rad: 0.0,
            h_m: 0.0,
            mark_lever_arm_m: [0.0; 3],
        }
    }

    #[test]
    fn a_point_timed_while_driving_is_said_with_the_nearest_stop() {
        let d = drive();
        // At 50 s, at 5 m/s: the vehicle stops at 65 s, 62.5 m on.
        let said = moving_marks(&[fix(7, 500)], &d, |_| false);
        assert_eq!(said.len(), 1, "{said:?}");
        let m = &said[0];
        assert_eq!((m.id, m.t_s), (7, 1050.0));
        assert!((m.speed_mps - 5.0).abs() < 1e-9, "{m:?}");
        let stop = m.nearest_stop.unwrap();
        // At rest once the ±1 s window's mean is 0.1 m/s or less: at 65.5 s, the window
        // holds the last half second's 0.125 m over 2.1 s.
        assert!((stop.t_s - 1065.5).abs() < 1e-6, "{stop:?}");
        assert!((stop.path_m - 62.5).abs() < 0.1, "{stop:?}");
        assert!(
            m.said()
                .contains("the vehicle stood 15.5 s later, 62.5 m along")
        );
        // Said elsewhere already: not again.
        assert!(moving_marks(&[fix(7, 500)], &d, |id| id == 7).is_empty());
    }

    /// A point timed at the stop, or while the vehicle crept its last metre to it, is
    /// at it; one at the start's standing too.
    #[test]
    fn a_point_timed_at_its_stop_or_creeping_up_to_it_is_not_said() {
        let d = drive();
        let at = [fix(1, 800), fix(2, 645), fix(3, 100)];
        assert!(moving_marks(&at, &d, |_| false).is_empty());
    }

    /// Driving over the whole search: no stop.
    #[test]
    fn no_stop_within_the_search_is_said() {
        let mut d = drive();
        d.odo_dist_m = vec![0.5; 950];
        let said = moving_marks(&[fix(3, 500)], &d, |_| false);
        assert_eq!(said[0].nearest_stop, None);
        assert!(said[0].said().contains("stood nowhere within 120 s"));
    }
}
