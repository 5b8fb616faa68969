//! The coarse azimuth search over ±180° by the control points, before the methods.

use serde::{Deserialize, Serialize};
use unz_stages::criteria;
use unz_stages::disupt::{DisuptParams, Problem, X, kryt1_with_free_drifts_xy};
use unz_stages::linearized::Observation;

/// Step of the coarse azimuth grid, degrees.
const COARSE_AZIMUTH_STEP_DEG: f64 = 1.0;
/// Most grid minima the coarse search checks with exact passes (one batch of lanes).
const COARSE_AZIMUTH_CHECKS: usize = 8;

/// The control points' RMS error if the route of `y0` turned by `dpsi_rad` about its
/// start. `known_m` are the control points' (north, east) from the start.
fn turned_rms_m(y0: &Observation, known_m: &[[f64; 2]], dpsi_rad: f64) -> f64 {
    let (s, c) = dpsi_rad.sin_cos();
    criteria::kryt2_rms_m(y0.cp_m.iter().zip(known_m).map(|(d, k)| {
        // Navigated position from the start, turned clockwise (heading) by dpsi.
        let (n, e) = (k[0] + d[0], k[1] + d[1]);
        [n * c - e * s - k[0], n * s + e * c - k[1]]
    }))
}

/// What the coarse azimuth search found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Coarse {
    /// Nothing better than the run's initial azimuth (or no control point).
    Kept,
    /// A better start for the searches, degrees.
    Taken(f64),
    /// A turn that fits the control points better but the pitch and roll worse: refused.
    Refused(CoarseRefused),
}

impl Coarse {
    /// The azimuth taken, degrees.
    pub fn taken_deg(self) -> Option<f64> {
        match self {
            Coarse::Taken(az) => Some(az),
            _ => None,
        }
    }

    /// The turn refused.
    pub fn refused(self) -> Option<CoarseRefused> {
        match self {
            Coarse::Refused(r) => Some(r),
            _ => None,
        }
    }
}

/// A coarse azimuth the control points preferred and Kryt1 refused (`disupt.json`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CoarseRefused {
    /// The azimuth the control points preferred, degrees.
    pub azimuth_deg: f64,
    /// The control points' RMS error there, m.
    pub kryt2_rms_m: f64,
    /// Kryt1 there with the horizontal drifts free (their least Kryt1), rad.
    pub kryt1_rad: f64,
    /// The control points' RMS error at the run's initial azimuth, m.
    pub start_kryt2_rms_m: f64,
    /// Kryt1 at the run's initial azimuth with the horizontal drifts free, rad.
    pub start_kryt1_rad: f64,
}

/// What a user is told of a refused coarse turn (the log, `disupt.md`, the campaign's
/// note).
pub fn coarse_refused_note(r: &CoarseRefused) -> String {
    format!(
        "coarse azimuth search: turning the route to {:.1}° fits the control points better \
         ({:.1} m RMS against {:.1} m) but the pitch and roll worse (Kryt1 {:.2} against \
         {:.2} rad, the horizontal drifts free), so the searches start at the initial \
         azimuth: the control points lie too near the start to fix the azimuth (a route \
         looping back to its start point), or one of them is wrong",
        r.azimuth_deg, r.kryt2_rms_m, r.start_kryt2_rms_m, r.kryt1_rad, r.start_kryt1_rad
    )
}

/// The azimuth with the smallest RMS error over the control points, searched over ±180°
/// around the problem's start, when it beats the start.
///
/// A change of initial azimuth turns an odometer-aided route about its start (the
/// Earth-rate terms it moves change the heading far less than the grid's step), so one
/// pass gives the whole 1° grid; the grid's minima (at most eight) are then checked with
/// exact passes side by side, and the best exact one is the answer. Nine passes instead
/// of the 36 that a 10° grid of exact passes took.
///
/// The turn is taken only when the gyro pitch and roll agree: Kryt1 there no larger than
/// at the start. Control points say little of the azimuth when they lie near the start
/// compared with the route's other errors (a drive that loops back to its start point):
/// turning the route then matches them at almost any azimuth, and the search would start
/// every method tens of degrees off (measured: a 7.8-km loop ending 10 m from the start,
/// manifest 5.3° off, a survey 10–40 m off: turns of 74–141°, the joint fit out of its
/// bounds, OEPI's "correction" 94–159° off with a 3-m error at the point). A wrong
/// azimuth misapplies the Earth's rate to the pitch and roll, so Kryt1 shows it: 161–239
/// there against 15.5 at the start, where on eight runs the taken turn's Kryt1 was 3–36
/// times smaller than the start's.
///
/// Kryt1 at the initial drifts decides first, from the passes at hand. Where it would
/// refuse, Kryt1 with the horizontal drifts free (within the methods' ±5 °/h) at both
/// decides instead ([`kryt1_with_free_drifts_xy`], four passes), for at given drifts a
/// few degrees of azimuth pass for them: two right turns of 5–6° on 15-minute runs
/// showed 1.24 and 1.28 times the start's Kryt1 (2 of 12 such runs refused, with a note
/// blaming a loop), and 0.97 and 0.79 times with the drifts free. The 22 wrong turns of
/// 24 loops (four routes back within 20–75 m of their start after 5–11 km, the manifest
/// 5.3° or 5–7.5° off, the point intact or 10–30 m off) kept 1.13–7.0 times the start's
/// Kryt1 with the drifts free: all refused, as before.
pub fn coarse_azimuth(problem: &Problem<'_>, dparams: &DisuptParams) -> Coarse {
    if problem.fixes.is_empty() {
        return Coarse::Kept;
    }
    let x0 = problem.x0();
    let tally = std::sync::atomic::AtomicUsize::new(0);
    let y0 = problem.observe_by(&x0, &tally);
    let start = problem.base.start();
    let known_m: Vec<[f64; 2]> = problem
        .fixes
        .iter()
        .map(|f| {
            let (n, e) = start.offset_m(f.lat_rad, f.lon_rad);
            [n, e]
        })
        .collect();
    let steps = (360.0 / COARSE_AZIMUTH_STEP_DEG) as usize;
    let predicted: Vec<f64> = (0..steps)
        .map(|i| {
            turned_rms_m(
                &y0,
                &known_m,
                (i as f64 * COARSE_AZIMUTH_STEP_DEG).to_radians(),
            )
        })
        .collect();
    let mut minima: Vec<usize> = (1..steps)
        .filter(|&i| predicted[i] <= predicted[i - 1] && predicted[i] <= predicted[(i + 1) % steps])
        .collect();
    minima.sort_by(|&a, &b| predicted[a].total_cmp(&predicted[b]));
    minima.truncate(COARSE_AZIMUTH_CHECKS);
    let xs: Vec<X> = minima
        .iter()
        .map(|&i| X {
            azimuth_deg: x0.azimuth_deg + i as f64 * COARSE_AZIMUTH_STEP_DEG,
            ..x0
        })
        .collect();
    let ys = problem.observe_many_by(&xs, &tally);
    let exact: Vec<f64> = ys.iter().map(Observation::kryt2_rms).collect();
    let Some(best) = (0..xs.len()).min_by(|&a, &b| exact[a].total_cmp(&exact[b])) else {
        return Coarse::Kept;
    };
    // (NaN errors, a pass that diverged, beat nothing.)
    if exact[best].partial_cmp(&y0.kryt2_rms()) != Some(std::cmp::Ordering::Less) {
        return Coarse::Kept;
    }
    let turn = xs[best].azimuth_deg - x0.azimuth_deg;
    let azimuth_deg = x0.azimuth_deg + (turn + 180.0).rem_euclid(360.0) - 180.0;
    // Kryt1 at the initial drifts first (two sums over passes at hand); where it refuses,
    // again with the horizontal drifts free at both, which decide (a few degrees of
    // azimuth pass for them at given drifts). Refused only on the evidence of two finite
    // values (none from a log without valid epochs, nor from an optimiser's failure: the
    // control points then decide, as before).
    let worse = |turned: f64, start: f64| turned.is_finite() && start.is_finite() && turned > start;
    let kryt1 = |y: &Observation| problem.kryt1(y);
    let refused = worse(kryt1(&ys[best]), kryt1(&y0)).then(|| {
        match kryt1_with_free_drifts_xy(
            problem,
            &[(xs[best], &ys[best]), (x0, &y0)],
            dparams,
            &tally,
        )
        .as_deref()
        {
            Ok(&[turned, start]) => (turned, start),
            _ => (f64::NAN, f64::NAN),
        }
    });
    let refused = refused.filter(|&(turned, start)| worse(turned, start));
    match refused {
        None => Coarse::Taken(azimuth_deg),
        Some((kryt1_rad, start_kryt1_rad)) => Coarse::Refused(CoarseRefused {
            azimuth_deg,
            kryt2_rms_m: exact[best],
            kryt1_rad,
            start_kryt2_rms_m: y0.kryt2_rms(),
            start_kryt1_rad,
        }),
    }
}
