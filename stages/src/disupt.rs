//! DISUPT: corrections of the initial settings x = [azpocz, driftx, drifty, driftz]
//! (optionally the odometer scale) that minimise the criteria over a whole run.
//!
//! - OEPI (paper Table 1): azpocz by Kryt2, driftz by Kryt2, driftx by Kryt1, drifty by
//!   Kryt1 — bounded one-dimensional Brent searches in sequence.
//! - OWPI (paper Table 2): azpocz by Kryt1, driftz by Kryt1, then (azpocz, driftx,
//!   drifty) by Kryt1 with Nelder–Mead.
//! - joint: Gauss–Newton over x, two levelling corrections and the odometer scale (when
//!   control points make it observable), fed with the raw pitch/roll residual series and
//!   every control point at once; each linearised step is the linear model's least-squares
//!   optimum (QR, then the SVD of R).
//!   A second round re-weights the epochs by their residuals' RMS (variance components:
//!   the epochs' misfit is several mrad, not the assumed 2), so that the control points
//!   weigh what their 1 m says; the covariance `s²(JᵀJ)⁻¹` gives each estimate a 1σ.
//!
//! Every search runs on the linearisation ([`crate::linearized::Linearization`]) of the
//! criteria's inputs around the current settings (one exact pass plus one
//! forward-difference pass per moved setting, in parallel); an exact pass confirms each
//! optimum, and where it disagrees with the model the model is rebuilt there and the
//! search repeated. A step that does not settle that way falls back to searching with
//! exact passes. Kryt2 of a set of control points is their RMS horizontal error. The
//! optimisers work in scaled units (degrees, °/h, ppm) so that their tolerances mean
//! something.
//!
//! Modules: `settings` (what is corrected, in the optimisers' units, and the methods'
//! bounds), `problem` (a run's exact passes and linearisations), `stepwise` (OEPI and
//! OWPI), `joint`, `holdout`, `odo_pitch` (the corrected route's pitch boresight from the
//! control points' heights) and `results` (the tables' rows and each method's result).

mod gap_tilts;
mod gap_turns;
mod gyro_walk;
mod holdout;
mod joint;
mod odo_pitch;
mod problem;
mod results;
mod settings;
mod stepwise;

use argmin::core::Error as ArgminError;

pub use gap_tilts::{GapTiltSteps, GapTilts, MAX_STEPS as MAX_GAP_TILT_STEPS, MIN_STEP_SIGMA_RAD};
pub use gap_turns::MAX_TURN_STEPS as MAX_GAP_TURN_STEPS;
pub use gyro_walk::{GyroWalk, WalkUptake};
pub use holdout::{
    HOLDOUT_INCONSISTENT_SIGMA, HOLDOUT_MIN_POINTS, Holdout, holdout, holdout_median_max_m,
    inconsistent_points_note, median_max,
};
pub use joint::{
    JointFit, JointOptions, MARK_ARM_MIN_POINTS, MarkArmSeen, OdoYawSeen, joint, joint_fit,
    within_bounds,
};
pub use odo_pitch::{
    HeightError, MAX_AGREED_ODO_PITCH_DEG, MAX_ODO_PITCH_DEG, MIN_DISTANCE_M, OdoPitchFit,
    OdoPitchPoint, OdoPitchRefusal, fit_odo_pitch, height_errors_at, with_slopes,
};
pub use problem::{
    Evaluation, LANES, Problem, ProblemSpec, moved_by_steps, observe_each, points_among, points_of,
    visits_of,
};
pub use results::{Component, Criterion, MethodResult, Step};
pub use settings::{DisuptParams, X, params_of, x_of};
pub use stepwise::{kryt1_with_free_drifts_xy, oepi, owpi};

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
    /// A linear solve failed.
    #[error("linear solve: {0}")]
    Linear(&'static str),
    /// The joint fit moved settings beyond their bounds: the control points and the log
    /// disagree beyond what the settings explain ([`DisuptParams::bound`]).
    #[error(
        "the fit left its bounds ({0}): the control points and the log disagree beyond what \
         the settings explain (a control point's coordinates or mark, the site (the run's \
         start), the odometer's scale, or a setting given, are wrong)"
    )]
    OutOfBounds(String),
    /// The vehicle hardly moved: nothing DISUPT corrects is observable.
    #[error(
        "the vehicle travelled {0:.1} m by its odometer, less than {MIN_TRAVEL_M} m: nothing \
         the methods correct is observable without motion (at rest the azimuth and the \
         horizontal drifts are confounded, and control points at the start say nothing of \
         the azimuth); the run keeps its initial settings"
    )]
    TooLittleMotion(f64),
}

/// Odometer path below which a run is not corrected, m: a vehicle that did not drive (a
/// static test, a run stopped after its alignment). Measured: such a run (120 s, 0 m) had
/// OEPI 3.0° and OWPI 3.5° off the truth from a 6.5°-off start, the joint fit out of its
/// bounds, and was "corrected" by OEPI.
pub const MIN_TRAVEL_M: f64 = 50.0;
