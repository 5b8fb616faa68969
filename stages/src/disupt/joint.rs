//! The joint estimator: Gauss–Newton over every setting at once, on the attitude
//! residual series and every control point, with each estimate's 1σ.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use nalgebra::{DMatrix, DVector};

use super::DisuptError;
use super::gyro_walk::{WalkFit, WalkUptake, least_squares_map, walk_covariance_and_uptake};
use super::problem::Problem;
use super::results::{Component, Criterion, MethodResult, Step, last_cp};
use super::settings::{DisuptParams, X, x_of};
use crate::linearized::{Linearization, N_PARAMS, Observation, Setting};

/// The joint fit's weighted residuals and their Jacobian in the free parameters, from a
/// linearisation: `r(p) ≈ r0 + A (p − p_ref)`.
pub(super) struct JointModel {
    pub(super) r0: DVector<f64>,
    pub(super) a: DMatrix<f64>,
}

/// Weighted residuals of an observation at parameters `p`: every valid epoch's ΔΘ, ΔΦ
/// (plus the levelling corrections), every control point's ΔX, ΔY, and the static
/// driftz prior; with the gaps' tilt steps profiled out of the epochs' rows and their
/// priors' rows last ([`GapTilts::profile`](super::gap_tilts::GapTilts::profile)).
fn joint_residuals(
    problem: &Problem<'_>,
    y: &Observation,
    p: &[f64; N_PARAMS],
    params: &DisuptParams,
    skip_cp: Option<usize>,
) -> Vec<f64> {
    let e = problem.epochs;
    let s = params.attitude_sigma_rad;
    let mut r = Vec::with_capacity(2 * e.block.len() + 2 * y.cp_m.len() + 1);
    // The odometer boresight moves the accelerometer references (derive's u̇ and ru go
    // along the odometer), not the gyro attitude.
    // So does the odometer bias (u̇ at starts and stops, ru in turns).
    let yaw_rad = p[Setting::OdoYaw.index()].to_radians();
    let bias = p[Setting::OdoBias.index()];
    let tilt = [
        p[Setting::TiltPitch.index()] * 1e-3,
        p[Setting::TiltRoll.index()] * 1e-3,
    ];
    for k in 0..e.block.len() {
        if e.valid[k] {
            let theta_p =
                e.theta_p_rad[k] + e.theta_p_per_yaw[k] * yaw_rad + e.theta_p_per_bias[k] * bias;
            let phi_p = e.phi_p_rad[k] + e.phi_p_per_yaw[k] * yaw_rad + e.phi_p_per_bias[k] * bias;
            r.push((y.theta_rad[k] - theta_p + tilt[0]) / s);
            r.push((crate::attitude::wrap_pi(y.phi_rad[k] - phi_p) + tilt[1]) / s);
        }
    }
    // A control point held out or excluded keeps its rows, at zero, so that row indices
    // stay put.
    let weights = cp_weights(problem, skip_cp, params);
    for (c, w) in y.cp_m.iter().zip(&weights) {
        r.push(c[0] * w);
        r.push(c[1] * w);
    }
    // At rest the vertical gyro measures driftz directly (method.md): a prior.
    if let Some((dz, sd)) = problem.drift_z_prior_deg_h {
        r.push((p[Setting::DriftZ.index()] - dz) / sd);
    }
    // The gaps' tilt steps, profiled out of the attitude rows, their priors' rows last.
    if let Some(g) = &problem.gap_tilts {
        g.profile(&mut r, s, &weights);
    }
    r
}

/// Each control point's weight in [`joint_residuals`], 1/m: 0 for a point held out
/// (`skip_cp`) or left out of the fit.
pub(super) fn cp_weights(
    problem: &Problem<'_>,
    skip_cp: Option<usize>,
    params: &DisuptParams,
) -> Vec<f64> {
    (0..problem.fixes.len())
        .map(|i| {
            if problem.held_out(skip_cp, i) || !problem.cp_used(i) {
                0.0
            } else {
                1.0 / params.position_sigma_m
            }
        })
        .collect()
}

/// Rows at the tail of [`joint_residuals`] that the gaps' tilt steps' priors hold: as
/// many as the steps' parameters, so neither counts in the degrees of freedom.
pub(super) fn nuisance_rows(problem: &Problem<'_>) -> usize {
    problem.gap_tilts.as_ref().map_or(0, |g| g.prior_rows())
}

/// Rows of the attitude residuals at the head of [`joint_residuals`]: ΔΘ and ΔΦ of every
/// valid epoch.
pub(super) fn attitude_rows(problem: &Problem<'_>) -> usize {
    2 * problem.epochs.valid.iter().filter(|v| **v).count()
}

/// RMS of the attitude residuals (ΔΘ, ΔΦ with the levelling corrections) of the valid
/// epochs, rad.
fn attitude_rms_rad(
    problem: &Problem<'_>,
    y: &Observation,
    p: &[f64; N_PARAMS],
    params: &DisuptParams,
) -> f64 {
    let n = attitude_rows(problem);
    let r = joint_residuals(problem, y, p, params, None);
    (ssr(&r[..n.min(r.len())]) / n.max(1) as f64).sqrt() * params.attitude_sigma_rad
}

/// Variance inflation of the ΔΘ and ΔΦ residuals (`r` interleaves them) for their
/// correlation from epoch to epoch. What the filter leaves of the vehicle's dynamics
/// persists over many epochs (in the simulated runs the roll residuals' autocorrelation is
/// still 0.4–0.5 after 20 s), so they carry less information than as many independent
/// ones would. Each series' long-run variance over its variance, 1 + 2 Σ w_k ρ_k with
/// Bartlett weights w_k = 1 − k/(K+1) and the Newey–West lag K = ⌊4 (n/100)^(2/9)⌋, is
/// that factor (at least 1: anticorrelated residuals are not taken to carry more).
fn attitude_inflation(r: &[f64]) -> [f64; 2] {
    let long_run = |x: Vec<f64>| {
        let n = x.len();
        let mean = x.iter().sum::<f64>() / n.max(1) as f64;
        let var: f64 = x.iter().map(|v| (v - mean).powi(2)).sum();
        if var <= 0.0 {
            return 1.0;
        }
        let lags = (4.0 * (n as f64 / 100.0).powf(2.0 / 9.0)).floor() as usize;
        let sum: f64 = (1..=lags.min(n.saturating_sub(1)))
            .map(|k| {
                let rho = x
                    .iter()
                    .zip(&x[k..])
                    .map(|(a, b)| (a - mean) * (b - mean))
                    .sum::<f64>()
                    / var;
                (1.0 - k as f64 / (lags + 1) as f64) * rho
            })
            .sum();
        (1.0 + 2.0 * sum).max(1.0)
    };
    [
        long_run(r.iter().step_by(2).copied().collect()),
        long_run(r.iter().skip(1).step_by(2).copied().collect()),
    ]
}

fn ssr(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

impl JointModel {
    pub(super) fn new(
        problem: &Problem<'_>,
        lin: &Linearization,
        free: &[Setting],
        params: &DisuptParams,
        skip_cp: Option<usize>,
    ) -> Self {
        let r0 = joint_residuals(problem, &lin.y_ref, &lin.p_ref, params, skip_cp);
        let mut a = DMatrix::zeros(r0.len(), free.len());
        for (col, s) in free.iter().enumerate() {
            let j = s.index();
            let Some(slope) = &lin.slopes[j] else {
                continue;
            };
            // The residuals' slope: the observation's slope through the residual map,
            // whose only other dependence on p is the levelling offsets and the prior.
            let mut p1 = lin.p_ref;
            p1[j] += 1.0;
            let mut y1 = lin.y_ref.clone();
            for (v, d) in y1.theta_rad.iter_mut().zip(&slope.theta_rad) {
                *v += d;
            }
            for (v, d) in y1.phi_rad.iter_mut().zip(&slope.phi_rad) {
                *v += d;
            }
            for (v, d) in y1.cp_m.iter_mut().zip(&slope.cp_m) {
                v[0] += d[0];
                v[1] += d[1];
            }
            let r1 = joint_residuals(problem, &y1, &p1, params, skip_cp);
            for (i, (b, c)) in r1.iter().zip(&r0).enumerate() {
                a[(i, col)] = b - c;
            }
        }
        Self {
            r0: DVector::from_vec(r0),
            a,
        }
    }

    /// The model's least-squares step `δ` from `p_ref`: the `δ` that minimises
    /// `‖r0 + A δ‖`, exactly (the model is linear). `A`'s columns are taken to unit
    /// norm (the settings' units, rad to rad/s, put them orders of magnitude apart), its
    /// QR takes its rows to `R`'s few (as many as free settings), and `R`'s SVD solves
    /// them: a direction of singular value below [`SINGULAR_FLOOR`] is one the residuals
    /// do not tell apart, and takes no step (of the steps that fit as well, the least,
    /// each setting's measured by how far it moves the residuals); a setting without a
    /// slope (a column of zeros) takes none.
    ///
    /// Before, the Levenberg–Marquardt crate took the step, iterating on the linear
    /// model (a QR of `A` and a copy of it at each iteration: 5 % of the 12-hour run's
    /// disupt stage), to within its tolerances.
    pub(super) fn solve(&self) -> Result<DVector<f64>, DisuptError> {
        let (rows, n) = self.a.shape();
        let norms: Vec<f64> = self.a.column_iter().map(|c| c.norm()).collect();
        let seen: Vec<usize> = (0..n)
            .filter(|&j| norms[j] > 0.0 && norms[j].is_finite())
            .collect();
        if self.r0.iter().any(|r| !r.is_finite()) {
            return Err(DisuptError::Linear("a residual is not a finite number"));
        }
        let mut step = DVector::zeros(n);
        if seen.is_empty() {
            return Ok(step);
        }
        let scaled = DMatrix::from_fn(rows, seen.len(), |i, k| {
            self.a[(i, seen[k])] / norms[seen[k]]
        });
        let minus_r0 = -&self.r0;
        let solved = if rows < seen.len() {
            scaled.svd(true, true).solve(&minus_r0, SINGULAR_FLOOR)
        } else {
            let qr = scaled.qr();
            let mut b = minus_r0;
            qr.q_tr_mul(&mut b);
            qr.r()
                .svd(true, true)
                .solve(&b.rows(0, seen.len()), SINGULAR_FLOOR)
        };
        let solved = solved.map_err(DisuptError::Linear)?;
        for (k, &j) in seen.iter().enumerate() {
            step[j] = solved[k] / norms[j];
        }
        Ok(step)
    }
}

/// The singular value (of `A` with columns of unit norm, whose largest is 1 to
/// √settings) below which [`JointModel::solve`] takes a direction as unseen: two
/// settings whose slopes, as directions, lie within about 10⁻¹² rad of one another.
const SINGULAR_FLOOR: f64 = 1e-12;

impl JointFit {
    /// The control points' part of the cost of this fit redone on `lin` alone (its
    /// settings, weights and free parameters; no navigation pass): the model's optimum,
    /// scored on the model's residuals there.
    pub fn linearised_cp_cost(
        &self,
        problem: &Problem<'_>,
        lin: &Linearization,
    ) -> Result<f64, DisuptError> {
        let model = JointModel::new(problem, lin, &self.free, &self.weights, None);
        let r = &model.r0 + &model.a * model.solve()?;
        let n_att = attitude_rows(problem);
        let rows = n_att..(n_att + 2 * lin.y_ref.cp_m.len()).min(r.len());
        Ok(ssr(&r.as_slice()[rows]))
    }
}

/// The covariance of a joint fit's settings and of an odometer lag found by the control
/// points' misfit of fits at trial lags ([`JointFit::lag_marginal`]).
#[derive(Debug, Clone)]
pub struct LagMarginal {
    /// 1σ of each estimated setting with the lag's uncertainty in it (0 for the others).
    pub sigma: X,
    /// 1σ of the lag, s.
    pub lag_sigma_s: f64,
    /// The estimated settings' covariance with the lag's uncertainty in it, in the order
    /// of the fit's free settings ([`JointFit::covariance`]'s).
    pub covariance: DMatrix<f64>,
    /// Each estimated setting's covariance with the lag (the settings' units times s).
    pub lag_covariance: DVector<f64>,
    /// How those settings and then the lag take up the gyros' heading walk, the lag's
    /// search in their step ([`JointFit::walk_uptake`]'s, one row more).
    pub walk_uptake: Option<WalkUptake>,
}

impl JointFit {
    /// The weighted residuals of this fit's model on `lin` at its point (no solve): what
    /// a lag trial's linearisation starts from.
    pub fn linearised_residuals(&self, problem: &Problem<'_>, lin: &Linearization) -> Vec<f64> {
        joint_residuals(problem, &lin.y_ref, &lin.p_ref, &self.weights, None)
    }

    /// The settings' and the lag's covariance where the lag is the minimum of the control
    /// points' misfit of this fit's model redone at each lag (the odometer-lag search's
    /// estimator, [`crate::odo_lag`]), in the linear world of this fit's model on
    /// `problem` (the lag-free derive) with the lag's column `lag_slope` (the residuals'
    /// change per second of lag, from the trials beside the optimum). With
    /// `r = r0 + A x + b L`, each lag's fit is `x(L) = −G (r0 + b L)` (`G = (AᵀA)⁻¹Aᵀ`), the lag
    /// `L = −cᵀ r0` with `c = M b̃ / |b̃|²` (`M = I − A G`, `b̃` the control points' rows of
    /// `M b`), so `x = −G (I − b cᵀ) r0`: both linear in the residuals, whose covariance is
    /// the fit's scatter (its inflation on the epochs, `cp_s2` on the control points: their
    /// misfit per degree of freedom when worse than their σ) plus the gyros' walk
    /// ([`super::GyroWalk`]). The settings' σ so take the lag's uncertainty in, where the
    /// fit's own are conditional on its lag. `None` where the slope has other rows than
    /// the model, the control points do not see the lag, or the model is singular.
    pub fn lag_marginal(
        &self,
        problem: &Problem<'_>,
        lag_slope: &[f64],
        cp_s2: f64,
        azimuth_deg: f64,
    ) -> Option<LagMarginal> {
        let model = JointModel::new(problem, &self.lin, &self.free, &self.weights, None);
        let a = &model.a;
        let (m, p) = a.shape();
        if lag_slope.len() != m || lag_slope.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let g = least_squares_map(a)?;
        let b = DVector::from_column_slice(lag_slope);
        let annihilate = |v: &DVector<f64>| v - a * (&g * v);
        let n_att = attitude_rows(problem);
        let cp_rows = n_att..(n_att + 2 * problem.fixes.len()).min(m);
        let mb = annihilate(&b);
        let mut b_cp = DVector::zeros(m);
        for i in cp_rows.clone() {
            b_cp[i] = mb[i];
        }
        let den = b_cp.norm_squared();
        if den <= 0.0 || !den.is_finite() {
            return None;
        }
        let c = annihilate(&b_cp) / den;
        // F: the settings' rows −G (I − b cᵀ), then the lag's −cᵀ.
        let gb = &g * &b;
        let mut f = DMatrix::zeros(p + 1, m);
        for i in 0..p {
            for j in 0..m {
                f[(i, j)] = -g[(i, j)] + gb[i] * c[j];
            }
        }
        for j in 0..m {
            f[(p, j)] = -c[j];
        }
        let s2 = self.cost / self.dof;
        let mut cov = DMatrix::zeros(p + 1, p + 1);
        for j in 0..m {
            let var = if j < n_att {
                s2 * self.inflation[j % 2]
            } else if cp_rows.contains(&j) {
                cp_s2.max(s2)
            } else {
                s2
            };
            let col = f.column(j);
            cov.ger(var, &col, &col, 1.0);
        }
        let mut walk_uptake = None;
        if let Some(walk) = problem.gyro_walk {
            let fit = WalkFit {
                lin: &self.lin,
                attitude_sigma_rad: self.weights.attitude_sigma_rad,
                cp_weights: &cp_weights(problem, None, &self.weights),
                azimuth_deg,
            };
            let (share, uptake) = walk_covariance_and_uptake(walk, problem, &fit, &f);
            cov += share;
            walk_uptake = uptake;
        }
        let mut sigma = X::default();
        for (k, &s) in self.free.iter().enumerate() {
            sigma.set(s, cov[(k, k)].max(0.0).sqrt());
        }
        let lag_sigma_s = cov[(p, p)].max(0.0).sqrt();
        lag_sigma_s.is_finite().then(|| LagMarginal {
            sigma,
            lag_sigma_s,
            covariance: cov.view((0, 0), (p, p)).into_owned(),
            lag_covariance: cov.view((0, p), (p, 1)).column(0).into_owned(),
            walk_uptake,
        })
    }
}

/// Gauss–Newton iterations of the joint fit before it stops.
const MAX_GAUSS_NEWTON: usize = 10;

/// Covariance `s²(AᵀA)⁻¹` of the free parameters of `model` (the fit's last
/// linearisation, which agreed with the exact pass at the solution, so its slopes hold
/// there), the first `n_att` rows (the attitude residuals, interleaved ΔΘ, ΔΦ) discounted
/// by `inflation` ([`attitude_inflation`] of the fit's residuals) for their correlation
/// from epoch to epoch.
pub(super) fn covariance_of(
    model: &JointModel,
    n_att: usize,
    inflation: [f64; 2],
    s2: f64,
) -> Option<DMatrix<f64>> {
    let mut a = model.a.clone();
    for i in 0..n_att.min(a.nrows()) {
        a.row_mut(i).unscale_mut(inflation[i % 2].sqrt());
    }
    (a.transpose() * &a).try_inverse().map(|c| c * s2)
}

/// The gyros' angle random walk's share of the covariance of `model`'s free settings
/// ([`super::gyro_walk`]), zero where the problem has no walk or the model no inverse,
/// and the fit's [`WalkUptake`] of the heading's walk (its step being `−G r`).
fn walk_share(
    problem: &Problem<'_>,
    model: &JointModel,
    lin: &Linearization,
    w: &DisuptParams,
    skip_cp: Option<usize>,
    azimuth_deg: f64,
) -> (DMatrix<f64>, Option<WalkUptake>) {
    let n = model.a.ncols();
    let walk = problem.gyro_walk.filter(|walk| walk.q_rad2_s().is_some());
    let step = walk
        .filter(|_| n > 0 && model.a.nrows() > 0)
        .and_then(|_| least_squares_map(&model.a));
    let (Some(walk), Some(g)) = (walk, step) else {
        return (DMatrix::zeros(n, n), None);
    };
    let fit = WalkFit {
        lin,
        attitude_sigma_rad: w.attitude_sigma_rad,
        cp_weights: &cp_weights(problem, skip_cp, w),
        azimuth_deg,
    };
    walk_covariance_and_uptake(walk, problem, &fit, &(-g))
}

/// How [`joint_fit`] weighs and what it leaves out.
#[derive(Debug, Clone, Copy, Default)]
pub struct JointOptions<'w> {
    /// Weigh the epochs with this σ (rad) instead of their residuals' RMS (variance
    /// components), so that the costs of several fits compare (the odometer-lag search).
    pub attitude_sigma_rad: Option<f64>,
    /// Leave this control point (index into the problem's fixes) out of the fit, with
    /// its point's other visits ([`Problem::held_out`]).
    pub skip_cp: Option<usize>,
    /// Start at this linearisation's point with its slopes, from a nearby problem (the
    /// odometer-lag search's previous trial): one exact pass there instead of the shared
    /// first linearisation. The slopes are a model like any other: where the exact passes
    /// disagree with it, the fit relinearises.
    pub warm: Option<&'w Linearization>,
}

/// A joint fit with what its callers need beyond the result: its cost, the weights and
/// the covariance of the free parameters, and the linearisation that holds at the
/// solution (for cheap refits).
#[derive(Debug, Clone)]
pub struct JointFit {
    /// The method's result (settings, σ, table row).
    pub result: MethodResult,
    /// The exact observation at the solution.
    pub y: Observation,
    /// Weighted sum of squared residuals at the solution.
    pub cost: f64,
    /// The control points' part of it.
    pub cp_cost: f64,
    /// Residuals less free parameters.
    pub dof: f64,
    /// σ the epochs were weighed with, rad.
    pub attitude_sigma_rad: f64,
    /// The estimated settings.
    pub free: Vec<Setting>,
    /// Their covariance, in the optimisers' units (rows and columns follow `free`).
    pub covariance: Option<DMatrix<f64>>,
    /// How the settings take up the gyros' heading walk (rows follow `free`, then the
    /// odometer lag's where [`Self::lag_covariance`] is known), for the corrected route's
    /// σ; `None` without a walk or a covariance.
    pub walk_uptake: Option<WalkUptake>,
    /// Each setting's covariance with the odometer lag, where the lag's search gave it
    /// ([`JointFit::lag_marginal`]).
    pub lag_covariance: Option<DVector<f64>>,
    /// The attitude residuals' variance inflation (ΔΘ, ΔΦ) the covariance took.
    pub(super) inflation: [f64; 2],
    pub(super) lin: Linearization,
    pub(super) weights: DisuptParams,
}

/// The joint estimator; a fit that leaves its bounds is refused ([`within_bounds`]).
pub fn joint(problem: &Problem<'_>, p: &DisuptParams) -> Result<MethodResult, DisuptError> {
    let fit = joint_fit(problem, p, &JointOptions::default())?;
    within_bounds(&fit, &problem.x0(), p)?;
    Ok(fit.result)
}

/// Refuses `fit` when it moved a setting from `start` beyond its bound
/// ([`DisuptParams::bound`]): the least squares follow control points that no
/// physical setting reaches (coordinates from another survey, a mark with the wrong point
/// id, an odometer scale wrong by half) to any value, and the corrected route would be
/// the fit's artefact, not an estimate.
pub fn within_bounds(fit: &JointFit, start: &X, p: &DisuptParams) -> Result<(), DisuptError> {
    let out = p.joint_out_of_bounds(start, &fit.result.x, &fit.free);
    if out.is_empty() {
        return Ok(());
    }
    let said: Vec<String> = out
        .iter()
        .map(|&(s, moved)| {
            let (name, unit) = s.name_and_unit();
            let given = match s {
                Setting::DriftX | Setting::DriftY | Setting::DriftZ => {
                    drift_given_off(start.get(s), fit.result.x.get(s), p.bound(s))
                }
                _ => None,
            };
            format!(
                "{name} moved {moved:+.1} {unit}, bound ±{} {unit}{}",
                p.bound(s),
                given.unwrap_or_default()
            )
        })
        .collect();
    Err(DisuptError::OutOfBounds(said.join("; ")))
}

/// What a drift that moved beyond its bound says when the drift it started from, °/h, was
/// itself beyond the bound and the fit brings it within the bound of zero: the drift
/// given (`[initial] drift_rad_s`) is off, not the run. `None` otherwise.
fn drift_given_off(start_deg_h: f64, fitted_deg_h: f64, bound_deg_h: f64) -> Option<String> {
    (start_deg_h.abs() > bound_deg_h && fitted_deg_h.abs() <= bound_deg_h).then(|| {
        format!(
            ", from {start_deg_h:+.1} °/h given to {fitted_deg_h:+.1}: the drift given \
             ([initial] drift_rad_s, in rad/s) is off, not the run"
        )
    })
}

/// The joint estimator, with options; see [`joint`].
pub fn joint_fit(
    problem: &Problem<'_>,
    p: &DisuptParams,
    opts: &JointOptions,
) -> Result<JointFit, DisuptError> {
    let t0 = Instant::now();
    let tally = AtomicUsize::new(0);
    let x0 = problem.x0();
    let skip = opts.skip_cp;
    let used_cps = (0..problem.fixes.len())
        .filter(|&i| problem.cp_used(i) && !problem.held_out(skip, i))
        .count();
    // The attitude's settings always; the odometer's when control points see them.
    let mut free: Vec<Setting> = Setting::ALL
        .into_iter()
        .filter(|s| !s.needs_control_points())
        .collect();
    if used_cps > 0 {
        for (on, s) in [
            (p.joint_odo_scale, Setting::OdoScale),
            (p.joint_odo_yaw, Setting::OdoYaw),
            (p.joint_odo_bias == Some(true), Setting::OdoBias),
        ] {
            if on {
                free.push(s);
            }
        }
    }
    if p.joint_mark_arm == Some(true) && used_cps >= MARK_ARM_MIN_POINTS {
        free.extend([Setting::MarkForward, Setting::MarkRight]);
    }
    let free = &free[..];
    let warm;
    let start = match opts.warm {
        Some(w) => {
            let y = problem.observe_by(&x_of(&w.p_ref), &tally);
            warm = Linearization {
                p_ref: w.p_ref,
                y_ref: y,
                slopes: w.slopes.clone(),
            };
            &warm
        }
        None => problem.base_linearization(),
    };
    let mut owned;
    let mut lin = start;
    if !start.covers(free) {
        owned = problem.completed(start, free, &tally);
        lin = &owned;
    }
    let mut pr = lin.p_ref;
    let mut y = lin.y_ref.clone();
    // The epochs are weighted by the σ their residuals show (variance components: the
    // misfit the filter leaves is several mrad, more than the configured floor), so that
    // the control points get their due weight. The first round takes it at the start; a
    // second round follows if the solution's residuals say otherwise by more than 50 %.
    let mut w = *p;
    w.attitude_sigma_rad = match opts.attitude_sigma_rad {
        Some(s) => s,
        None => attitude_rms_rad(problem, &y, &pr, p).max(p.attitude_sigma_rad),
    };
    let mut cost = ssr(&joint_residuals(problem, &y, &pr, &w, skip));
    let mut model = JointModel::new(problem, lin, free, &w, skip);
    let rounds = if opts.attitude_sigma_rad.is_some() {
        1
    } else {
        2
    };
    for round in 0..rounds {
        for _ in 0..MAX_GAUSS_NEWTON {
            // The exact pass at the model's optimum; halve the step while it does worse.
            let mut step = model.solve()?;
            let (mut p_new, mut y_new, mut cost_new);
            let mut halvings = 0;
            loop {
                p_new = pr;
                for (k, s) in free.iter().enumerate() {
                    p_new[s.index()] += step[k];
                }
                y_new = problem.observe_by(&x_of(&p_new), &tally);
                cost_new = ssr(&joint_residuals(problem, &y_new, &p_new, &w, skip));
                if cost_new <= cost || halvings == 5 {
                    break;
                }
                step /= 2.0;
                halvings += 1;
            }
            let agrees = halvings == 0 && lin.predict(&p_new).agrees_with(&y_new);
            (pr, y, cost) = (p_new, y_new, cost_new);
            if agrees {
                break;
            }
            owned = problem.linearize_by(&x_of(&pr), y.clone(), free, &tally);
            lin = &owned;
            model = JointModel::new(problem, lin, free, &w, skip);
        }
        if round == 0 && rounds == 2 {
            let rms = attitude_rms_rad(problem, &y, &pr, &w).max(p.attitude_sigma_rad);
            if (rms / w.attitude_sigma_rad - 1.0).abs() <= 0.5 {
                break;
            }
            w.attitude_sigma_rad = rms;
            cost = ssr(&joint_residuals(problem, &y, &pr, &w, skip));
            // The linearisation still holds at `pr` (it agreed there): only the weights
            // change.
            model = JointModel::new(problem, lin, free, &w, skip);
        }
    }
    let x = x_of(&pr);
    // The rows of control points left out are zero: not residuals.
    let rows = model
        .r0
        .len()
        .saturating_sub(2 * (problem.fixes.len() - used_cps) + nuisance_rows(problem));
    let dof = (rows as f64 - free.len() as f64).max(1.0);
    let r = joint_residuals(problem, &y, &pr, &w, skip);
    let n_att = attitude_rows(problem);
    let inflation = attitude_inflation(&r[..n_att.min(r.len())]);
    let (covariance, walk_uptake) = match covariance_of(&model, n_att, inflation, cost / dof) {
        Some(c) => {
            let (share, uptake) = walk_share(problem, &model, lin, &w, skip, x.azimuth_deg);
            (Some(c + share), uptake)
        }
        None => (None, None),
    };
    // 1σ of each estimated setting (0 for the others).
    let sigma = covariance.as_ref().map(|c| {
        let mut sd = X::default();
        for (k, &s) in free.iter().enumerate() {
            sd.set(s, c[(k, k)].max(0.0).sqrt());
        }
        sd
    });
    let (dx_m, dy_m) = last_cp(&y);
    let evaluations = tally.load(Ordering::Relaxed);
    let step = Step {
        step: 1,
        component: Component::All,
        criterion: Criterion::LeastSquares,
        input: x0,
        output: x,
        dx_m,
        dy_m,
        evaluations,
        at_bound: Vec::new(),
    };
    let result = MethodResult {
        x,
        sigma,
        dx_m,
        dy_m,
        kryt1: problem.kryt1(&y),
        steps: vec![step],
        evaluations,
        wall_s: t0.elapsed().as_secs_f64(),
    };
    let cp_cost = ssr(&r[n_att.min(r.len())..n_att + 2 * y.cp_m.len()]);
    Ok(JointFit {
        result,
        y,
        cost,
        cp_cost,
        dof,
        attitude_sigma_rad: w.attitude_sigma_rad,
        free: free.to_vec(),
        covariance,
        walk_uptake,
        lag_covariance: None,
        inflation,
        lin: lin.clone(),
        weights: w,
    })
}

impl JointFit {
    /// The linearisation that holds at the solution.
    pub fn linearization(&self) -> &Linearization {
        &self.lin
    }

    /// The odometer yaw boresight this fit held at zero, as its residuals show it: the
    /// fit's model at its last linearisation with the boresight free too (one pass for
    /// the boresight's slope, counted in `tally`), solved once, with its 1σ from that
    /// model's covariance (the fit's weights and inflation). `None` when the fit had the
    /// boresight free already or no control point (which the boresight needs).
    ///
    /// The boresight turns the route as the azimuth does, so the control points see only
    /// their sum and the fit's azimuth takes it whole; the pitch and roll tell them apart
    /// (a wrong azimuth misapplies the Earth's rate, a boresight moves the accelerometer
    /// references along the odometer).
    pub fn odo_yaw_seen(
        &self,
        problem: &Problem<'_>,
        tally: &AtomicUsize,
    ) -> Result<Option<OdoYawSeen>, DisuptError> {
        if self.free.contains(&Setting::OdoYaw)
            || self.lin.y_ref.cp_m.is_empty()
            || problem.cps_used() == 0
        {
            return Ok(None);
        }
        let Some(s) = self.solved_with(problem, &[Setting::OdoYaw], tally)? else {
            return Ok(None);
        };
        Ok(Some(OdoYawSeen {
            odo_yaw_deg: s.value(0),
            sigma_deg: s.covariance[(s.k, s.k)].max(0.0).sqrt(),
        }))
    }

    /// The fit's model at its last linearisation with `extra` settings free too (their
    /// slopes added to it, the passes counted in `tally`), solved once, with the
    /// covariance of that model (the fit's weights and inflation).
    fn solved_with(
        &self,
        problem: &Problem<'_>,
        extra: &[Setting],
        tally: &AtomicUsize,
    ) -> Result<Option<SolvedWith>, DisuptError> {
        let mut free = self.free.clone();
        free.extend_from_slice(extra);
        let lin = problem.completed(&self.lin, &free, tally);
        let model = JointModel::new(problem, &lin, &free, &self.weights, None);
        let delta = model.solve()?;
        let r = &model.r0 + &model.a * &delta;
        let dof = (r.len() as f64 - (free.len() + nuisance_rows(problem)) as f64).max(1.0);
        let n_att = attitude_rows(problem);
        let covariance =
            covariance_of(&model, n_att, self.inflation, ssr(r.as_slice()) / dof).map(|c| {
                let step = free.iter().position(|s| *s == Setting::Azimuth);
                let azimuth_deg =
                    lin.p_ref[Setting::Azimuth.index()] + step.map_or(0.0, |k| delta[k]);
                c + walk_share(problem, &model, &lin, &self.weights, None, azimuth_deg).0
            });
        Ok(covariance.map(|covariance| SolvedWith {
            k: self.free.len(),
            at: extra.iter().map(|s| lin.p_ref[s.index()]).collect(),
            delta,
            covariance,
        }))
    }
}

/// [`JointFit::solved_with`]'s solution: the extra settings are its last columns, from
/// `k` on.
struct SolvedWith {
    /// The first extra setting's column.
    k: usize,
    /// The extra settings' values at the linearisation's point.
    at: Vec<f64>,
    /// The step from that point, every free setting.
    delta: DVector<f64>,
    /// Its covariance.
    covariance: DMatrix<f64>,
}

impl SolvedWith {
    /// The `i`-th extra setting's solved value.
    fn value(&self, i: usize) -> f64 {
        self.at[i] + self.delta[self.k + i]
    }
}

impl JointFit {
    /// The mark's horizontal lever arm the control points' errors show, beyond the one the
    /// fixes already have: the fit's model at its last linearisation with the arm's two
    /// components (body x forward, y right) free too, solved once, with their covariance
    /// (the fit's weights and inflation). No pass: the arm moves each point by the
    /// attitude at its stop, which the linearisation's exact pass kept. `None` with fewer
    /// than [`MARK_ARM_MIN_POINTS`] points in the fit, a fit that had the mark free, or a
    /// model that cannot be solved.
    ///
    /// An arm moves every point along the vehicle's heading at its stop, where the
    /// settings move them along the route (the azimuth turns it about the start, the scale
    /// stretches it, the drifts bend it): points stopped at several headings tell them
    /// apart.
    pub fn mark_arm_seen(&self, problem: &Problem<'_>) -> Result<Option<MarkArmSeen>, DisuptError> {
        let y = &self.lin.y_ref;
        if self.free.contains(&Setting::MarkForward)
            || problem.cps_used() < MARK_ARM_MIN_POINTS
            || y.cp_arm_ne.len() != y.cp_m.len()
        {
            return Ok(None);
        }
        // The mark's slopes take no pass.
        let no_pass = AtomicUsize::new(0);
        let extra = [Setting::MarkForward, Setting::MarkRight];
        let Some(s) = self.solved_with(problem, &extra, &no_pass)? else {
            return Ok(None);
        };
        let c = |a: usize, b: usize| s.covariance[(s.k + a, s.k + b)];
        Ok(MarkArmSeen::of(
            [s.value(0), s.value(1)],
            [[c(0, 0), c(0, 1)], [c(1, 0), c(1, 1)]],
        ))
    }

    /// The mark's move this fit estimated (when it had the mark free), with its
    /// covariance.
    pub fn mark_arm_estimate(&self) -> Option<MarkArmSeen> {
        let at = |s: Setting| self.free.iter().position(|&f| f == s);
        let (i, j) = (at(Setting::MarkForward)?, at(Setting::MarkRight)?);
        let c = self.covariance.as_ref()?;
        MarkArmSeen::of(
            self.result.x.mark_arm_m,
            [[c[(i, i)], c[(i, j)]], [c[(j, i)], c[(j, j)]]],
        )
    }
}

impl MarkArmSeen {
    /// An arm and its 2 × 2 covariance; `None` unless both are finite and the covariance
    /// is positive definite.
    fn of(arm: [f64; 2], cov: [[f64; 2]; 2]) -> Option<Self> {
        let det = cov[0][0] * cov[1][1] - cov[0][1] * cov[1][0];
        if !(det > 0.0 && cov[0][0] > 0.0 && arm.iter().all(|v| v.is_finite())) {
            return None;
        }
        // Mahalanobis distance from no arm: aᵀ C⁻¹ a.
        let d2 = (cov[1][1] * arm[0] * arm[0] - 2.0 * cov[0][1] * arm[0] * arm[1]
            + cov[0][0] * arm[1] * arm[1])
            / det;
        Some(Self {
            forward_m: arm[0],
            right_m: arm[1],
            sigma_forward_m: cov[0][0].sqrt(),
            sigma_right_m: cov[1][1].sqrt(),
            correlation: cov[0][1] / (cov[0][0] * cov[1][1]).sqrt(),
            distance_sigma: d2.max(0.0).sqrt(),
        })
    }
}

/// Points the fit must weigh for [`JointFit::mark_arm_seen`]: the arm's two components
/// beside the settings need points at several headings.
pub const MARK_ARM_MIN_POINTS: usize = 3;

/// The mark's horizontal lever arm a joint fit's control points show
/// ([`JointFit::mark_arm_seen`]), beyond the fixes' own, body axes.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MarkArmSeen {
    /// Along the body's x (forward), m.
    pub forward_m: f64,
    /// Along the body's y (right), m.
    pub right_m: f64,
    /// 1σ of `forward_m`, m.
    pub sigma_forward_m: f64,
    /// 1σ of `right_m`, m.
    pub sigma_right_m: f64,
    /// Correlation of the two.
    pub correlation: f64,
    /// Its distance from no arm in its own covariance (Mahalanobis), in σ.
    pub distance_sigma: f64,
}

/// An odometer yaw boresight a joint fit's residuals show ([`JointFit::odo_yaw_seen`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OdoYawSeen {
    /// The boresight, degrees.
    pub odo_yaw_deg: f64,
    /// Its 1σ, degrees.
    pub sigma_deg: f64,
}

impl OdoYawSeen {
    /// How many σ from zero.
    pub fn z(&self) -> f64 {
        self.odo_yaw_deg.abs() / self.sigma_deg
    }
}

#[cfg(test)]
mod tests {
    use super::{JointModel, drift_given_off};
    use nalgebra::{DMatrix, DVector};

    /// A tall model of `rows` × 4 whose columns differ by orders of magnitude (as the
    /// settings' slopes do: rad, rad/s, m), its residuals `−A x + e`.
    fn model(rows: usize) -> (JointModel, DVector<f64>) {
        let scales = [1.0, 3.0e4, 2.0e-3, 50.0];
        let mut seed = 0x9E37_79B9_7F4A_7C15_u64;
        let mut uniform = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let a = DMatrix::from_fn(rows, 4, |_, j| uniform() * scales[j]);
        let x = DVector::from_vec(vec![0.3, -2.0e-5, 40.0, 1.0e-2]);
        let e = DVector::from_fn(rows, |_, _| 0.01 * uniform());
        let r0 = -(&a * &x) + e;
        (JointModel { r0, a }, x)
    }

    #[test]
    fn the_step_is_the_linear_models_least_squares_optimum() {
        let (m, x) = model(500);
        let step = m.solve().unwrap();
        // The normal equations hold at the step: Aᵀ r = 0, to the rounding of A's norms.
        let r = &m.r0 + &m.a * &step;
        for (j, col) in m.a.column_iter().enumerate() {
            let g = col.dot(&r) / (col.norm() * r.norm());
            assert!(g.abs() < 1e-12, "column {j}: {g:e}");
        }
        // And the step is their solution (well conditioned once the columns are scaled),
        // near the settings the residuals were made from (the noise moves it a little).
        let norms: Vec<f64> = m.a.column_iter().map(|c| c.norm()).collect();
        let scaled = DMatrix::from_fn(m.a.nrows(), 4, |i, j| m.a[(i, j)] / norms[j]);
        let normal = (scaled.transpose() * &scaled).cholesky().unwrap();
        let want = normal.solve(&(scaled.transpose() * -&m.r0));
        for j in 0..4 {
            let want_j = want[j] / norms[j];
            assert!(
                (step[j] - want_j).abs() <= 1e-9 * want_j.abs(),
                "{j}: {} against {want_j}",
                step[j]
            );
            assert!((step[j] - x[j]).abs() <= 1e-2 * x[j].abs(), "{j}");
        }
    }

    #[test]
    fn a_setting_the_residuals_do_not_see_is_left_where_it_is() {
        // A setting without a slope has a column of zeros: its step is 0, and the others'
        // are the model's without it.
        let (m, _) = model(300);
        let mut blind = m.a.clone();
        blind.column_mut(2).fill(0.0);
        let with_zero = JointModel {
            r0: m.r0.clone(),
            a: blind.clone(),
        }
        .solve()
        .unwrap();
        let without = JointModel {
            r0: m.r0.clone(),
            a: blind.remove_column(2),
        }
        .solve()
        .unwrap();
        assert_eq!(with_zero[2], 0.0);
        for (k, j) in [0, 1, 3].into_iter().enumerate() {
            assert!(
                (with_zero[j] - without[k]).abs() <= 1e-12 * without[k].abs(),
                "{j}: {} against {}",
                with_zero[j],
                without[k]
            );
        }
    }

    #[test]
    fn a_residual_that_is_not_a_number_is_an_error_not_a_step() {
        let (mut m, _) = model(50);
        m.r0[7] = f64::NAN;
        let err = m.solve().unwrap_err().to_string();
        assert!(err.contains("not a finite number"), "{err}");
    }

    #[test]
    fn fewer_residuals_than_settings_take_the_least_step() {
        // One residual, two settings: of the steps that zero it, the least, each setting's
        // measured by how far it moves the residual: both move it alike (2.5 each).
        let m = JointModel {
            r0: DVector::from_vec(vec![-5.0]),
            a: DMatrix::from_row_slice(1, 2, &[3.0, 4.0]),
        };
        let step = m.solve().unwrap();
        assert!((3.0 * step[0] - 2.5).abs() < 1e-14, "{step}");
        assert!((4.0 * step[1] - 2.5).abs() < 1e-14, "{step}");
    }

    #[test]
    fn a_drift_given_beyond_its_bound_and_fitted_near_zero_is_blamed() {
        // Kingston with drift x given as 0.001 rad/s (206.3 °/h): fitted to +0.1.
        assert_eq!(
            drift_given_off(206.3, 0.1, 5.0).unwrap(),
            ", from +206.3 °/h given to +0.1: the drift given ([initial] drift_rad_s, in \
             rad/s) is off, not the run"
        );
        // A drift given within its bound, or fitted beyond it from zero: not the drift
        // given's fault.
        assert_eq!(drift_given_off(3.0, -9.0, 5.0), None);
        assert_eq!(drift_given_off(206.3, 40.0, 5.0), None);
    }
}
