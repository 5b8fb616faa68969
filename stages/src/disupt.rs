//! DISUPT: corrections of the initial settings x = [azpocz, driftx, drifty, driftz]
//! (optionally the odometer scale) that minimise the criteria over a whole run.
//!
//! - OEPI (paper Table 1): azpocz by Kryt2, driftz by Kryt2, driftx by Kryt1, drifty by
//!   Kryt1 — bounded one-dimensional Brent searches in sequence.
//! - OWPI (paper Table 2): azpocz by Kryt1, driftz by Kryt1, then (azpocz, driftx,
//!   drifty) by Kryt1 with Nelder–Mead.
//! - joint: Levenberg–Marquardt over x (and the odometer scale when control points make it
//!   observable), fed with the raw pitch/roll residual series and every control point at
//!   once; forward-difference Jacobians whose passes run in parallel; the covariance
//!   `s²(JᵀJ)⁻¹` gives each estimate a 1σ.
//!
//! Kryt2 of a set of control points is their RMS horizontal error. Every evaluation is an
//! exact navigation pass; the optimisers work in scaled units (degrees, °/h, ppm) so that
//! their tolerances mean something.

use std::cell::RefCell;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::brent::BrentOpt;
use argmin::solver::neldermead::NelderMead;
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::criteria::{self, ControlPointFix, KalmanParams, Kryt1Scratch, Kryt2};
use crate::derive::Epochs;
use crate::filter::LowPass;
use crate::simulate::DEG_PER_H;
use crate::strapdown::{NavInputs, NavSettings, NavTrack, navigate};

/// Settings in the optimisers' units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct X {
    /// Initial azimuth, degrees.
    pub azimuth_deg: f64,
    /// Gyro drifts (x, y, z), °/h.
    pub drift_deg_h: [f64; 3],
    /// Odometer scale deviation from the base, ppm.
    pub odo_ppm: f64,
    /// Joint fit only: pitch and roll levelling corrections, mrad. The accelerometer
    /// biases enter the levelled initial attitude and the accelerometer pitch/roll alike;
    /// the levelling error then turns with the heading, the accelerometer one does not.
    pub tilt_mrad: [f64; 2],
}

/// Bounds and switches of the methods.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DisuptParams {
    /// Half-width of the azimuth search around its start, degrees.
    pub azimuth_bound_deg: f64,
    /// Half-width of each drift search around its start, °/h.
    pub drift_bound_deg_h: f64,
    /// 1σ of one epoch's pitch/roll residual in the joint fit, rad.
    pub attitude_sigma_rad: f64,
    /// 1σ of a control point's coordinates in the joint fit, m.
    pub position_sigma_m: f64,
    /// Estimate the odometer scale in the joint fit (needs control points).
    pub joint_odo_scale: bool,
}

impl Default for DisuptParams {
    fn default() -> Self {
        Self {
            azimuth_bound_deg: 15.0,
            drift_bound_deg_h: 5.0,
            attitude_sigma_rad: 2e-3,
            position_sigma_m: 1.0,
            joint_odo_scale: true,
        }
    }
}

/// One run's optimisation problem: everything is derived once; each evaluation is one
/// navigation pass and the criteria, without I/O or allocation.
pub struct Problem<'a> {
    /// Navigation inputs.
    pub inputs: NavInputs<'a>,
    /// Settings before DISUPT (`x_pocz`).
    pub base: NavSettings,
    /// Epochs of the criteria.
    pub epochs: &'a Epochs,
    /// The filter F.
    pub lp: LowPass,
    /// Kalman filter of Kryt1.
    pub kalman: KalmanParams,
    /// Control points.
    pub fixes: &'a [ControlPointFix],
    /// Prior on the vertical drift from the static start: (value, 1σ), °/h.
    pub drift_z_prior_deg_h: Option<(f64, f64)>,
    passes: AtomicUsize,
}

/// Criteria of one pass.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Kryt1, rad.
    pub kryt1: f64,
    /// Kryt2 at each control point.
    pub kryt2: Vec<Kryt2>,
}

impl Evaluation {
    /// RMS Kryt2 over the control points, m (NaN without control points).
    pub fn kryt2_rms(&self) -> f64 {
        (self
            .kryt2
            .iter()
            .map(|k| k.kryt2_m * k.kryt2_m)
            .sum::<f64>()
            / self.kryt2.len() as f64)
            .sqrt()
    }

    /// (ΔX, ΔY) at the last control point.
    pub fn last_error(&self) -> (f64, f64) {
        self.kryt2
            .last()
            .map_or((f64::NAN, f64::NAN), |k| (k.dx_m, k.dy_m))
    }
}

thread_local! {
    static SCRATCH: RefCell<(NavTrack, Kryt1Scratch, Vec<f64>)> = RefCell::new(Default::default());
}

impl<'a> Problem<'a> {
    /// A problem around `base`.
    pub fn new(
        inputs: NavInputs<'a>,
        base: NavSettings,
        epochs: &'a Epochs,
        lp: LowPass,
        kalman: KalmanParams,
        fixes: &'a [ControlPointFix],
    ) -> Self {
        Self {
            inputs,
            base,
            epochs,
            lp,
            kalman,
            fixes,
            drift_z_prior_deg_h: None,
            passes: AtomicUsize::new(0),
        }
    }

    /// Navigation passes so far.
    pub fn passes(&self) -> usize {
        self.passes.load(Ordering::Relaxed)
    }

    /// The base settings in optimiser units.
    pub fn x0(&self) -> X {
        X {
            azimuth_deg: self.base.initial.heading_rad.to_degrees(),
            drift_deg_h: self.base.drift_rad_s.map(|d| d / DEG_PER_H),
            odo_ppm: 0.0,
            tilt_mrad: [0.0; 2],
        }
    }

    /// Navigation settings of `x`.
    pub fn settings(&self, x: &X) -> NavSettings {
        let mut s = self.base;
        s.initial.heading_rad = x.azimuth_deg.to_radians();
        s.drift_rad_s = x.drift_deg_h.map(|d| d * DEG_PER_H);
        s.odo_scale = self.base.odo_scale * (1.0 + x.odo_ppm * 1e-6);
        s.initial.pitch_rad -= x.tilt_mrad[0] * 1e-3;
        s.initial.roll_rad -= x.tilt_mrad[1] * 1e-3;
        s
    }

    fn with_track<T>(
        &self,
        x: &X,
        f: impl FnOnce(&NavTrack, &mut Kryt1Scratch, &mut Vec<f64>) -> T,
    ) -> T {
        self.passes.fetch_add(1, Ordering::Relaxed);
        SCRATCH.with(|cell| {
            let (track, scratch, buf) = &mut *cell.borrow_mut();
            navigate(&self.inputs, &self.settings(x), track);
            f(track, scratch, buf)
        })
    }

    /// Kryt1 and Kryt2 of `x` (one exact pass).
    pub fn evaluate(&self, x: &X) -> Evaluation {
        self.with_track(x, |track, scratch, _| Evaluation {
            kryt1: criteria::kryt1(self.epochs, &self.lp, track, &self.kalman, scratch, None),
            kryt2: criteria::kryt2(track, self.fixes),
        })
    }

    /// The joint fit's weighted residuals of `x`.
    fn residuals(&self, x: &X, p: &DisuptParams) -> Vec<f64> {
        self.with_track(x, |track, scratch, buf| {
            criteria::attitude_residuals(self.epochs, &self.lp, track, scratch, buf);
            let c = [x.tilt_mrad[0] * 1e-3, x.tilt_mrad[1] * 1e-3];
            let mut r: Vec<f64> = buf
                .iter()
                .enumerate()
                .map(|(i, v)| (v + c[i % 2]) / p.attitude_sigma_rad)
                .collect();
            for k in criteria::kryt2(track, self.fixes) {
                r.push(k.dx_m / p.position_sigma_m);
                r.push(k.dy_m / p.position_sigma_m);
            }
            // At rest the vertical gyro measures driftz directly (method.md): a prior.
            if let Some((dz, sd)) = self.drift_z_prior_deg_h {
                r.push((x.drift_deg_h[2] - dz) / sd);
            }
            r
        })
    }
}

/// Which criterion a search minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Criterion {
    /// Kryt1.
    Kryt1,
    /// Kryt2 (RMS over the control points).
    Kryt2,
    /// Both at once, as weighted least squares (joint).
    LeastSquares,
}

/// Which component(s) a step moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Component {
    /// azpocz.
    Azimuth,
    /// driftx.
    DriftX,
    /// drifty.
    DriftY,
    /// driftz.
    DriftZ,
    /// (azpocz, driftx, drifty) together.
    AzimuthDriftXy,
    /// Every estimated setting at once (joint).
    All,
}

/// One row of the paper's tables.
#[derive(Debug, Clone, Serialize)]
pub struct Step {
    /// Step number, from 1.
    pub step: usize,
    /// What moved.
    pub component: Component,
    /// By which criterion.
    pub criterion: Criterion,
    /// Settings before the step.
    pub input: X,
    /// Settings after it.
    pub output: X,
    /// ΔX at the last control point after the step, m.
    pub dx_m: f64,
    /// ΔY at the last control point after the step, m.
    pub dy_m: f64,
    /// Navigation passes of the step.
    pub evaluations: usize,
}

/// The result of one method.
#[derive(Debug, Clone, Serialize)]
pub struct MethodResult {
    /// Optimised settings.
    pub x: X,
    /// 1σ of each optimised component (joint only), same units.
    pub sigma: Option<X>,
    /// ΔX at the last control point with `x`, m.
    pub dx_m: f64,
    /// ΔY at the last control point with `x`, m.
    pub dy_m: f64,
    /// Kryt1 with `x`, rad.
    pub kryt1: f64,
    /// The table rows.
    pub steps: Vec<Step>,
    /// Navigation passes.
    pub evaluations: usize,
    /// Wall time, s.
    pub wall_s: f64,
}

struct Line<'p, 'a> {
    problem: &'p Problem<'a>,
    x: X,
    component: Component,
    criterion: Criterion,
}

fn set(x: &mut X, c: Component, v: f64) {
    match c {
        Component::Azimuth => x.azimuth_deg = v,
        Component::DriftX => x.drift_deg_h[0] = v,
        Component::DriftY => x.drift_deg_h[1] = v,
        Component::DriftZ => x.drift_deg_h[2] = v,
        Component::AzimuthDriftXy | Component::All => {}
    }
}

fn get(x: &X, c: Component) -> f64 {
    match c {
        Component::Azimuth | Component::AzimuthDriftXy | Component::All => x.azimuth_deg,
        Component::DriftX => x.drift_deg_h[0],
        Component::DriftY => x.drift_deg_h[1],
        Component::DriftZ => x.drift_deg_h[2],
    }
}

fn cost(problem: &Problem<'_>, x: &X, criterion: Criterion) -> f64 {
    let e = problem.evaluate(x);
    match criterion {
        Criterion::Kryt1 => e.kryt1,
        Criterion::Kryt2 | Criterion::LeastSquares => e.kryt2_rms(),
    }
}

impl CostFunction for Line<'_, '_> {
    type Param = f64;
    type Output = f64;

    fn cost(&self, v: &f64) -> Result<f64, ArgminError> {
        let mut x = self.x;
        set(&mut x, self.component, *v);
        Ok(cost(self.problem, &x, self.criterion))
    }
}

struct Plane<'p, 'a> {
    problem: &'p Problem<'a>,
    x: X,
}

impl CostFunction for Plane<'_, '_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, v: &Vec<f64>) -> Result<f64, ArgminError> {
        let mut x = self.x;
        x.azimuth_deg = v[0];
        x.drift_deg_h[0] = v[1];
        x.drift_deg_h[1] = v[2];
        Ok(cost(self.problem, &x, Criterion::Kryt1))
    }
}

/// Errors of the methods.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DisuptError {
    /// A method needs control points the run does not have.
    #[error("{0} needs at least one control point")]
    NoControlPoint(&'static str),
    /// An optimiser failed.
    #[error("optimiser: {0}")]
    Optimiser(String),
}

fn brent(
    problem: &Problem<'_>,
    x: X,
    component: Component,
    criterion: Criterion,
    half: f64,
) -> Result<X, DisuptError> {
    let c = get(&x, component);
    let solver = BrentOpt::new(c - half, c + half).set_tolerance(1e-8, 1e-4);
    let res = Executor::new(
        Line {
            problem,
            x,
            component,
            criterion,
        },
        solver,
    )
    .configure(|s| s.max_iters(100))
    .run()
    .map_err(|e| DisuptError::Optimiser(e.to_string()))?;
    let mut out = x;
    set(
        &mut out,
        component,
        *res.state().get_best_param().unwrap_or(&c),
    );
    Ok(out)
}

fn run_steps(
    problem: &Problem<'_>,
    plan: &[(Component, Criterion)],
    p: &DisuptParams,
) -> Result<MethodResult, DisuptError> {
    let t0 = Instant::now();
    let passes0 = problem.passes();
    let mut x = problem.x0();
    let mut steps = Vec::new();
    for (i, &(component, criterion)) in plan.iter().enumerate() {
        let before = problem.passes();
        let input = x;
        x = match component {
            Component::AzimuthDriftXy => {
                let start = vec![x.azimuth_deg, x.drift_deg_h[0], x.drift_deg_h[1]];
                let simplex = vec![
                    start.clone(),
                    vec![start[0] + 1.0, start[1], start[2]],
                    vec![start[0], start[1] + 1.0, start[2]],
                    vec![start[0], start[1], start[2] + 1.0],
                ];
                let solver = NelderMead::new(simplex)
                    .with_sd_tolerance(1e-7)
                    .map_err(|e| DisuptError::Optimiser(e.to_string()))?;
                let res = Executor::new(Plane { problem, x }, solver)
                    .configure(|s| s.max_iters(400))
                    .run()
                    .map_err(|e| DisuptError::Optimiser(e.to_string()))?;
                let best = res.state().get_best_param().cloned().unwrap_or(start);
                X {
                    azimuth_deg: best[0],
                    drift_deg_h: [best[1], best[2], x.drift_deg_h[2]],
                    ..x
                }
            }
            Component::Azimuth => brent(problem, x, component, criterion, p.azimuth_bound_deg)?,
            _ => brent(problem, x, component, criterion, p.drift_bound_deg_h)?,
        };
        // Every reported optimum is confirmed by an exact pass.
        let e = problem.evaluate(&x);
        let (dx_m, dy_m) = e.last_error();
        steps.push(Step {
            step: i + 1,
            component,
            criterion,
            input,
            output: x,
            dx_m,
            dy_m,
            evaluations: problem.passes() - before,
        });
    }
    let e = problem.evaluate(&x);
    let (dx_m, dy_m) = e.last_error();
    Ok(MethodResult {
        x,
        sigma: None,
        dx_m,
        dy_m,
        kryt1: e.kryt1,
        steps,
        evaluations: problem.passes() - passes0,
        wall_s: t0.elapsed().as_secs_f64(),
    })
}

/// OEPI (paper Table 1).
pub fn oepi(problem: &Problem<'_>, p: &DisuptParams) -> Result<MethodResult, DisuptError> {
    if problem.fixes.is_empty() {
        return Err(DisuptError::NoControlPoint("OEPI"));
    }
    run_steps(
        problem,
        &[
            (Component::Azimuth, Criterion::Kryt2),
            (Component::DriftZ, Criterion::Kryt2),
            (Component::DriftX, Criterion::Kryt1),
            (Component::DriftY, Criterion::Kryt1),
        ],
        p,
    )
}

/// OWPI (paper Table 2).
pub fn owpi(problem: &Problem<'_>, p: &DisuptParams) -> Result<MethodResult, DisuptError> {
    run_steps(
        problem,
        &[
            (Component::Azimuth, Criterion::Kryt1),
            (Component::DriftZ, Criterion::Kryt1),
            (Component::AzimuthDriftXy, Criterion::Kryt1),
        ],
        p,
    )
}

/// The joint least-squares problem in the form the LM crate wants.
struct Joint<'p, 'a> {
    problem: &'p Problem<'a>,
    params: &'p DisuptParams,
    p: DVector<f64>,
    cache: RefCell<Option<(DVector<f64>, Vec<f64>)>>,
}

/// Forward-difference steps: 0.01°, 0.01 °/h (×3), 0.01 mrad (×2), 10 ppm.
const FD_STEP: [f64; 7] = [1e-2, 1e-2, 1e-2, 1e-2, 1e-2, 1e-2, 10.0];

/// The joint parameter vector `[az, dx, dy, dz, tilt_pitch, tilt_roll, (ppm)]` as `X`.
fn joint_x(p: &DVector<f64>) -> X {
    X {
        azimuth_deg: p[0],
        drift_deg_h: [p[1], p[2], p[3]],
        tilt_mrad: [p[4], p[5]],
        odo_ppm: if p.len() > 6 { p[6] } else { 0.0 },
    }
}

impl Joint<'_, '_> {
    fn x_of(&self, p: &DVector<f64>) -> X {
        joint_x(p)
    }

    fn residuals_at(&self, p: &DVector<f64>) -> Vec<f64> {
        if let Some((cp, r)) = &*self.cache.borrow()
            && cp == p
        {
            return r.clone();
        }
        let r = self.problem.residuals(&self.x_of(p), self.params);
        *self.cache.borrow_mut() = Some((p.clone(), r.clone()));
        r
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Joint<'_, '_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, p: &DVector<f64>) {
        self.p.copy_from(p);
    }

    fn params(&self) -> DVector<f64> {
        self.p.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let r = self.residuals_at(&self.p);
        r.iter()
            .all(|v| v.is_finite())
            .then(|| DVector::from_vec(r))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let r0 = self.residuals_at(&self.p);
        let n = self.p.len();
        let (problem, params, p0) = (self.problem, self.params, &self.p);
        let x_of = joint_x;
        let columns: Vec<Vec<f64>> = (0..n)
            .into_par_iter()
            .map(|j| {
                let mut pj = p0.clone();
                pj[j] += FD_STEP[j];
                let rj = problem.residuals(&x_of(&pj), params);
                rj.iter()
                    .zip(&r0)
                    .map(|(a, b)| (a - b) / FD_STEP[j])
                    .collect()
            })
            .collect();
        let m = r0.len();
        Some(DMatrix::from_fn(m, n, |i, j| columns[j][i]))
    }
}

/// The joint estimator.
pub fn joint(problem: &Problem<'_>, p: &DisuptParams) -> Result<MethodResult, DisuptError> {
    let t0 = Instant::now();
    let passes0 = problem.passes();
    let x0 = problem.x0();
    let with_scale = p.joint_odo_scale && !problem.fixes.is_empty();
    let mut start = vec![
        x0.azimuth_deg,
        x0.drift_deg_h[0],
        x0.drift_deg_h[1],
        x0.drift_deg_h[2],
        0.0,
        0.0,
    ];
    if with_scale {
        start.push(0.0);
    }
    // Position residuals are nonlinear in a large azimuth error: start from the azimuth
    // that best fits the control points (a cheap 1-D search) when there are some.
    if !problem.fixes.is_empty() {
        start[0] = brent(
            problem,
            x0,
            Component::Azimuth,
            Criterion::Kryt2,
            p.azimuth_bound_deg,
        )?
        .azimuth_deg;
    }
    let target = Joint {
        problem,
        params: p,
        p: DVector::from_vec(start),
        cache: RefCell::new(None),
    };
    let (solved, report) = LevenbergMarquardt::new().with_patience(20).minimize(target);
    if !report.termination.was_successful() {
        return Err(DisuptError::Optimiser(format!("{:?}", report.termination)));
    }
    let x = solved.x_of(&solved.p);
    // Covariance s²(JᵀJ)⁻¹ at the solution.
    let sigma = solved.jacobian().and_then(|j| {
        let r = solved.residuals_at(&solved.p);
        let dof = (r.len() as f64 - solved.p.len() as f64).max(1.0);
        let s2 = r.iter().map(|v| v * v).sum::<f64>() / dof;
        (j.transpose() * &j).try_inverse().map(|c| {
            let sd = |i: usize| (c[(i, i)] * s2).max(0.0).sqrt();
            X {
                azimuth_deg: sd(0),
                drift_deg_h: [sd(1), sd(2), sd(3)],
                tilt_mrad: [sd(4), sd(5)],
                odo_ppm: if with_scale { sd(6) } else { 0.0 },
            }
        })
    });
    let e = problem.evaluate(&x);
    let (dx_m, dy_m) = e.last_error();
    let evaluations = problem.passes() - passes0;
    let step = Step {
        step: 1,
        component: Component::All,
        criterion: Criterion::LeastSquares,
        input: x0,
        output: x,
        dx_m,
        dy_m,
        evaluations,
    };
    Ok(MethodResult {
        x,
        sigma,
        dx_m,
        dy_m,
        kryt1: e.kryt1,
        steps: vec![step],
        evaluations,
        wall_s: t0.elapsed().as_secs_f64(),
    })
}
