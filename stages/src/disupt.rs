//! DISUPT: corrections of the initial settings x = [azpocz, driftx, drifty, driftz]
//! (optionally the odometer scale) that minimise the criteria over a whole run.
//!
//! - OEPI (paper Table 1): azpocz by Kryt2, driftz by Kryt2, driftx by Kryt1, drifty by
//!   Kryt1 — bounded one-dimensional Brent searches in sequence.
//! - OWPI (paper Table 2): azpocz by Kryt1, driftz by Kryt1, then (azpocz, driftx,
//!   drifty) by Kryt1 with Nelder–Mead.
//! - joint: Gauss–Newton over x, two levelling corrections and the odometer scale (when
//!   control points make it observable), fed with the raw pitch/roll residual series and
//!   every control point at once; each linearised step is solved by Levenberg–Marquardt.
//!   A second round re-weights the epochs by their residuals' RMS (variance components:
//!   the epochs' misfit is several mrad, not the assumed 2), so that the control points
//!   weigh what their 1 m says; the covariance `s²(JᵀJ)⁻¹` gives each estimate a 1σ.
//!
//! Every search runs on the [`Linearization`] of the criteria's inputs around the current
//! settings (one exact pass plus one forward-difference pass per moved setting, in
//! parallel); an exact pass confirms each optimum, and where it disagrees with the model
//! the model is rebuilt there and the search repeated. A step that does not settle that
//! way falls back to searching with exact passes. Kryt2 of a set of control points is
//! their RMS horizontal error. The optimisers work in scaled units (degrees, °/h, ppm) so
//! that their tolerances mean something.

use std::borrow::Cow;
use std::cell::RefCell;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::brent::BrentOpt;
use argmin::solver::neldermead::NelderMead;
use either::Either;
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::criteria::{self, ControlPointFix, KalmanParams, Kryt2};
use crate::derive::{Epochs, MovedOdometer, OdoIncrements};
use crate::earth;
use crate::filter::LowPass;
use crate::linearized::{Linearization, N_PARAMS, Observation, Setting};
use crate::strapdown::{self, CriteriaSink, LaneBatch, NavInputs, NavSettings, in_lanes};
use crate::units::DEG_PER_H;

/// Settings in the optimisers' units.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct X {
    /// Initial azimuth, degrees.
    pub azimuth_deg: f64,
    /// Gyro drifts (x, y, z), °/h.
    pub drift_deg_h: [f64; 3],
    /// Odometer scale deviation from the base, ppm.
    pub odo_ppm: f64,
    /// Joint fit only (when asked for): odometer yaw boresight added to the base's,
    /// degrees. The odometer's direction of travel is body x turned by it.
    #[serde(default)]
    pub odo_yaw_deg: f64,
    /// Joint fit only (when asked for): odometer speed bias added to the base's, m/s.
    #[serde(default)]
    pub odo_bias_mps: f64,
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
    /// 1σ of one epoch's pitch/roll residual in the joint fit's first round, rad; the
    /// second round uses the residuals' RMS at the first solution when it is larger.
    pub attitude_sigma_rad: f64,
    /// 1σ of a control point's coordinates in the joint fit, m.
    pub position_sigma_m: f64,
    /// Estimate the odometer scale in the joint fit (needs control points).
    pub joint_odo_scale: bool,
    /// Estimate the odometer yaw boresight in the joint fit (needs control points). It
    /// turns the route like the initial azimuth does, so only the attitude residuals
    /// (Kryt1's information) tell the two apart: the azimuth's σ grows to what they
    /// give. Off by default.
    pub joint_odo_yaw: bool,
    /// Estimate an odometer speed bias in the joint fit (needs control points): what an
    /// OBD-II speed has, a pulse odometer has not. Absent: the stage decides by the kind
    /// of odometer (on for speed logs, off for pulse counts and distances).
    pub joint_odo_bias: Option<bool>,
    /// Estimate the odometer's lag with the joint fit (needs two control points or more:
    /// it moves the route at the stops by the lag times the velocity change from turns).
    pub joint_odo_lag: bool,
    /// Half-width of the lag search, s.
    pub odo_lag_bound_s: f64,
}

impl Default for DisuptParams {
    fn default() -> Self {
        Self {
            azimuth_bound_deg: 15.0,
            drift_bound_deg_h: 5.0,
            attitude_sigma_rad: 2e-3,
            position_sigma_m: 1.0,
            joint_odo_scale: true,
            joint_odo_yaw: false,
            joint_odo_bias: None,
            joint_odo_lag: true,
            odo_lag_bound_s: 1.0,
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
    /// The odometer increments, when they are read as a pass goes instead of from
    /// `inputs` (a derive at another odometer timing: [`ProblemSpec::on_moved`]).
    moved_odometer: Option<MovedOdometer<'a>>,
    passes: AtomicUsize,
    base_lin: std::sync::OnceLock<Linearization>,
}

/// Everything of a DISUPT problem but the derive it runs on, so that the same problem
/// can be set on another derive (the odometer-lag search re-derives).
#[derive(Debug, Clone, Copy)]
pub struct ProblemSpec<'a> {
    /// Settings before DISUPT (the searches' start).
    pub settings: NavSettings,
    /// The filter F's parameters.
    pub filter: crate::filter::FilterParams,
    /// Kalman filter of Kryt1.
    pub kalman: KalmanParams,
    /// Control points.
    pub fixes: &'a [ControlPointFix],
    /// Prior on the vertical drift from the static start: (value, 1σ), °/h.
    pub drift_z_prior_deg_h: Option<(f64, f64)>,
}

impl<'a> ProblemSpec<'a> {
    /// The problem on the derive `d`.
    pub fn on<'b>(self, d: &'b crate::derive::Derived) -> Problem<'b>
    where
        'a: 'b,
    {
        let mut p = Problem::new(
            d.nav_inputs(),
            self.settings,
            &d.epochs,
            LowPass::new(&self.filter, d.nominal_dt_s),
            self.kalman,
            self.fixes,
        );
        p.drift_z_prior_deg_h = self.drift_z_prior_deg_h;
        p
    }

    /// The problem on the derive `d` whose odometer increments are not stored but read
    /// from `odometer` as each pass goes (the odometer-lag search's trials).
    pub fn on_moved<'b>(
        self,
        d: &'b crate::derive::Derived,
        odometer: MovedOdometer<'b>,
    ) -> Problem<'b>
    where
        'a: 'b,
    {
        let mut p = self.on(d);
        p.moved_odometer = Some(odometer);
        p
    }
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
        criteria::kryt2_rms_m(self.kryt2.iter().map(|k| [k.dx_m, k.dy_m]))
    }

    /// (ΔX, ΔY) at the last control point.
    pub fn last_error(&self) -> (f64, f64) {
        self.kryt2
            .last()
            .map_or((f64::NAN, f64::NAN), |k| (k.dx_m, k.dy_m))
    }
}

/// Most passes stepped side by side in vector lanes by [`Problem::observe_many_by`].
pub const LANES: usize = strapdown::MAX_LANES;

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
            moved_odometer: None,
            passes: AtomicUsize::new(0),
            base_lin: std::sync::OnceLock::new(),
        }
    }

    /// The odometer increments a pass of this problem reads, sample by sample.
    fn odometer_increments(&self) -> LaneIncrements<'a> {
        match self.moved_odometer {
            Some(moved) => Either::Right(moved.increments()),
            None => Either::Left(self.inputs.odo_dist_m.iter().copied()),
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
            odo_yaw_deg: 0.0,
            odo_bias_mps: 0.0,
        }
    }

    /// Navigation settings of `x`.
    pub fn settings(&self, x: &X) -> NavSettings {
        let mut s = self.base;
        s.initial.heading_rad = x.azimuth_deg.to_radians();
        s.drift_rad_s = x.drift_deg_h.map(|d| d * DEG_PER_H);
        s.odo_scale = self.base.odo_scale * (1.0 + x.odo_ppm * 1e-6);
        s.odo_yaw_rad = self.base.odo_yaw_rad + x.odo_yaw_deg.to_radians();
        s.odo_bias_mps = self.base.odo_bias_mps + x.odo_bias_mps;
        s.initial.pitch_rad -= x.tilt_mrad[0] * 1e-3;
        s.initial.roll_rad -= x.tilt_mrad[1] * 1e-3;
        s
    }

    /// Kryt1 and Kryt2 of `x` (one exact pass).
    pub fn evaluate(&self, x: &X) -> Evaluation {
        self.evaluation_of(&self.observe(x))
    }

    /// What the criteria read from the pass of `x` (one exact pass).
    pub fn observe(&self, x: &X) -> Observation {
        self.observe_by(x, &AtomicUsize::new(0))
    }

    /// [`Self::observe`], counted in `tally` too (a method's own passes). The pass keeps
    /// no track: it sums what the criteria need as it goes ([`CriteriaSink`]).
    pub fn observe_by(&self, x: &X, tally: &AtomicUsize) -> Observation {
        let mut y = self.observe_batch(&[*x], tally);
        y.pop().expect("one observation of one point")
    }

    /// The observations of several settings (in their order), each what
    /// [`Self::observe`] gives, bit for bit; counted in `tally` too. Up to [`LANES`]
    /// passes run side by side in vector lanes, and the batches in parallel: the points
    /// are shared evenly between rayon's threads first, so that a few points still use
    /// every core.
    pub fn observe_many_by(&self, xs: &[X], tally: &AtomicUsize) -> Vec<Observation> {
        let threads = rayon::current_num_threads().max(1);
        let chunk = xs.len().div_ceil(threads).clamp(1, LANES);
        xs.par_chunks(chunk)
            .flat_map_iter(|chunk| self.observe_batch(chunk, tally))
            .collect()
    }

    /// [`Self::observe_many_by`] on the calling thread only, in as few batches of lanes as
    /// the points fill: the least CPU for a few points, where the caller's own concurrency
    /// keeps the cores busy.
    pub fn observe_batched_by(&self, xs: &[X], tally: &AtomicUsize) -> Vec<Observation> {
        xs.chunks(LANES)
            .flat_map(|chunk| self.observe_batch(chunk, tally))
            .collect()
    }

    /// At most [`LANES`] points in one batch of lanes.
    fn observe_batch(&self, xs: &[X], tally: &AtomicUsize) -> Vec<Observation> {
        tally.fetch_add(xs.len(), Ordering::Relaxed);
        self.passes.fetch_add(xs.len(), Ordering::Relaxed);
        in_lanes(
            xs.len(),
            &mut OnDerives {
                problems: &[self],
                xs,
            },
        )
    }

    /// What the criteria read from a pass's sink.
    fn observation_of_sink(&self, mut sink: CriteriaSink) -> Observation {
        let mut y = Observation::default();
        criteria::epoch_attitude_from_blocks(
            self.epochs,
            &self.lp,
            std::mem::take(&mut sink.blocks),
            &mut y.theta_rad,
            &mut y.phi_rad,
        );
        y.cp_m = self
            .fixes
            .iter()
            .filter_map(|f| {
                let (lat, lon) = sink.position_at(f.sample)?;
                Some(earth::local_offset_m(lat, lon, f.lat_rad, f.lon_rad, f.h_m))
            })
            .map(|(dx, dy)| [dx, dy])
            .collect();
        y
    }

    /// The criteria of an observation.
    pub fn evaluation_of(&self, y: &Observation) -> Evaluation {
        Evaluation {
            kryt1: y.kryt1(self.epochs, &self.kalman),
            kryt2: y.kryt2(self.fixes),
        }
    }

    /// [`Self::linearize`], its passes counted in `tally` too.
    pub fn linearize_by(
        &self,
        x: &X,
        y: Observation,
        which: &[Setting],
        tally: &AtomicUsize,
    ) -> Linearization {
        let ys = self.observe_many_by(&moved_by_steps(x, which), tally);
        linearization_of(x, y, which, ys)
    }

    /// Passes of the shared first linearisation (0 before it is built).
    pub fn base_passes(&self) -> usize {
        self.base_lin
            .get()
            .map_or(0, |l| 1 + l.slopes.iter().flatten().count())
    }

    /// The linearisation around `x0` in every parameter but the odometer boresight,
    /// built once and shared by the methods (each starts there; its passes are counted in
    /// [`Self::base_passes`]).
    pub fn base_linearization(&self) -> &Linearization {
        self.base_lin.get_or_init(|| {
            let x0 = self.x0();
            let mut xs = vec![x0];
            xs.extend(moved_by_steps(&x0, BASE_SETTINGS));
            let mut ys = self.observe_many_by(&xs, &AtomicUsize::new(0));
            let y0 = ys.remove(0);
            linearization_of(&x0, y0, BASE_SETTINGS, ys)
        })
    }

    /// `lin` with the slopes it lacks among `which` added (one pass each, counted in
    /// `tally`).
    pub fn completed(
        &self,
        lin: &Linearization,
        which: &[Setting],
        tally: &AtomicUsize,
    ) -> Linearization {
        let missing: Vec<Setting> = which
            .iter()
            .copied()
            .filter(|s| lin.slopes[s.index()].is_none())
            .collect();
        let x = x_of(&lin.p_ref);
        let ys = self.observe_many_by(&moved_by_steps(&x, &missing), tally);
        let mut out = linearization_of(&x, lin.y_ref.clone(), &missing, ys);
        for (j, slope) in lin.slopes.iter().enumerate() {
            if slope.is_some() {
                out.slopes[j].clone_from(slope);
            }
        }
        out
    }
}

/// The exact observation of `x` on each of `problems`, derives of one run at other
/// odometer timings (the same IMU series, control points and blocks), in batches of
/// lanes each on its own odometer increments; each what [`Problem::observe`] gives, bit
/// for bit. Counted in `tally` and each problem's passes.
///
/// # Panics
/// If the problems do not share their IMU series, control points and blocks.
pub fn observe_each(problems: &[&Problem<'_>], x: &X, tally: &AtomicUsize) -> Vec<Observation> {
    let Some(first) = problems.first() else {
        return Vec::new();
    };
    assert!(
        problems.iter().all(|p| p.inputs.same_imu_as(&first.inputs)
            && p.inputs.len() == first.inputs.len()
            && std::ptr::eq(p.fixes, first.fixes)
            && p.lp.block == first.lp.block),
        "derives of different runs or filters"
    );
    tally.fetch_add(problems.len(), Ordering::Relaxed);
    problems
        .chunks(LANES)
        .flat_map(|chunk| {
            for p in chunk {
                p.passes.fetch_add(1, Ordering::Relaxed);
            }
            let xs = vec![*x; chunk.len()];
            in_lanes(
                chunk.len(),
                &mut OnDerives {
                    problems: chunk,
                    xs: &xs,
                },
            )
        })
        .collect()
}

/// Points side by side: the `i`-th at `xs[i]` on `problems[i]`, or all on the only
/// problem. The problems share their IMU series, control points and blocks; each lane
/// runs on its own problem's odometer increments.
struct OnDerives<'p, 'a> {
    problems: &'p [&'p Problem<'a>],
    xs: &'p [X],
}

impl<'a> OnDerives<'_, 'a> {
    fn problem(&self, i: usize) -> &Problem<'a> {
        self.problems[i.min(self.problems.len() - 1)]
    }
}

impl LaneBatch for OnDerives<'_, '_> {
    type Out = Observation;

    fn run<const N: usize>(&mut self, points: [usize; N]) -> [Observation; N] {
        let first = self.problems[0];
        let settings = points.map(|i| self.problem(i).settings(&self.xs[i]));
        let n = first.inputs.len();
        let at: Vec<usize> = first
            .fixes
            .iter()
            .map(|f| f.sample)
            .filter(|&k| k < n)
            .collect();
        // The sinks live for this batch only: each holds its pass's blocks (a run's
        // length), so none is kept once the observations are taken.
        let mut sinks: [CriteriaSink; N] = std::array::from_fn(|_| CriteriaSink::default());
        if self.problems.len() == 1 && first.moved_odometer.is_none() {
            strapdown::run_criteria(&first.inputs, &settings, first.lp.block, &at, &mut sinks);
        } else {
            let odometers = points.map(|i| self.problem(i).odometer_increments());
            strapdown::run_criteria_streams(
                &first.inputs,
                odometers,
                &settings,
                first.lp.block,
                &at,
                &mut sinks,
            );
        }
        let mut sinks = sinks.into_iter();
        std::array::from_fn(|l| {
            let sink = sinks.next().expect("one sink per lane");
            self.problem(points[l]).observation_of_sink(sink)
        })
    }
}

/// A lane's odometer increments: a derive's stored ones, or read from the ingested
/// odometer as the pass goes.
type LaneIncrements<'a> = Either<std::iter::Copied<std::slice::Iter<'a, f64>>, OdoIncrements<'a>>;

/// `x` moved by one finite-difference step in each setting of `which`, in turn.
pub fn moved_by_steps(x: &X, which: &[Setting]) -> Vec<X> {
    which
        .iter()
        .map(|&s| {
            let mut xs = *x;
            xs.set(s, x.get(s) + s.fd_step());
            xs
        })
        .collect()
}

/// The linearisation around `x` (observed `y`) from the observations `moved` of
/// [`moved_by_steps`]`(x, which)`.
fn linearization_of(
    x: &X,
    y: Observation,
    which: &[Setting],
    moved: Vec<Observation>,
) -> Linearization {
    let mut slopes: [Option<Observation>; N_PARAMS] = Default::default();
    for (&s, ys) in which.iter().zip(moved) {
        slopes[s.index()] = Some(ys.slope(&y, s.fd_step()));
    }
    Linearization {
        p_ref: params_of(x),
        y_ref: y,
        slopes,
    }
}

/// `X` as the linearisation's parameter vector (in [`Setting::ALL`] order).
pub fn params_of(x: &X) -> [f64; N_PARAMS] {
    Setting::ALL.map(|s| x.get(s))
}

/// Settings of the shared first linearisation: all but the odometer boresight and bias,
/// which only the joint fit moves, and only when asked.
const BASE_SETTINGS: &[Setting] = Setting::ALL.split_at(Setting::OdoYaw.index()).0;

/// The inverse of [`params_of`].
pub fn x_of(p: &[f64; N_PARAMS]) -> X {
    let mut x = X::default();
    for s in Setting::ALL {
        x.set(s, p[s.index()]);
    }
    x
}

impl X {
    /// The value of one setting, in the optimisers' units.
    pub fn get(&self, s: Setting) -> f64 {
        match s {
            Setting::Azimuth => self.azimuth_deg,
            Setting::DriftX => self.drift_deg_h[0],
            Setting::DriftY => self.drift_deg_h[1],
            Setting::DriftZ => self.drift_deg_h[2],
            Setting::TiltPitch => self.tilt_mrad[0],
            Setting::TiltRoll => self.tilt_mrad[1],
            Setting::OdoScale => self.odo_ppm,
            Setting::OdoYaw => self.odo_yaw_deg,
            Setting::OdoBias => self.odo_bias_mps,
        }
    }

    /// Sets one setting, in the optimisers' units.
    pub fn set(&mut self, s: Setting, v: f64) {
        match s {
            Setting::Azimuth => self.azimuth_deg = v,
            Setting::DriftX => self.drift_deg_h[0] = v,
            Setting::DriftY => self.drift_deg_h[1] = v,
            Setting::DriftZ => self.drift_deg_h[2] = v,
            Setting::TiltPitch => self.tilt_mrad[0] = v,
            Setting::TiltRoll => self.tilt_mrad[1] = v,
            Setting::OdoScale => self.odo_ppm = v,
            Setting::OdoYaw => self.odo_yaw_deg = v,
            Setting::OdoBias => self.odo_bias_mps = v,
        }
    }
}

/// Which criterion a search minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Criterion {
    /// Kryt1.
    Kryt1,
    /// Kryt2 (RMS over the control points).
    Kryt2,
    /// Both at once, as weighted least squares (joint).
    LeastSquares,
}

/// Which component(s) a step moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
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
#[derive(Debug, Clone, Serialize, Deserialize)]
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
    #[serde(
        skip_serializing_if = "crate::finite::is_absent",
        default = "crate::finite::absent"
    )]
    pub dx_m: f64,
    /// ΔY at the last control point after the step, m.
    #[serde(
        skip_serializing_if = "crate::finite::is_absent",
        default = "crate::finite::absent"
    )]
    pub dy_m: f64,
    /// Navigation passes of the step.
    pub evaluations: usize,
}

/// The result of one method.
#[derive(Debug, Clone, Serialize, Deserialize)]
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
    /// The method's own navigation passes (the shared first linearisation, see
    /// [`Problem::base_passes`], aside).
    pub evaluations: usize,
    /// Wall time, s.
    pub wall_s: f64,
}

impl Component {
    /// The settings a step moves.
    fn settings(self) -> &'static [Setting] {
        match self {
            Component::Azimuth => &[Setting::Azimuth],
            Component::DriftX => &[Setting::DriftX],
            Component::DriftY => &[Setting::DriftY],
            Component::DriftZ => &[Setting::DriftZ],
            Component::AzimuthDriftXy => &[Setting::Azimuth, Setting::DriftX, Setting::DriftY],
            Component::All => BASE_SETTINGS,
        }
    }
}

/// Errors of the methods.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DisuptError {
    /// A method needs control points the run does not have.
    #[error("{0} needs at least one control point")]
    NoControlPoint(&'static str),
    /// An optimiser (argmin) failed; the cause is kept as the source.
    #[error("optimiser: {0}")]
    Optimiser(#[from] ArgminError),
    /// A least-squares step (Levenberg–Marquardt) did not converge.
    #[error("least squares did not converge: {0}")]
    LeastSquares(String),
    /// A linear solve failed.
    #[error("linear solve: {0}")]
    Linear(&'static str),
}

/// Relinearisations of one search before it falls back to exact passes.
const MAX_RELINEARISATIONS: usize = 6;

/// A criterion over the free parameters of `p`, evaluated exactly (a pass each) or on a
/// linearisation (no pass).
struct Objective<'p, 'a> {
    problem: &'p Problem<'a>,
    lin: Option<&'p Linearization>,
    p: [f64; N_PARAMS],
    free: &'static [Setting],
    criterion: Criterion,
    buf: RefCell<Observation>,
    tally: &'p AtomicUsize,
}

impl Objective<'_, '_> {
    fn at(&self, values: &[f64]) -> f64 {
        let mut p = self.p;
        for (s, &v) in self.free.iter().zip(values) {
            p[s.index()] = v;
        }
        let value = |y: &Observation| match self.criterion {
            Criterion::Kryt1 => y.kryt1(self.problem.epochs, &self.problem.kalman),
            Criterion::Kryt2 | Criterion::LeastSquares => y.kryt2_rms(),
        };
        match self.lin {
            Some(lin) => {
                let mut y = self.buf.borrow_mut();
                lin.predict_into(&p, &mut y);
                value(&y)
            }
            None => value(&self.problem.observe_by(&x_of(&p), self.tally)),
        }
    }
}

/// One component (Brent).
struct Along<'o, 'p, 'a>(&'o Objective<'p, 'a>);

impl CostFunction for Along<'_, '_, '_> {
    type Param = f64;
    type Output = f64;

    fn cost(&self, v: &f64) -> Result<f64, ArgminError> {
        Ok(self.0.at(&[*v]))
    }
}

/// Several components (Nelder–Mead).
struct Within<'o, 'p, 'a>(&'o Objective<'p, 'a>);

impl CostFunction for Within<'_, '_, '_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, v: &Vec<f64>) -> Result<f64, ArgminError> {
        Ok(self.0.at(v))
    }
}

/// Minimises `criterion` over `component`, starting from `x`, on `lin` (or exactly).
fn minimise(
    problem: &Problem<'_>,
    lin: Option<&Linearization>,
    x: X,
    component: Component,
    criterion: Criterion,
    p: &DisuptParams,
    tally: &AtomicUsize,
) -> Result<X, DisuptError> {
    let objective = Objective {
        problem,
        lin,
        p: params_of(&x),
        free: component.settings(),
        criterion,
        buf: RefCell::new(Observation::default()),
        tally,
    };
    let mut out = x;
    let settings = component.settings();
    if let [single] = settings {
        let half = if *single == Setting::Azimuth {
            p.azimuth_bound_deg
        } else {
            p.drift_bound_deg_h
        };
        let c = x.get(*single);
        let (rel, abs) = if lin.is_some() {
            (1e-10, 1e-6)
        } else {
            (1e-8, 1e-4)
        };
        let solver = BrentOpt::new(c - half, c + half).set_tolerance(rel, abs);
        let res = Executor::new(Along(&objective), solver)
            .configure(|s| s.max_iters(200))
            .run()
            .map_err(DisuptError::Optimiser)?;
        out.set(*single, *res.state().get_best_param().unwrap_or(&c));
        return Ok(out);
    }
    {
        // Several settings at once: Nelder–Mead from a simplex of unit steps.
        let start: Vec<f64> = settings.iter().map(|&s| x.get(s)).collect();
        let mut simplex = vec![start.clone()];
        simplex.extend((0..start.len()).map(|i| {
            let mut v = start.clone();
            v[i] += 1.0;
            v
        }));
        let solver = NelderMead::new(simplex)
            .with_sd_tolerance(1e-9)
            .map_err(DisuptError::Optimiser)?;
        let res = Executor::new(Within(&objective), solver)
            .configure(|s| s.max_iters(if lin.is_some() { 2000 } else { 400 }))
            .run()
            .map_err(DisuptError::Optimiser)?;
        let best = res.state().get_best_param().cloned().unwrap_or(start);
        for (&s, v) in settings.iter().zip(best) {
            out.set(s, v);
        }
    }
    Ok(out)
}

/// Where one step of OEPI/OWPI ended.
struct Searched {
    /// The optimum.
    x: X,
    /// Its exact observation.
    y: Observation,
    /// A linearisation at `x` in the next step's settings, when it was built.
    next_lin: Option<Linearization>,
}

/// One step of OEPI/OWPI from `x` (whose exact observation is `y`, and `lin` a
/// linearisation there, when at hand): search the linearisation, confirm with an exact
/// pass, relinearise where they disagree.
///
/// The exact pass at the model's optimum runs in one batch of lanes with the
/// finite-difference passes either outcome needs next (this step's settings, to
/// relinearise there if the two disagree; `next`, the following step's, if they agree),
/// which cost little beside it: a step costs one batch of passes instead of two passes
/// in turn, and the results are those of separate passes, bit for bit.
#[allow(clippy::too_many_arguments)]
fn search(
    problem: &Problem<'_>,
    x: X,
    y: &Observation,
    lin: Option<Linearization>,
    (component, next): (Component, &[Setting]),
    criterion: Criterion,
    p: &DisuptParams,
    tally: &AtomicUsize,
) -> Result<Searched, DisuptError> {
    let free = component.settings();
    let base = problem.base_linearization();
    let at_x = |l: &Linearization| l.p_ref == params_of(&x) && l.covers(free);
    let mut lin = match lin {
        Some(l) if at_x(&l) => Cow::Owned(l),
        _ if at_x(base) => Cow::Borrowed(base),
        _ => Cow::Owned(problem.linearize_by(&x, y.clone(), free, tally)),
    };
    let mut which = free.to_vec();
    which.extend(next.iter().filter(|s| !free.contains(s)));
    for _ in 0..MAX_RELINEARISATIONS {
        let x_new = minimise(problem, Some(&lin), x, component, criterion, p, tally)?;
        let mut xs = vec![x_new];
        xs.extend(moved_by_steps(&x_new, &which));
        let mut ys = problem.observe_batched_by(&xs, tally);
        let y_new = ys.remove(0);
        let agrees = lin.predict(&params_of(&x_new)).agrees_with(&y_new);
        let there = linearization_of(&x_new, y_new.clone(), &which, ys);
        if agrees {
            return Ok(Searched {
                x: x_new,
                y: y_new,
                next_lin: Some(there),
            });
        }
        lin = Cow::Owned(there);
    }
    let x_new = minimise(problem, None, x, component, criterion, p, tally)?;
    let y_new = problem.observe_by(&x_new, tally);
    Ok(Searched {
        x: x_new,
        y: y_new,
        next_lin: None,
    })
}

fn last_cp(y: &Observation) -> (f64, f64) {
    y.cp_m.last().map_or((f64::NAN, f64::NAN), |c| (c[0], c[1]))
}

fn run_steps(
    problem: &Problem<'_>,
    plan: &[(Component, Criterion)],
    p: &DisuptParams,
) -> Result<MethodResult, DisuptError> {
    let t0 = Instant::now();
    let tally = AtomicUsize::new(0);
    let passes = || tally.load(Ordering::Relaxed);
    let mut x = problem.x0();
    let mut y = problem.base_linearization().y_ref.clone();
    let mut lin = None;
    let mut steps = Vec::new();
    for (i, &(component, criterion)) in plan.iter().enumerate() {
        let before = passes();
        let input = x;
        let next = plan.get(i + 1).map_or(&[][..], |(c, _)| c.settings());
        let done = search(
            problem,
            x,
            &y,
            lin.take(),
            (component, next),
            criterion,
            p,
            &tally,
        )?;
        (x, y, lin) = (done.x, done.y, done.next_lin);
        let (dx_m, dy_m) = last_cp(&y);
        steps.push(Step {
            step: i + 1,
            component,
            criterion,
            input,
            output: x,
            dx_m,
            dy_m,
            evaluations: passes() - before,
        });
    }
    let (dx_m, dy_m) = last_cp(&y);
    Ok(MethodResult {
        x,
        sigma: None,
        dx_m,
        dy_m,
        kryt1: y.kryt1(problem.epochs, &problem.kalman),
        steps,
        evaluations: passes(),
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

/// The joint fit's weighted residuals and their Jacobian in the free parameters, from a
/// linearisation: `r(p) ≈ r0 + A (p − p_ref)`.
struct JointModel {
    r0: DVector<f64>,
    a: DMatrix<f64>,
}

/// Weighted residuals of an observation at parameters `p`: every valid epoch's ΔΘ, ΔΦ
/// (plus the levelling corrections), every control point's ΔX, ΔY, and the static
/// driftz prior.
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
    // A control point held out keeps its rows, at zero, so that row indices stay put.
    for (i, c) in y.cp_m.iter().enumerate() {
        let w = if skip_cp == Some(i) {
            0.0
        } else {
            1.0 / params.position_sigma_m
        };
        r.push(c[0] * w);
        r.push(c[1] * w);
    }
    // At rest the vertical gyro measures driftz directly (method.md): a prior.
    if let Some((dz, sd)) = problem.drift_z_prior_deg_h {
        r.push((p[Setting::DriftZ.index()] - dz) / sd);
    }
    r
}

/// RMS of the attitude residuals (ΔΘ, ΔΦ with the levelling corrections) of the valid
/// epochs, rad.
fn attitude_rms_rad(
    problem: &Problem<'_>,
    y: &Observation,
    p: &[f64; N_PARAMS],
    params: &DisuptParams,
) -> f64 {
    let n = 2 * problem.epochs.valid.iter().filter(|v| **v).count();
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
    fn new(
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

    /// The model's least-squares step `δ` from `p_ref` (Levenberg–Marquardt).
    fn solve(&self) -> Result<DVector<f64>, DisuptError> {
        let (solved, report) = LevenbergMarquardt::new().minimize(LinearStep {
            model: self,
            delta: DVector::zeros(self.a.ncols()),
        });
        if !report.termination.was_successful() {
            return Err(DisuptError::LeastSquares(format!(
                "{:?}",
                report.termination
            )));
        }
        Ok(solved.delta)
    }
}

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
        let n_att = 2 * problem.epochs.valid.iter().filter(|v| **v).count();
        let rows = n_att..(n_att + 2 * lin.y_ref.cp_m.len()).min(r.len());
        Ok(ssr(&r.as_slice()[rows]))
    }
}

/// The linearised least-squares step in the form the LM crate wants (`δ` from `p_ref`).
struct LinearStep<'m> {
    model: &'m JointModel,
    delta: DVector<f64>,
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for LinearStep<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, d: &DVector<f64>) {
        self.delta.copy_from(d);
    }

    fn params(&self) -> DVector<f64> {
        self.delta.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        Some(&self.model.r0 + &self.model.a * &self.delta)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        Some(self.model.a.clone())
    }
}

/// Gauss–Newton iterations of the joint fit before it stops.
const MAX_GAUSS_NEWTON: usize = 10;

/// Covariance `s²(AᵀA)⁻¹` of the free parameters with the last linearisation (which
/// agreed with the exact pass at the solution, so its slopes hold there), the first `n_att`
/// rows (the attitude residuals `r` interleaves) discounted for their correlation from
/// epoch to epoch.
fn covariance_of(model: &JointModel, r: &[f64], n_att: usize, s2: f64) -> Option<DMatrix<f64>> {
    let inflation = attitude_inflation(&r[..n_att.min(r.len())]);
    let mut a = model.a.clone();
    for i in 0..n_att.min(a.nrows()) {
        a.row_mut(i).unscale_mut(inflation[i % 2].sqrt());
    }
    (a.transpose() * &a).try_inverse().map(|c| c * s2)
}

/// How [`joint_fit`] weighs and what it leaves out.
#[derive(Debug, Clone, Copy, Default)]
pub struct JointOptions<'w> {
    /// Weigh the epochs with this σ (rad) instead of their residuals' RMS (variance
    /// components), so that the costs of several fits compare (the odometer-lag search).
    pub attitude_sigma_rad: Option<f64>,
    /// Leave this control point (index into the problem's fixes) out of the fit.
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
    lin: Linearization,
    weights: DisuptParams,
}

/// The joint estimator.
pub fn joint(problem: &Problem<'_>, p: &DisuptParams) -> Result<MethodResult, DisuptError> {
    joint_fit(problem, p, &JointOptions::default()).map(|f| f.result)
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
    let used_cps = problem.fixes.len() - usize::from(skip.is_some_and(|i| i < problem.fixes.len()));
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
    let rows = model.r0.len() - if skip.is_some() { 2 } else { 0 };
    let dof = (rows as f64 - free.len() as f64).max(1.0);
    let r = joint_residuals(problem, &y, &pr, &w, skip);
    let n_att = 2 * problem.epochs.valid.iter().filter(|v| **v).count();
    let covariance = covariance_of(&model, &r, n_att, cost / dof);
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
    };
    let result = MethodResult {
        x,
        sigma,
        dx_m,
        dy_m,
        kryt1: y.kryt1(problem.epochs, &problem.kalman),
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
        lin: lin.clone(),
        weights: w,
    })
}

impl JointFit {
    /// The linearisation that holds at the solution.
    pub fn linearization(&self) -> &Linearization {
        &self.lin
    }
}

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
