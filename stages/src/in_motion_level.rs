//! Levelling in motion: the initial pitch and roll of a log that begins while driving,
//! fitted to the accelerometer references of its first minute.
//!
//! Without a static start the levelling can only read the accelerometer references
//! Θ_p, Φ_p (eqs 7–8), and one epoch of them is as noisy as the odometer's acceleration
//! u̇ is: on simulated runs the first epoch alone levelled up to 2.8° off, and every method
//! then bent the gyro drifts to make up for the tilt. The fit here reads every valid epoch
//! of the first [`IN_MOTION_LEVEL_WINDOW_S`]: the navigation's filtered pitch and roll
//! (Θ_N, Φ_N, the same filter as the references), and how they move per milliradian of
//! initial pitch and roll (one pass each, side by side in lanes), so the vehicle's turns
//! over the window (which carry an initial tilt from pitch into roll) are accounted for.
//! Gauss–Newton on those residuals. The passes navigate the window and a margin after
//! it only ([`FILTER_MARGIN_S`]), so the levelling costs the same whatever the log's length.
//!
//! The window trades the references' noise against the drifts' tilt, which grows over it
//! (1 °/h: 0.017° a minute) and which the fit would take for an initial tilt. On six
//! simulated 40-minute logs begun while driving (two control points, LN-200 errors), the
//! joint fit's worst azimuth error with windows of 30, 60, 90, 120 and 300 s was 0.16,
//! 0.11, 0.11, 0.20 and 0.45° (and two fits out of bounds), against 0.57° and two out of
//! bounds levelled from the first epoch alone.

use std::sync::atomic::AtomicUsize;

use crate::attitude::wrap_pi;
use crate::disupt::Problem;
use crate::strapdown::NavSettings;

/// Seconds from the first epoch whose valid epochs the levelling reads.
pub const IN_MOTION_LEVEL_WINDOW_S: f64 = 60.0;
/// Fewest valid epochs the fit needs; with fewer the first epoch's references stand.
const MIN_EPOCHS: usize = 10;
/// Gauss–Newton rounds at most: the residuals are all but linear in the tilt (a first
/// step of 39 mrad was followed by one of 0.009 mrad, then 10⁻⁷).
const ROUNDS: usize = 3;
/// Step of the forward differences, mrad.
const STEP_MRAD: f64 = 1.0;
/// Seconds navigated past the window: the zero-phase filter's backward sweep starts at
/// the end of what a pass navigated, and its start-up has died away (by e^−50 at the
/// default 0.3 Hz) well before it reaches the window.
pub const FILTER_MARGIN_S: f64 = 30.0;

/// Which initial angles the fit may move (those levelled in motion; a manifest's stand).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Free {
    /// Initial pitch.
    pub pitch: bool,
    /// Initial roll.
    pub roll: bool,
}

/// The fit's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InMotionLevel {
    /// The settings with the fitted initial pitch and roll.
    pub settings: NavSettings,
    /// Valid epochs the fit read.
    pub epochs: usize,
    /// RMS of their pitch and roll residuals at the fitted angles, rad.
    pub residual_rms_rad: f64,
}

/// Fits the initial pitch and roll of `problem`'s base settings (those `free`) to the
/// valid epochs of its first [`IN_MOTION_LEVEL_WINDOW_S`]; `None` with fewer than ten.
pub fn level_in_motion(whole: &Problem<'_>, free: Free) -> Option<InMotionLevel> {
    if !(free.pitch || free.roll) {
        return None;
    }
    let t_first = *whole.epochs.t_s.first()?;
    // The problem over the window and the filter's margin only.
    let kept = whole
        .epochs
        .t_s
        .partition_point(|&t| t <= t_first + IN_MOTION_LEVEL_WINDOW_S + FILTER_MARGIN_S);
    let e = &whole.epochs.prefix(kept);
    let samples = e
        .block
        .last()
        .map_or(0, |&b| (b + 1) * whole.lp.block)
        .min(whole.inputs.dt_s.len());
    let i = &whole.inputs;
    let inputs = crate::strapdown::NavInputs {
        dt_s: &i.dt_s[..samples],
        dtheta_rad: i.dtheta_rad.prefix(samples),
        odo_dist_m: &i.odo_dist_m[..samples],
    };
    let problem = Problem::new(inputs, whole.base, e, whole.lp, whole.kalman, &[]);
    let window: Vec<usize> = (0..e.t_s.len())
        .take_while(|&k| e.t_s[k] <= t_first + IN_MOTION_LEVEL_WINDOW_S)
        .filter(|&k| e.valid[k])
        .collect();
    if window.len() < MIN_EPOCHS {
        return None;
    }
    let residuals = |y: &crate::linearized::Observation| -> Vec<f64> {
        window
            .iter()
            .flat_map(|&k| {
                [
                    y.theta_rad[k] - e.theta_p_rad[k],
                    wrap_pi(y.phi_rad[k] - e.phi_p_rad[k]),
                ]
            })
            .collect()
    };
    let tally = AtomicUsize::new(0);
    let mut x = problem.x0();
    for _ in 0..ROUNDS {
        let moved = |k: usize| {
            let mut m = x;
            m.tilt_mrad[k] += STEP_MRAD;
            m
        };
        let ys = problem.observe_batched_by(&[x, moved(0), moved(1)], &tally);
        let r = residuals(&ys[0]);
        let slopes: Vec<Vec<f64>> = ys[1..]
            .iter()
            .map(|y| {
                residuals(y)
                    .iter()
                    .zip(&r)
                    .map(|(a, b)| (a - b) / STEP_MRAD)
                    .collect()
            })
            .collect();
        let step = solve(&slopes, &r, [free.pitch, free.roll])?;
        x.tilt_mrad[0] += step[0];
        x.tilt_mrad[1] += step[1];
        if step[0].hypot(step[1]) < 1e-3 {
            break;
        }
    }
    // The residuals at the result (one more pass).
    let y = problem.observe_batched_by(&[x], &tally);
    let r = residuals(&y[0]);
    let rms = (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
    Some(InMotionLevel {
        settings: problem.settings(&x),
        epochs: window.len(),
        residual_rms_rad: rms,
    })
}

/// The least-squares step (mrad) of the free angles: `slopes[j]` is the residuals' change
/// per mrad of angle j; `None` when the free angles leave the residuals unmoved.
fn solve(slopes: &[Vec<f64>], r: &[f64], free: [bool; 2]) -> Option<[f64; 2]> {
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let (a, b) = (&slopes[0], &slopes[1]);
    let n = nalgebra::Matrix2::new(
        if free[0] { dot(a, a) } else { 1.0 },
        if free[0] && free[1] { dot(a, b) } else { 0.0 },
        if free[0] && free[1] { dot(a, b) } else { 0.0 },
        if free[1] { dot(b, b) } else { 1.0 },
    );
    let g = nalgebra::Vector2::new(
        if free[0] { -dot(a, r) } else { 0.0 },
        if free[1] { -dot(b, r) } else { 0.0 },
    );
    let s = n.try_inverse()? * g;
    (s[0].is_finite() && s[1].is_finite()).then_some([s[0], s[1]])
}

#[cfg(test)]
mod tests {
    use super::solve;

    #[test]
    fn the_step_solves_the_linear_residuals_and_keeps_fixed_angles() {
        // r + a·δp + b·δr = 0 exactly at δ = (2, −3).
        let a = vec![1.0, 0.0, 0.5, 0.2];
        let b = vec![0.0, 1.0, 0.3, -0.4];
        let r: Vec<f64> = a
            .iter()
            .zip(&b)
            .map(|(a, b)| -(2.0 * a - 3.0 * b))
            .collect();
        let both = solve(&[a.clone(), b.clone()], &r, [true, true]).unwrap();
        assert!((both[0] - 2.0).abs() < 1e-12 && (both[1] + 3.0).abs() < 1e-12);
        // Pitch fixed: only roll moves, to its least-squares value.
        let roll = solve(&[a, b.clone()], &r, [false, true]).unwrap();
        let bb: f64 = b.iter().map(|v| v * v).sum();
        let br: f64 = b.iter().zip(&r).map(|(x, y)| x * y).sum();
        assert_eq!(roll[0], 0.0);
        assert!((roll[1] + br / bb).abs() < 1e-12);
        // Residuals the angles do not move: no step.
        assert!(solve(&[vec![0.0; 4], vec![0.0; 4]], &r, [true, true]).is_none());
    }
}
