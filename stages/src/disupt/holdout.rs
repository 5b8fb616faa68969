//! Hold-out errors: each control point's error when the joint fit leaves it out.

use std::sync::atomic::AtomicUsize;

use serde::{Deserialize, Serialize};

use super::DisuptError;
use super::joint::{JointFit, JointModel, JointOptions, joint_fit};
use super::problem::Problem;
use super::settings::{DisuptParams, X, x_of};
use crate::linearized::Setting;

/// The error at a control point when it was left out of the joint fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Holdout {
    /// Control-point id.
    pub id: u32,
    /// ΔX north there, navigated minus known, m.
    pub dx_m: f64,
    /// ΔY east there, m.
    pub dy_m: f64,
}

/// Median and largest horizontal error of hold-out results, m (`None` without any).
pub fn holdout_median_max_m(h: &[Holdout]) -> Option<(f64, f64)> {
    let mut e: Vec<f64> = h.iter().map(|p| p.dx_m.hypot(p.dy_m)).collect();
    e.sort_by(f64::total_cmp);
    let n = e.len();
    let median = match n {
        0 => return None,
        _ if n % 2 == 1 => e[n / 2],
        _ => 0.5 * (e[n / 2 - 1] + e[n / 2]),
    };
    Some((median, e[n - 1]))
}

/// Hold-out errors: for every control point, the joint fit without it (same weights),
/// and the error there of an exact pass with those settings. Each refit solves the
/// fit's linearisation without the point's rows (no pass); the exact passes run side by
/// side, and a refit whose exact pass disagrees with the model is redone in full.
pub fn holdout(
    problem: &Problem<'_>,
    fit: &JointFit,
    p: &DisuptParams,
) -> Result<Vec<Holdout>, DisuptError> {
    let n = problem.fixes.len();
    let mut ps = Vec::with_capacity(n);
    for i in 0..n {
        // Without the only control point, nothing sees the odometer's settings.
        let free: Vec<Setting> = fit
            .free
            .iter()
            .copied()
            .filter(|s| n > 1 || !s.needs_control_points())
            .collect();
        let model = JointModel::new(problem, &fit.lin, &free, &fit.weights, Some(i));
        let delta = model
            .a
            .clone()
            .svd(true, true)
            .solve(&(-&model.r0), 1e-12)
            .map_err(DisuptError::Linear)?;
        let mut pi = fit.lin.p_ref;
        for (k, s) in free.iter().enumerate() {
            pi[s.index()] += delta[k];
        }
        ps.push(pi);
    }
    let xs: Vec<X> = ps.iter().map(x_of).collect();
    let ys = problem.observe_many_by(&xs, &AtomicUsize::new(0));
    let mut out = Vec::with_capacity(n);
    for (i, (pi, y)) in ps.iter().zip(ys).enumerate() {
        let y = if fit.lin.predict(pi).agrees_with(&y) {
            y
        } else {
            let opts = JointOptions {
                attitude_sigma_rad: Some(fit.attitude_sigma_rad),
                skip_cp: Some(i),
                warm: Some(&fit.lin),
            };
            joint_fit(problem, p, &opts)?.y
        };
        out.push(Holdout {
            id: problem.fixes[i].id,
            dx_m: y.cp_m[i][0],
            dy_m: y.cp_m[i][1],
        });
    }
    Ok(out)
}
