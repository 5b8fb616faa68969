//! The coarse azimuth search over ±180° by the control points, before the methods.

use unz_stages::criteria;
use unz_stages::disupt::{Problem, X};
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

/// The azimuth with the smallest RMS error over the control points, searched over ±180°
/// around the problem's start, when it beats the start; `None` without control points.
///
/// A change of initial azimuth turns an odometer-aided route about its start (the
/// Earth-rate terms it moves change the heading far less than the grid's step), so one
/// pass gives the whole 1° grid; the grid's minima (at most eight) are then checked with
/// exact passes side by side, and the best exact one is the answer. Nine passes instead
/// of the 36 that a 10° grid of exact passes took.
pub fn coarse_azimuth_deg(problem: &Problem<'_>) -> Option<f64> {
    if problem.fixes.is_empty() {
        return None;
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
    let exact: Vec<f64> = problem
        .observe_many_by(&xs, &tally)
        .iter()
        .map(Observation::kryt2_rms)
        .collect();
    let best = (0..xs.len()).min_by(|&a, &b| exact[a].total_cmp(&exact[b]))?;
    (exact[best] < y0.kryt2_rms()).then(|| {
        let az = xs[best].azimuth_deg - x0.azimuth_deg;
        x0.azimuth_deg + (az + 180.0).rem_euclid(360.0) - 180.0
    })
}
