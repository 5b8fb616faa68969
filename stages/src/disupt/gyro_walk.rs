//! The gyros' angle random walk in the joint fit's covariance.
//!
//! The joint fit's residuals are not independent: the gyros' white noise (angle random
//! walk, density `N` rad/√s) turns the dead reckoning by a random walk that every later
//! epoch and control point carries. The fit absorbs much of it into the drifts and the
//! azimuth (a walk's best straight line over a run of `T` has a slope of σ `N √(6/5T)`,
//! 0.09 °/h for an LN-200 over 40 minutes), so its residuals show only what is left:
//! their scatter and the Newey–West inflation ([`super::joint`]) miss it. Measured on five
//! simulated 40-minute runs, the drifts were 0.1–0.3 °/h off where their σ said 0.03–0.25,
//! and the azimuth 0.15–0.36° off at σ 0.02–0.07°: the heading's walk moves the control
//! points metres (0.06° over 14 km is 15 m) where the fit weighs them to 1 m.
//!
//! The walk's share of the estimate's covariance is `G Σ Gᵀ`, `G = (AᵀA)⁻¹Aᵀ` the fit's
//! least-squares map from its weighted residuals to the settings and `Σ` the walk's
//! covariance of those residuals, in two independent parts (to first order a level
//! vehicle's tilt does not move its route, nor its heading its tilt):
//! - **Tilt.** A kick `ε` of the nav frame's level at epoch `j` shows in the gyro pitch and
//!   roll there as an isotropic pair and later as `M_k M_j⁻¹` of it, `M_k` the epoch's
//!   response to the start's pitch and roll (the fit's levelling slopes, turns and the
//!   Earth's rate in them). With `S_j = Σ_{k≥j} G_k M_k M_j⁻¹` (`G_k` the two columns of
//!   epoch `k`'s rows), the share is `N² Σ_j Δt_j S_j S_jᵀ`.
//! - **Heading.** A kick `δ` at epoch `j` turns every later displacement: a control point
//!   `c` after it moves by `δ J (p_c − p_j)` (`J` a quarter turn), `p` the positions of a
//!   pass at the fit's start turned by the azimuth the fit moved. With
//!   `v_j = Σ_{c after j} G_c w_c J (p_c − p_j)` the share is `N² Σ_j Δt_j v_j v_jᵀ`.
//!
//! Both are suffix sums over the epochs: linear in the run's length.
//!
//! The same heading walk turns the corrected route, and the fit takes part of it up
//! through the control points: [`WalkUptake`] carries, for a kick at any moment, the
//! settings' step it causes, so that the route's σ ([`crate::route_sigma`]) can weigh
//! the walk's turn of the route against the fit's answer to it.

use std::sync::OnceLock;

use nalgebra::{DMatrix, DVector, Matrix2};

use super::problem::Problem;
use crate::linearized::{Linearization, Setting};
use crate::strapdown::{self, NavInputs, PassSink};

/// The gyros' angle random walk a problem's joint fits take into their covariance, and
/// the route it turns (computed on first use, shared by the problems of one run: the lag
/// search's re-derives move the route by less than the walk's σ notices).
#[derive(Debug)]
pub struct GyroWalk {
    arw_rad_sqrt_s: f64,
    route: OnceLock<Option<WalkRoute>>,
}

/// The positions the heading's walk turns: a pass at a problem's start.
#[derive(Debug, Clone)]
struct WalkRoute {
    /// The heading the pass started with, rad.
    heading0_rad: f64,
    /// Time from the first sample of each epoch's middle sample, s, and its north and
    /// east from the start, m (every epoch).
    epochs: Vec<(f64, [f64; 2])>,
    /// Likewise of each control point's sample.
    fixes: Vec<(f64, [f64; 2])>,
}

impl GyroWalk {
    /// The walk of gyros whose angle random walk is `arw_rad_sqrt_s`.
    pub fn new(arw_rad_sqrt_s: f64) -> Self {
        Self {
            arw_rad_sqrt_s,
            route: OnceLock::new(),
        }
    }

    /// The walk's variance per second, rad²/s, where it has one to add (a positive,
    /// finite density).
    pub(super) fn q_rad2_s(&self) -> Option<f64> {
        let q = self.arw_rad_sqrt_s * self.arw_rad_sqrt_s;
        (q > 0.0 && q.is_finite()).then_some(q)
    }

    /// The route of `problem`'s start (one pass the first time; `None` where the problem
    /// has no stored odometer to run it on).
    fn route(&self, problem: &Problem<'_>) -> Option<&WalkRoute> {
        self.route.get_or_init(|| WalkRoute::of(problem)).as_ref()
    }
}

/// Samples summed into one step of the route's pass: 0.1 s at 100 Hz. The walk's share
/// reads the route's positions as lever arms, where metres do not matter; summed, the
/// pass costs a tenth (0.85 ms over a 40-minute run, against 7.3 ms sample by sample;
/// the z of seeds 51–55's settings the same to 0.01).
const ROUTE_STEP_SAMPLES: usize = 10;

impl WalkRoute {
    fn of(problem: &Problem<'_>) -> Option<Self> {
        let inputs = &problem.inputs;
        let n = inputs.pass_samples();
        if n == 0 || n < inputs.len() {
            return None;
        }
        // The route's pass on increments summed over steps of ROUTE_STEP_SAMPLES (the
        // attitude's non-commutativity over 0.1 s, and the distance put at the step's end
        // attitude, move a land vehicle's route by centimetres a turn).
        let steps = n.div_ceil(ROUTE_STEP_SAMPLES);
        let (mut dt_s, mut dtheta_rad, mut odo_m) = (
            Vec::with_capacity(steps),
            Vec::with_capacity(steps),
            Vec::with_capacity(steps),
        );
        for first in (0..n).step_by(ROUTE_STEP_SAMPLES) {
            let (mut dt, mut th, mut d) = (0.0, [0.0; 3], 0.0);
            for k in first..(first + ROUTE_STEP_SAMPLES).min(n) {
                dt += inputs.dt_s[k];
                let a = inputs.dtheta_rad.get(k);
                (0..3).for_each(|i| th[i] += a[i]);
                d += inputs.odo_dist_m[k];
            }
            dt_s.push(dt);
            dtheta_rad.push(th);
            odo_m.push(d);
        }
        let summed = NavInputs {
            dt_s: &dt_s,
            dtheta_rad: (&dtheta_rad).into(),
            odo_dist_m: &odo_m,
        };
        let block = problem.lp.block.max(1);
        // Each wanted sample as the step it ends in.
        let step_of = |k: usize| k.min(n - 1) / ROUTE_STEP_SAMPLES;
        let mut wanted: Vec<(usize, usize)> = (problem.epochs.block.iter())
            .enumerate()
            .map(|(k, &b)| (step_of(b * block + block / 2), k))
            .collect();
        let n_epochs = wanted.len();
        wanted.extend(
            (problem.fixes.iter())
                .enumerate()
                .map(|(c, f)| (step_of(f.sample), n_epochs + c)),
        );
        wanted.sort_unstable();
        let settings = problem.settings(&problem.x0());
        let mut sink = AtSamples {
            frame: settings.start().local_frame(),
            dt_s: &dt_s,
            t_s: 0.0,
            wanted: &wanted,
            next: 0,
            out: vec![(0.0, [0.0; 2]); wanted.len()],
        };
        strapdown::run(&summed, &settings, &mut sink);
        let mut epochs = sink.out;
        let fixes = epochs.split_off(n_epochs);
        Some(Self {
            heading0_rad: settings.initial.heading_rad,
            epochs,
            fixes,
        })
    }
}

/// A pass's time and north, east at chosen samples.
struct AtSamples<'a> {
    frame: crate::earth::LocalFrame,
    dt_s: &'a [f64],
    t_s: f64,
    /// (sample, slot in `out`), by sample.
    wanted: &'a [(usize, usize)],
    next: usize,
    out: Vec<(f64, [f64; 2])>,
}

impl PassSink for AtSamples<'_> {
    fn sample(&mut self, k: usize, lat: f64, lon: f64, _h: f64, _q: &[f64; 4], _d: f64) {
        self.t_s += self.dt_s.get(k).copied().unwrap_or(0.0);
        while let Some(&(s, slot)) = self.wanted.get(self.next) {
            if s != k {
                break;
            }
            let (n, e) = self.frame.offset_m(lat, lon);
            self.out[slot] = (self.t_s, [n, e]);
            self.next += 1;
        }
    }
}

/// How a joint fit's settings take up the heading's walk: a kick `δ` of the heading at
/// time `t` moves each control point after it by `δ J (p_c − p)` (`J` a quarter turn, `p`
/// the route's position at `t`), and the fit's step by `δ u(t, p)` with
/// `u = Σ_{c: t_c ≥ t} F_c w_c J (p_c − p) = a_s − B_s J p`: `F_c` the two columns of the
/// fit's map from its weighted residuals to its step (`−G`, or the odometer-lag search's
/// map) at point `c`'s rows, `w_c` its weight, `p_c` its position on the walk's route.
/// `a_s` and `B_s` are constant between control points: one pair per stretch `s`.
///
/// The corrected route at time `T` is then off by `δ (J (p_T − p), 1)` (north, east,
/// heading) from the kick itself, plus `S_T δ u` through the settings (`S_T` its
/// sensitivities): the two nearly cancel where control points pin the route, and the
/// route's σ holds their covariance ([`crate::route_sigma::RouteSigma`]).
#[derive(Debug, Clone, PartialEq)]
pub struct WalkUptake {
    /// The walk's variance per second, rad²/s.
    pub q_rad2_s: f64,
    /// The settings' count: each stretch's `a_s` has this many rows, `B_s` as many.
    pub settings: usize,
    /// Time of each weighed control point, s from the first sample, increasing: a kick at
    /// `t` is in stretch `s`, the first whose bound is at or after `t` (`bounds_s.len()`
    /// past the last).
    pub bounds_s: Vec<f64>,
    /// Each stretch's `a_s` (the settings' units per radian of kick), then `B_s`'s north
    /// and east columns (per radian and metre): `3 × settings` values a stretch,
    /// `bounds_s.len() + 1` stretches.
    pub stretches: Vec<f64>,
    /// The heading walk's share of the settings' covariance as the fit took it
    /// (`q Σ_j Δt_j u_j u_jᵀ` over its epochs, on its walk's route), row by row: the part
    /// of the fit's covariance that the route's σ takes again with the route's own turn.
    pub heading_share: Vec<f64>,
}

impl WalkUptake {
    /// The stretch a kick at `t_s` is in.
    pub fn stretch_at(&self, t_s: f64) -> usize {
        self.bounds_s.partition_point(|&b| b < t_s)
    }

    /// The step per radian of a kick at `t_s` where the route is at `north_m`, `east_m`,
    /// into `u` (`settings` values).
    pub fn step_per_kick(&self, t_s: f64, north_m: f64, east_m: f64, u: &mut [f64]) {
        let p = self.settings;
        let s = self.stretch_at(t_s);
        let at = &self.stretches[3 * p * s..3 * p * (s + 1)];
        // J p = (−e, n): `a − B_n (−e) − B_e n`.
        for (i, u) in u.iter_mut().enumerate().take(p) {
            *u = at[i] - at[2 * p + i] * north_m + at[p + i] * east_m;
        }
    }

    /// The same uptake of the settings `rows` only (indices into this one's), in order.
    pub fn select(&self, rows: &[usize]) -> Self {
        let p = self.settings;
        let stretches = self
            .stretches
            .chunks_exact(3 * p)
            .flat_map(|at| (0..3).flat_map(move |part| rows.iter().map(move |&r| at[part * p + r])))
            .collect();
        let heading_share = rows
            .iter()
            .flat_map(|&r| rows.iter().map(move |&c| self.heading_share[r * p + c]))
            .collect();
        Self {
            q_rad2_s: self.q_rad2_s,
            settings: rows.len(),
            bounds_s: self.bounds_s.clone(),
            stretches,
            heading_share,
        }
    }
}

/// The heading walk's [`WalkUptake`] by a fit whose step is `f_step` times its weighted
/// residuals (rows: the settings; columns: [`super::joint`]'s residuals), on the walk's
/// `route`, with `q` its variance per second. Its heading share is also added to `cov`
/// (the heading's walk, see the module documentation).
fn uptake_of(
    problem: &Problem<'_>,
    fit: &WalkFit<'_>,
    route: &WalkRoute,
    f_step: &DMatrix<f64>,
    q: f64,
    cov: &mut DMatrix<f64>,
) -> WalkUptake {
    let (n_att, cps) = weighed_points(problem, fit, route, f_step.ncols());
    let p = f_step.nrows();
    let turned = turned_by(fit.azimuth_deg, route);
    // From the last stretch (no point after it) back to the first (every point).
    let mut stretches = vec![0.0; 3 * p * (cps.len() + 1)];
    let mut sum = vec![0.0; 3 * p];
    for (s, &c) in cps.iter().enumerate().rev() {
        let w = fit.cp_weights[c];
        let pc = turned(route.fixes[c].1);
        let (f_n, f_e) = (
            f_step.column(n_att + 2 * c),
            f_step.column(n_att + 2 * c + 1),
        );
        for i in 0..p {
            // F_c w J p_c, J p_c = (−e, n); B's north column F_n w, east F_e w.
            sum[i] += w * (-f_n[i] * pc[1] + f_e[i] * pc[0]);
            sum[p + i] += w * f_n[i];
            sum[2 * p + i] += w * f_e[i];
        }
        stretches[3 * p * s..3 * p * (s + 1)].copy_from_slice(&sum);
    }
    let mut uptake = WalkUptake {
        q_rad2_s: q,
        settings: p,
        bounds_s: cps.iter().map(|&c| route.fixes[c].0).collect(),
        stretches,
        heading_share: Vec::new(),
    };
    // `q Σ_j Δt_j u_j u_jᵀ` over the epochs a point follows (the last stretch's `u` is 0).
    let mut share = DMatrix::zeros(p, p);
    let mut u = DVector::<f64>::zeros(p);
    let last = uptake.bounds_s.last().copied().unwrap_or(f64::NEG_INFINITY);
    for j in (0..route.epochs.len()).rev() {
        let (t_j, ne_j) = route.epochs[j];
        if t_j > last {
            continue;
        }
        let before = if j > 0 { route.epochs[j - 1].0 } else { 0.0 };
        let dt = (t_j - before).max(0.0);
        let pj = turned(ne_j);
        uptake.step_per_kick(t_j, pj[0], pj[1], u.as_mut_slice());
        share.ger(q * dt, &u, &u, 1.0);
        cov.ger(q * dt, &u, &u, 1.0);
    }
    uptake.heading_share = share.transpose().as_slice().to_vec();
    uptake
}

/// The attitude rows' count of `problem`, and the control points `fit` weighs whose rows
/// are among a map's `cols` columns, earliest first (ties in their order).
fn weighed_points(
    problem: &Problem<'_>,
    fit: &WalkFit<'_>,
    route: &WalkRoute,
    cols: usize,
) -> (usize, Vec<usize>) {
    let n_att = 2 * problem.epochs.valid.iter().filter(|v| **v).count();
    let mut cps: Vec<usize> = (0..route.fixes.len())
        .filter(|&c| fit.cp_weights.get(c).is_some_and(|w| *w > 0.0) && n_att + 2 * c + 1 < cols)
        .collect();
    cps.sort_by(|&a, &b| route.fixes[a].0.total_cmp(&route.fixes[b].0));
    (n_att, cps)
}

/// The walk route's (north, east) turned by the fit's azimuth from the route's start.
fn turned_by(azimuth_deg: f64, route: &WalkRoute) -> impl Fn([f64; 2]) -> [f64; 2] {
    let turn = (azimuth_deg.to_radians() - route.heading0_rad).sin_cos();
    move |ne: [f64; 2]| {
        [
            ne[0] * turn.1 - ne[1] * turn.0,
            ne[0] * turn.0 + ne[1] * turn.1,
        ]
    }
}

/// What the walk's share of a joint fit's covariance reads of the fit.
pub(super) struct WalkFit<'a> {
    /// The linearisation the model was built on (its levelling slopes).
    pub lin: &'a Linearization,
    /// σ the epochs were weighed with, rad.
    pub attitude_sigma_rad: f64,
    /// Each control point's weight, 1/m (0 for one left out).
    pub cp_weights: &'a [f64],
    /// The fit's azimuth, degrees.
    pub azimuth_deg: f64,
}

/// `G = (AᵀA)⁻¹Aᵀ`, the least-squares map from the residuals of a model of slopes `a`
/// to its step (one column per residual row); `None` where `AᵀA` is singular.
pub(super) fn least_squares_map(a: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    Some(a.tr_mul(a).try_inverse()? * a.transpose())
}

/// The angle random walk's covariance of the estimates `F r` that the rows of `f` make of
/// the fit's weighted residuals `r` (`F Σ Fᵀ`, `Σ` the walk's covariance of `r`; see the
/// module documentation): the fit's own with `F` its step's map, and the odometer-lag
/// search's, whose lag and settings are other functions of the same residuals.
pub(super) fn walk_covariance_of(
    walk: &GyroWalk,
    problem: &Problem<'_>,
    fit: &WalkFit<'_>,
    f: &DMatrix<f64>,
) -> DMatrix<f64> {
    walk_covariance_and_uptake(walk, problem, fit, f).0
}

/// [`walk_covariance_of`], and the heading walk's [`WalkUptake`] by the estimates when
/// `f` is the fit's step's map (`None` without a walk or its route).
pub(super) fn walk_covariance_and_uptake(
    walk: &GyroWalk,
    problem: &Problem<'_>,
    fit: &WalkFit<'_>,
    f: &DMatrix<f64>,
) -> (DMatrix<f64>, Option<WalkUptake>) {
    let k = f.nrows();
    let mut cov = DMatrix::zeros(k, k);
    let Some(q) = walk.q_rad2_s() else {
        return (cov, None);
    };
    tilt_share(problem, fit, f, q, &mut cov);
    let uptake = (walk.route(problem)).map(|route| uptake_of(problem, fit, route, f, q, &mut cov));
    (cov, uptake)
}

/// The tilt's walk (see the module documentation), added to `cov`.
fn tilt_share(
    problem: &Problem<'_>,
    fit: &WalkFit<'_>,
    g: &DMatrix<f64>,
    q: f64,
    cov: &mut DMatrix<f64>,
) {
    let (Some(pitch), Some(roll)) = (
        &fit.lin.slopes[Setting::TiltPitch.index()],
        &fit.lin.slopes[Setting::TiltRoll.index()],
    ) else {
        return;
    };
    let e = problem.epochs;
    let p = g.nrows();
    let response = |k: usize| {
        Matrix2::new(
            pitch.theta_rad[k],
            roll.theta_rad[k],
            pitch.phi_rad[k],
            roll.phi_rad[k],
        )
    };
    // The valid epochs' rows, in time order (row 2v, 2v + 1 for the v-th valid epoch).
    let valid: Vec<usize> = (0..e.block.len()).filter(|&k| e.valid[k]).collect();
    if valid
        .iter()
        .any(|&k| k >= pitch.theta_rad.len() || k >= roll.theta_rad.len())
    {
        return;
    }
    let scale = q / (fit.attitude_sigma_rad * fit.attitude_sigma_rad);
    // Σ_{k≥j} G_k M_k, built from the last epoch back.
    let mut suffix = DMatrix::<f64>::zeros(p, 2);
    let mut s_j = DMatrix::<f64>::zeros(p, 2);
    for (v, &k) in valid.iter().enumerate().rev() {
        let m = response(k);
        let (col_theta, col_phi) = (g.column(2 * v), g.column(2 * v + 1));
        for i in 0..p {
            suffix[(i, 0)] += col_theta[i] * m[(0, 0)] + col_phi[i] * m[(1, 0)];
            suffix[(i, 1)] += col_theta[i] * m[(0, 1)] + col_phi[i] * m[(1, 1)];
        }
        let Some(m_inv) = m.try_inverse() else {
            continue;
        };
        let before = if v > 0 { e.t_s[valid[v - 1]] } else { 0.0 };
        let dt = (e.t_s[k] - before).max(0.0);
        for i in 0..p {
            for c in 0..2 {
                s_j[(i, c)] = suffix[(i, 0)] * m_inv[(0, c)] + suffix[(i, 1)] * m_inv[(1, c)];
            }
        }
        cov.gemm(scale * dt, &s_j, &s_j.transpose(), 1.0);
    }
}
