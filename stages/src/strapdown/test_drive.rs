//! A drive, and passes over it, for the kernels' unit tests.

use super::NavSettings;
use crate::attitude::Euler;

/// The angle increments of a turning, bumping drive of `n` samples 10 ms apart, with one
/// violent sample (at 2500, beyond the half-angle series), rad.
pub(super) fn turning_dtheta(n: usize) -> Vec<[f64; 3]> {
    (0..n)
        .map(|k| {
            let t = k as f64 * 0.01;
            if k == 2500 {
                return [0.2, -0.1, 0.3];
            }
            [
                1e-4 * (t * 3.0).sin(),
                2e-4 * (t * 2.0).cos(),
                3e-3 * (t * 0.5).sin(),
            ]
        })
        .collect()
}

/// The settings of lane `l` of a batch whose lanes all differ: headings, drifts and
/// odometer scales; lanes 5 and 6 have an odometer boresight (so a batch of eight takes
/// that loop), lane 3 a speed bias.
pub(super) fn lane_settings(l: usize) -> NavSettings {
    NavSettings {
        initial: Euler {
            roll_rad: 0.01,
            pitch_rad: -0.02,
            heading_rad: 0.3 * l as f64,
        },
        drift_rad_s: [1e-6 * l as f64, -2e-7, 3e-6],
        odo_scale: 1.0 + 1e-4 * l as f64,
        odo_yaw_rad: if l == 5 || l == 6 { 0.01 } else { 0.0 },
        odo_pitch_rad: if l == 6 { 0.02 } else { 0.0 },
        odo_bias_mps: if l == 3 { -0.08 } else { 0.0 },
        lat0_rad: 0.78,
        lon0_rad: -1.33,
        h0_m: 90.0,
    }
}
