//! The odometer's pitch boresight, fitted to the control points' surveyed heights.
//!
//! Dead reckoning carries the odometer's distance along the body's x axis. When the
//! vehicle's path does not run along the IMU's x but climbs above it by an angle β (an
//! IMU pitched on its mount, a body that sits nose-down at speed), every metre of
//! distance moves the height by tan β that the route leaves out, and the error grows with
//! distance: on the Kingston log (real), the path runs 0.95° above the IMU's x while
//! driving (the reference INS's pitch against its velocity's), and the corrected route
//! ends 38 m below the last control point after 2.4 km.
//!
//! The horizontal criteria cannot see β: it moves the horizontal route by 1 − cos β (1.5e-4
//! at 1°) and by β times the body's pitch, which the odometer scale takes, and the pitch
//! the gyros carry is the IMU's, so Kryt1 is blind to it. The control points' heights see
//! it whole: a route's height error at a point `distance_m` along it changes by
//! `tan β · distance_m` (to the cosine of the IMU's pitch and roll), so β is the linear
//! least-squares fit of the height errors on distance through the start (whose height is
//! the manifest's). Whatever else grows in proportion to distance (a levelling pitch error
//! the pitch and roll left) is taken with it. The corrected navigation takes β in its
//! height alone ([`crate::strapdown::NavSettings::odo_pitch_rad`]): its horizontal route
//! stays the one the horizontal fit made.
//!
//! What guards it:
//! - a point at least [`MIN_DISTANCE_M`] along the route;
//! - with two or more such points, each one's height predicted by the others' fit must be
//!   nearer than without any: the points must show one angle (a datum offset does not
//!   grow with distance, and fails it);
//! - |β| at most [`MAX_ODO_PITCH_DEG`] from a single such point (a height in another datum
//!   than the start's shows as an angle: the geoid lies 20–50 m from the ellipsoid), or
//!   [`MAX_AGREED_ODO_PITCH_DEG`] when two or more agree (an IMU pitched on its mount).
//!
//! A vehicle's angle known from other runs (`[vehicle] odo_pitch_deg`, which a campaign's
//! runs pool) is the route's from the start: the points' errors are then of the route
//! with it, the fit finds what they show beyond it, and the guards judge that change (the
//! points must show it better than the configured angle alone; a single point moves it by
//! at most [`MAX_ODO_PITCH_DEG`]). A refused fit leaves the configured angle.

use serde::{Deserialize, Serialize};

use crate::criteria::{ControlPointFix, FixPose};

/// The nearest a control point must lie along the route (m) for its height to speak of the
/// angle: at 200 m, a 1-m height error is 0.3°.
pub const MIN_DISTANCE_M: f64 = 200.0;

/// The largest pitch boresight taken from a single point, deg: a body's attitude at speed
/// is a degree or two (Kingston: 0.95°), and a point in another datum than the start's
/// shows as an angle too (30 m at 300 m: 5.7°).
pub const MAX_ODO_PITCH_DEG: f64 = 5.0;

/// The largest pitch boresight taken when two or more points agree on it (each predicted
/// by the others better than without any), deg: an IMU pitched on its mount, up to the
/// axes check's tilt limit ([`crate::imu_axes::MAX_TILT_DEG`]).
pub const MAX_AGREED_ODO_PITCH_DEG: f64 = crate::imu_axes::MAX_TILT_DEG;

/// A route's height error at one control point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightError {
    /// Control-point id.
    pub id: u32,
    /// Time of the stop, s in the log's time base.
    pub t_s: f64,
    /// Distance travelled to it along the route, m.
    pub distance_m: f64,
    /// Navigated height of the vehicle's mark minus the surveyed height, m.
    pub dh_m: f64,
    /// How far the height there moves per unit of tan β, m: the distance, to the cosine of
    /// the IMU's pitch and roll along the way, until a pass with the angle measures it
    /// ([`with_slopes`]).
    pub slope_m: f64,
}

impl HeightError {
    /// Whether this is the error at the stop of control point `id` at `t_s` (a point
    /// visited twice has a stop per visit).
    pub fn is_at(&self, id: u32, t_s: f64) -> bool {
        self.id == id && self.t_s == t_s
    }

    /// The height error at `fix` of the navigated `pose` there.
    pub fn at(fix: &ControlPointFix, pose: &FixPose) -> Self {
        Self {
            id: fix.id,
            t_s: fix.t_s,
            distance_m: pose.distance_m,
            dh_m: fix.height_error_m(pose),
            slope_m: pose.distance_m,
        }
    }
}

/// `errors` with each point's slope measured: `probe` holds the height errors of the same
/// route with tan β larger by `tan_step` (≠ 0), and the height moves exactly in
/// proportion to tan β (the angle moves no attitude; the height's effect on the Earth's
/// radii is a millionth). An IMU pitched 20° on its mount climbs 6 % less per metre than
/// its distance says.
pub fn with_slopes(
    errors: &[HeightError],
    probe: &[HeightError],
    tan_step: f64,
) -> Vec<HeightError> {
    errors
        .iter()
        .map(|e| {
            let slope_m = probe
                .iter()
                .find(|p| p.is_at(e.id, e.t_s))
                .map_or(e.slope_m, |p| (p.dh_m - e.dh_m) / tan_step);
            HeightError { slope_m, ..*e }
        })
        .collect()
}

/// Height errors at every control point whose sample `pose` gives.
pub fn height_errors_at(
    fixes: &[ControlPointFix],
    pose: impl Fn(usize) -> Option<FixPose>,
) -> Vec<HeightError> {
    fixes
        .iter()
        .filter_map(|f| Some(HeightError::at(f, &pose(f.sample)?)))
        .collect()
}

/// One control point of the fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OdoPitchPoint {
    /// Control-point id.
    pub id: u32,
    /// Time of the stop, s in the log's time base.
    pub t_s: f64,
    /// Distance travelled to it, m.
    pub distance_m: f64,
    /// How far its height moves per unit of tan β, m: the distance, to the cosine of the
    /// IMU's pitch and roll along the way when a probe pass measured it.
    pub slope_m: f64,
    /// Height error of the route without the angle fitted (with the configured one), m
    /// (navigated minus surveyed).
    pub dh_before_m: f64,
    /// Height error of the corrected navigation, m: with the angle when it was taken (as
    /// its pass measured it), else as before.
    pub dh_m: f64,
    /// Height error with the angle fitted to the other points alone, m (the point held
    /// out): with two or more points at [`MIN_DISTANCE_M`] or more.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub holdout_dh_m: Option<f64>,
}

/// The odometer's pitch boresight the control points' heights show, and whether the
/// corrected navigation took it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OdoPitchFit {
    /// The angle, deg: positive, the path climbs above the body's x.
    pub odo_pitch_deg: f64,
    /// The angle configured for the vehicle (`[vehicle] odo_pitch_deg`), deg: the route's
    /// before the fit, and the corrected navigation's when the fit is refused.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub configured_deg: f64,
    /// Whether the corrected navigation was written with it.
    pub applied: bool,
    /// Why it was not, when not.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refused: Option<String>,
    /// What refused it, when refused.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refused_for: Option<OdoPitchRefusal>,
    /// The points it was fitted to, in the order of the route.
    pub points: Vec<OdoPitchPoint>,
}

/// What refused a pitch boresight's fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OdoPitchRefusal {
    /// No control point lies [`MIN_DISTANCE_M`] or more along the route: nothing to fit.
    NoFarPoint,
    /// A point held out is no nearer with the others' angle than with the configured one
    /// (none, or the vehicle's): the points do not agree on a change.
    NotOneAngle,
    /// The angle is beyond what a single point is taken for, or beyond the tilt limit:
    /// likely heights in another datum than the start's.
    BeyondLimit,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl OdoPitchFit {
    /// The angle the corrected navigation takes, rad (the configured one when refused).
    pub fn applied_rad(&self) -> f64 {
        if self.applied {
            self.odo_pitch_deg
        } else {
            self.configured_deg
        }
        .to_radians()
    }

    /// What the fit moved the angle by from the configured one, deg (0 when refused).
    pub fn change_deg(&self) -> f64 {
        if self.applied {
            self.odo_pitch_deg - self.configured_deg
        } else {
            0.0
        }
    }

    /// Records the corrected navigation's height errors (`after`, by id and time), as its
    /// pass measured them.
    pub fn measured(&mut self, after: &[HeightError]) {
        for p in &mut self.points {
            if let Some(a) = after.iter().find(|a| a.is_at(p.id, p.t_s)) {
                p.dh_m = a.dh_m;
            }
        }
    }
}

/// The sums of the least-squares fit of height errors against their slopes, through the
/// start: Σ dh·slope and Σ slope².
#[derive(Clone, Copy, Default)]
struct Sums {
    dh_slope: f64,
    slope2: f64,
}

impl Sums {
    fn of<'a>(errors: impl Iterator<Item = &'a HeightError>) -> Self {
        errors.fold(Self::default(), |s, e| Self {
            dh_slope: s.dh_slope + e.dh_m * e.slope_m,
            slope2: s.slope2 + e.slope_m * e.slope_m,
        })
    }

    /// The sums without `e` (one of them).
    fn without(self, e: &HeightError) -> Self {
        Self {
            dh_slope: self.dh_slope - e.dh_m * e.slope_m,
            slope2: self.slope2 - e.slope_m * e.slope_m,
        }
    }

    /// tan β: the angle that takes the errors away, None without a point along the route.
    fn tan(self) -> Option<f64> {
        (self.slope2 > 0.0).then(|| -self.dh_slope / self.slope2)
    }
}

/// Fits the pitch boresight to a route's height errors at its control points (of the
/// route with the `configured_deg` angle), and judges what it adds to that angle (see the
/// module's doc). None without any point.
pub fn fit_odo_pitch(errors: &[HeightError], configured_deg: f64) -> Option<OdoPitchFit> {
    if errors.is_empty() {
        return None;
    }
    let far = |e: &&HeightError| e.distance_m >= MIN_DISTANCE_M;
    let tan_change = Sums::of(errors.iter()).tan().unwrap_or(0.0);
    let far_count = errors.iter().filter(far).count();
    // A far point held out: the far points' sums without it.
    let far_sums = Sums::of(errors.iter().filter(far));
    let points: Vec<OdoPitchPoint> = errors
        .iter()
        .map(|e| {
            let holdout_dh_m = (far_count >= 2 && far(&e))
                .then(|| far_sums.without(e).tan().map(|t| e.dh_m + t * e.slope_m))
                .flatten();
            OdoPitchPoint {
                id: e.id,
                t_s: e.t_s,
                distance_m: e.distance_m,
                slope_m: e.slope_m,
                dh_before_m: e.dh_m,
                dh_m: e.dh_m,
                holdout_dh_m,
            }
        })
        .collect();
    let configured_rad = configured_deg.to_radians();
    let odo_pitch_deg = (configured_rad.tan() + tan_change).atan().to_degrees();
    let change_deg = odo_pitch_deg - configured_deg;
    let without = if configured_rad == 0.0 {
        "without any".to_owned()
    } else {
        format!("with the configured {configured_deg:.3}° alone")
    };
    let refused = if far_count == 0 {
        Some((
            OdoPitchRefusal::NoFarPoint,
            format!("no control point lies {MIN_DISTANCE_M:.0} m or more along the route"),
        ))
    } else if let Some(p) = points.iter().find(|p| {
        p.holdout_dh_m
            .is_some_and(|h| h.abs() >= p.dh_before_m.abs())
    }) {
        let shown = if configured_rad == 0.0 {
            "do not show one angle".to_owned()
        } else {
            format!("show no one angle beyond the configured {configured_deg:.3}°")
        };
        Some((
            OdoPitchRefusal::NotOneAngle,
            format!(
                "the heights {shown}: point {}'s, fitted from the others, is {:+.2} m off \
                 against {:+.2} m {without}",
                p.id,
                p.holdout_dh_m.unwrap_or(f64::NAN),
                p.dh_before_m
            ),
        ))
    } else {
        let last = errors
            .iter()
            .filter(far)
            .max_by(|a, b| a.distance_m.total_cmp(&b.distance_m))
            .expect("a far point");
        let at_last = format!(
            "point {}: {:+.1} m after {:.0} m",
            last.id, last.dh_m, last.distance_m
        );
        let datum = "are the control points' heights in the start's datum (ellipsoidal or \
                     above the geoid, which lie 20–50 m apart)?";
        let why = if far_count < 2 && change_deg.abs() > MAX_ODO_PITCH_DEG {
            let beyond = if configured_rad == 0.0 {
                String::new()
            } else {
                format!(" beyond the configured {configured_deg:.3}°")
            };
            Some(format!(
                "the heights need {change_deg:.1}°{beyond}, more than the \
                 {MAX_ODO_PITCH_DEG}° a single point is taken for ({at_last}): {datum}"
            ))
        } else {
            (odo_pitch_deg.abs() > MAX_AGREED_ODO_PITCH_DEG).then(|| {
                format!(
                    "the heights need {odo_pitch_deg:.1}°, more than the \
                     {MAX_AGREED_ODO_PITCH_DEG}° the axes check's tilt limit ({at_last}): \
                     {datum}"
                )
            })
        };
        why.map(|w| (OdoPitchRefusal::BeyondLimit, w))
    };
    let (refused_for, refused) = refused.unzip();
    Some(OdoPitchFit {
        odo_pitch_deg,
        configured_deg,
        applied: refused.is_none(),
        refused,
        refused_for,
        points,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(id: u32, distance_m: f64, dh_m: f64) -> HeightError {
        HeightError {
            id,
            t_s: f64::from(id),
            distance_m,
            dh_m,
            slope_m: distance_m,
        }
    }

    /// The slopes a probe pass measures: a point's height moving by `slope` per tan β.
    #[test]
    fn slopes_are_measured_by_a_probe() {
        let errors = [err(1, 805.0, 125.26), err(2, 2397.0, 377.74)];
        let tan = 0.1;
        let probe = [
            err(1, 805.0, 125.26 + 0.1 * 760.0),
            err(2, 2397.0, 377.74 + 0.1 * 2250.0),
        ];
        let measured = with_slopes(&errors, &probe, tan);
        assert!((measured[0].slope_m - 760.0).abs() < 1e-9);
        assert!((measured[1].slope_m - 2250.0).abs() < 1e-9);
        // Fitted on those slopes, the errors go as the probe says they would.
        let fit = fit_odo_pitch(&measured, 0.0).unwrap();
        let t = fit.odo_pitch_deg.to_radians().tan();
        let sxy = 125.26 * 760.0 + 377.74 * 2250.0;
        assert!((t + sxy / (760.0f64.powi(2) + 2250.0f64.powi(2))).abs() < 1e-12);
    }

    /// Kingston's two points (the joint fit's route): 14.36 m low after 792 m, 38.38 m
    /// low after 2363 m: 0.94°, each point predicted by the other within 1.5 and 4.5 m.
    #[test]
    fn kingstons_heights_show_one_angle() {
        let fit = fit_odo_pitch(&[err(1, 792.3, -14.36), err(2, 2363.3, -38.38)], 0.0).unwrap();
        assert!(fit.applied, "{fit:?}");
        assert!((fit.odo_pitch_deg - 0.9415).abs() < 1e-3, "{fit:?}");
        let h: Vec<f64> = fit.points.iter().map(|p| p.holdout_dh_m.unwrap()).collect();
        assert!(
            (h[0] + 1.49).abs() < 0.02 && (h[1] - 4.47).abs() < 0.02,
            "{h:?}"
        );
        assert_eq!(fit.applied_rad(), fit.odo_pitch_deg.to_radians());
    }

    /// One point: its angle, taken, with nothing to hold out.
    #[test]
    fn one_point_gives_its_angle() {
        let fit = fit_odo_pitch(&[err(1, 1000.0, 10.0)], 0.0).unwrap();
        assert!(fit.applied);
        assert!((fit.odo_pitch_deg + 0.01f64.atan().to_degrees()).abs() < 1e-12);
        assert_eq!(fit.points[0].holdout_dh_m, None);
    }

    /// A datum 30 m off at both points does not grow with distance: the points do not
    /// show one angle. At one point it is more than a single point is taken for; two
    /// points agreeing on 8.9° (an IMU pitched 10° on its mount) are taken.
    #[test]
    fn a_datum_offset_is_refused() {
        let fit = fit_odo_pitch(&[err(1, 792.3, 15.64), err(2, 2363.3, -8.38)], 0.0).unwrap();
        assert!(!fit.applied);
        assert_eq!(fit.applied_rad(), 0.0);
        assert_eq!(fit.refused_for, Some(OdoPitchRefusal::NotOneAngle));
        assert!(fit.refused.unwrap().contains("do not show one angle"));
        let fit = fit_odo_pitch(&[err(1, 300.0, -35.0)], 0.0).unwrap();
        assert!(!fit.applied);
        assert!(
            fit.refused.unwrap().contains("datum"),
            "{:?}",
            fit.odo_pitch_deg
        );
        let fit = fit_odo_pitch(&[err(1, 805.0, 125.26), err(2, 2397.0, 377.74)], 0.0).unwrap();
        assert!(
            fit.applied && (fit.odo_pitch_deg + 8.94).abs() < 0.01,
            "{fit:?}"
        );
        let fit = fit_odo_pitch(&[err(1, 805.0, 600.0), err(2, 2397.0, 1790.0)], 0.0).unwrap();
        assert!(!fit.applied && fit.refused.unwrap().contains("tilt limit"));
        assert_eq!(fit.refused_for, Some(OdoPitchRefusal::BeyondLimit));
    }

    /// Points near the start say nothing of an angle: refused, and not held out.
    #[test]
    fn points_near_the_start_are_not_judged() {
        let fit = fit_odo_pitch(&[err(1, 50.0, -1.0)], 0.0).unwrap();
        assert!(!fit.applied);
        assert_eq!(fit.refused_for, Some(OdoPitchRefusal::NoFarPoint));
        assert!(fit.refused.unwrap().contains("200 m"));
        let fit = fit_odo_pitch(&[err(1, 50.0, 0.3), err(2, 2000.0, -20.0)], 0.0).unwrap();
        assert!(fit.applied, "{fit:?}");
        assert_eq!(fit.points[0].holdout_dh_m, None);
        assert_eq!(fit.points[1].holdout_dh_m, None);
        assert!(fit_odo_pitch(&[], 0.0).is_none());
    }

    /// With a configured angle the errors are the route's with it: the fit adds what they
    /// show beyond it, and a refused fit leaves the configured angle.
    #[test]
    fn a_configured_angle_is_the_fits_start() {
        let configured_deg = 0.9;
        let tan_configured = 0.9f64.to_radians().tan();
        // Kingston's route with 0.9° already in: 0.0415° more shows at both points.
        let left = |d: f64| -d * (0.9415f64.to_radians().tan() - tan_configured);
        let fit = fit_odo_pitch(
            &[err(1, 792.3, left(792.3)), err(2, 2363.3, left(2363.3))],
            configured_deg,
        )
        .unwrap();
        assert!(fit.applied, "{fit:?}");
        assert!((fit.odo_pitch_deg - 0.9415).abs() < 1e-9, "{fit:?}");
        assert!((fit.change_deg() - 0.0415).abs() < 1e-9);
        assert_eq!(fit.configured_deg, 0.9);
        // A single point 30 m off in datum after 300 m moves it by 5.7°: refused, and the
        // configured angle stays.
        let fit = fit_odo_pitch(&[err(1, 300.0, -30.0)], configured_deg).unwrap();
        assert!(!fit.applied);
        assert_eq!(fit.applied_rad(), 0.9f64.to_radians());
        assert_eq!(fit.change_deg(), 0.0);
        assert_eq!(fit.refused_for, Some(OdoPitchRefusal::BeyondLimit));
        let why = fit.refused.unwrap();
        assert!(why.contains("5.7° beyond the configured 0.900°"), "{why}");
        // Points that show no one change are judged against the configured angle alone.
        let fit = fit_odo_pitch(
            &[err(1, 792.3, 15.64), err(2, 2363.3, -8.38)],
            configured_deg,
        )
        .unwrap();
        assert_eq!(fit.refused_for, Some(OdoPitchRefusal::NotOneAngle));
        let why = fit.refused.unwrap();
        assert!(why.contains("beyond the configured 0.900°: point"), "{why}");
        assert!(why.contains("with the configured 0.900° alone"), "{why}");
        // Points that agree are taken up to the tilt limit, in all.
        let steep = |d: f64, tilt_deg: f64| -d * (tilt_deg.to_radians().tan() - tan_configured);
        let up_to = |tilt_deg| {
            fit_odo_pitch(
                &[
                    err(1, 800.0, steep(800.0, tilt_deg)),
                    err(2, 2400.0, steep(2400.0, tilt_deg)),
                ],
                configured_deg,
            )
            .unwrap()
        };
        assert!(up_to(29.5).applied);
        let fit = up_to(30.5);
        assert!(!fit.applied && fit.refused.unwrap().contains("tilt limit"));
    }

    /// The corrected pass's own errors replace the fit's, point by point.
    #[test]
    fn measured_errors_are_recorded() {
        let mut fit = fit_odo_pitch(&[err(1, 792.3, -14.36), err(2, 2363.3, -38.38)], 0.0).unwrap();
        fit.measured(&[err(2, 2363.3, 0.44)]);
        assert_eq!(fit.points[0].dh_m, -14.36);
        assert_eq!(fit.points[1].dh_m, 0.44);
    }
}
