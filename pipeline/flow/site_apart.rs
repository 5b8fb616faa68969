//! Control points all off by one shift: the site (the run's start) is off, or the points
//! are surveyed in another datum than it.
//!
//! No setting DISUPT moves shifts a route: the azimuth turns it about the start (a point
//! moves across its bearing, by its distance from the start), the odometer's scale
//! stretches it (along its bearing), the drifts bend it more the longer it runs. So when
//! the errors of the navigation with the initial settings, at points far apart, are one
//! vector give or take a fraction of its size, that vector is where the route starts
//! against the points. Kingston with its site 1.1 km off had its joint fit refused and
//! OEPI's route 1134 m off, under an "ok", blamed on the control points or the odometer.

use serde::{Deserialize, Serialize};
use unz_stages::criteria::{ControlPointFix, Kryt2};
use unz_stages::earth::Geodetic;

/// Least size of the shift for it to be said, m: the joint fit's hold-out errors on
/// Kingston are 2–3 m, and its residuals with the site 20 m off were 12.5σ.
pub const SITE_APART_MIN_M: f64 = 20.0;

/// The shift must be this many times the points' spread about it: on Kingston as
/// surveyed the errors are 7 m apart from their mean of 7 m (its initial azimuth's and
/// the drifts' share), with its site 50 m off the same 10 m about a mean of 50 m.
pub const SITE_APART_OVER_SPREAD: f64 = 4.0;

/// The points must lie at least this part of the farthest one's distance from the start
/// apart: a turn of the route about the start moves points near each other alike.
pub const POINTS_APART_PER_REACH: f64 = 0.5;

/// One shift of every control point's error before DISUPT.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SiteApart {
    /// The mean error (navigated minus surveyed), north, m.
    pub north_m: f64,
    /// The same, east, m.
    pub east_m: f64,
    /// The largest distance of a point's error from the mean, m.
    pub spread_m: f64,
    /// The largest distance between two of the points, m.
    pub points_apart_m: f64,
}

impl SiteApart {
    /// The shift of the errors `before` (with the initial settings) at the `fixes` they
    /// are of, on a route that starts at `site`: when there are two points or more, far
    /// enough apart ([`POINTS_APART_PER_REACH`]), and their errors are one shift
    /// ([`SITE_APART_MIN_M`], [`SITE_APART_OVER_SPREAD`]).
    pub fn of(before: &[Kryt2], fixes: &[ControlPointFix], site: Geodetic) -> Option<Self> {
        if before.len() < 2 || before.len() != fixes.len() {
            return None;
        }
        let n = before.len() as f64;
        let (north_m, east_m) = (
            before.iter().map(|k| k.dx_m).sum::<f64>() / n,
            before.iter().map(|k| k.dy_m).sum::<f64>() / n,
        );
        let spread_m = (before.iter())
            .map(|k| (k.dx_m - north_m).hypot(k.dy_m - east_m))
            .fold(0.0, f64::max);
        let at: Vec<(f64, f64)> = (fixes.iter())
            .map(|f| site.offset_m(f.lat_rad, f.lon_rad))
            .collect();
        let reach_m = at.iter().map(|(n, e)| n.hypot(*e)).fold(0.0, f64::max);
        let points_apart_m = (at.iter().enumerate())
            .flat_map(|(i, a)| {
                at[i + 1..]
                    .iter()
                    .map(move |b| (a.0 - b.0).hypot(a.1 - b.1))
            })
            .fold(0.0, f64::max);
        let size_m = north_m.hypot(east_m);
        let shifted = size_m >= SITE_APART_MIN_M
            && size_m >= SITE_APART_OVER_SPREAD * spread_m
            && points_apart_m >= POINTS_APART_PER_REACH * reach_m;
        shifted.then_some(Self {
            north_m,
            east_m,
            spread_m,
            points_apart_m,
        })
    }

    /// What it is, for the run's log and its row of the campaign summary.
    pub fn said(&self) -> String {
        format!(
            "every control point's error before DISUPT is about {:.0} m north and {:.0} m \
             east (navigated minus surveyed; within {:.0} m of each other, on points {:.0} m \
             apart): a shift of the whole route, which no setting DISUPT moves makes; the \
             site (the run's start) is that far from where the route began, or the points \
             are surveyed in another datum than the site",
            self.north_m, self.east_m, self.spread_m, self.points_apart_m
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SITE: Geodetic = Geodetic {
        lat_rad: 0.772,
        lon_rad: -1.3346,
        h_m: 40.0,
    };

    /// A point `(north_m, east_m)` from the site and its error `(dx_m, dy_m)`.
    type Point = ((f64, f64), (f64, f64));

    /// The points' errors and fixes.
    fn points(at: &[Point]) -> (Vec<Kryt2>, Vec<ControlPointFix>) {
        let (rn, re) = unz_stages::earth::radii_m(SITE.lat_rad);
        at.iter()
            .enumerate()
            .map(|(i, &((n, e), (dx, dy)))| {
                let id = i as u32 + 1;
                let k = Kryt2 {
                    id,
                    t_s: 0.0,
                    dx_m: dx,
                    dy_m: dy,
                    kryt2_m: dx.hypot(dy),
                };
                let f = ControlPointFix {
                    id,
                    sample: i,
                    t_s: 0.0,
                    lat_rad: SITE.lat_rad + n / (rn + SITE.h_m),
                    lon_rad: SITE.lon_rad + e / ((re + SITE.h_m) * SITE.lat_rad.cos()),
                    h_m: SITE.h_m,
                    mark_lever_arm_m: [0.0; 3],
                };
                (k, f)
            })
            .unzip()
    }

    #[test]
    fn one_shift_at_points_far_apart_is_the_sites() {
        // Kingston with its site at its second point's coordinates.
        let (k, f) = points(&[
            ((470.0, 50.0), (-246.4, -1117.0)),
            ((-236.0, -1117.0), (-228.0, -1108.9)),
        ]);
        let apart = SiteApart::of(&k, &f, SITE).unwrap();
        assert!((apart.north_m + 237.2).abs() < 0.1 && (apart.east_m + 1113.0).abs() < 0.1);
        assert!((apart.points_apart_m - 1363.9).abs() < 1.0, "{apart:?}");
        assert!(
            apart.said().starts_with(
                "every control point's error before DISUPT is about -237 m north and -1113 m \
                 east (navigated minus surveyed; within 10 m of each other, on points 1364 m \
                 apart)"
            ),
            "{}",
            apart.said()
        );
    }

    #[test]
    fn a_turn_a_spread_a_small_shift_or_points_together_are_not() {
        let far = ((-1200.0, -1100.0), (-500.0, 300.0));
        // A turn of the route about the start: errors across each bearing, by distance.
        let (k, f) = points(&[
            ((470.0, 50.0), (-5.0, 47.0)),
            ((-236.0, -1117.0), (112.0, -24.0)),
        ]);
        assert_eq!(SiteApart::of(&k, &f, SITE), None);
        // Errors as far from each other as from zero (Kingston as surveyed: 7 m about 7 m).
        let (k, f) = points(&[
            ((470.0, 50.0), (-9.7, 3.2)),
            ((-236.0, -1117.0), (8.7, 11.4)),
        ]);
        assert_eq!(SiteApart::of(&k, &f, SITE), None);
        // One shift, below 20 m.
        let (k, f) = points(&[
            ((470.0, 50.0), (15.0, 3.0)),
            ((-236.0, -1117.0), (16.0, 2.0)),
        ]);
        assert_eq!(SiteApart::of(&k, &f, SITE), None);
        // Points 28 m apart, 1.6 km out: a turn moves them alike.
        let (k, f) = points(&[far, ((-1220.0, -1120.0), (-505.0, 302.0))]);
        assert_eq!(SiteApart::of(&k, &f, SITE), None);
        // One point: nothing to compare.
        let (k, f) = points(&[far]);
        assert_eq!(SiteApart::of(&k, &f, SITE), None);
    }
}
