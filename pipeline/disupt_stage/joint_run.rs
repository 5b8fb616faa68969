//! The methods as the stage runs them: OEPI and OWPI beside the joint fit, the joint at
//! the estimated odometer lag, and the σ of its corrected route.

use rayon::prelude::*;
use unz_stages::derive::Derived;
use unz_stages::disupt::{
    self, JointFit, JointOptions, MethodResult, Problem, ProblemSpec, joint_fit,
};
use unz_stages::odo_lag::{Rederive, joint_with_lag};
use unz_stages::odo_rebridge::Rebridged;
use unz_stages::route_sigma::{
    Moved, Ran, RouteBase, RouteSigma, route_samples, route_sigma, states_along,
};
use unz_stages::strapdown::{NavInputs, NavSettings};

use super::Method;
use super::exclusions::{Excluding, exclude_inconsistent, without_the_point_out_of_bounds};
use super::report::{
    Lag, MARK_ARM_REFIT_SIGMA, MARK_ARM_SIGMA, MarkArmCheck, ODO_YAW_REFIT_Z, OdoYawCheck,
};
use crate::flow::NavCase;

/// The joint fit as the stage ran it: at the estimated odometer lag (with the derive
/// there) or at the configured timing.
pub(super) struct JointRun {
    pub(super) fit: JointFit,
    pub(super) lag: Lag,
    pub(super) profile: Option<Vec<[f64; 2]>>,
    pub(super) derived: Option<Derived>,
    /// The parameters of the fit (the stage's, with `joint_odo_yaw` on when the check
    /// below redid the fit): the hold-out's fits take them.
    pub(super) params: disupt::DisuptParams,
    /// The odometer yaw boresight check of a fit that held it at zero.
    pub(super) odo_yaw: Option<OdoYawCheck>,
    /// The mark's lever arm the fit's control points showed beyond the configured one,
    /// when the fit held it.
    pub(super) mark_arm: Option<MarkArmCheck>,
    /// The odometer's failures bridged again at each lag, and what that changed at the
    /// estimated one.
    pub(super) rebridged: Option<Rebridged>,
}

/// Step of the lag in the route's sensitivity, s.
const LAG_STEP_S: f64 = 0.05;

/// Whether the route's σ of `run` has a lag part: a lag estimated with a σ, and a
/// covariance for the rest.
fn route_sigma_has_lag(run: &JointRun) -> bool {
    run.fit.covariance.is_some() && run.profile.is_some() && run.lag.sigma_s > 0.0
}

/// The route σ's pass at the joint fit's lag moved by [`LAG_STEP_S`] (when
/// [`route_sigma_has_lag`]), as the ingested odometer leaves it: its states at the
/// route's samples (a long run's, whose odometer increments are not kept), or its
/// odometer increments, with which it runs as one more lane of the σ's batch of passes
/// (a run of up to `increments_max_samples` samples: a lane there costs less than a pass
/// of its own, and the increments, 8 bytes a sample, are held until then).
pub(super) enum LagPass {
    /// Its (north, east, heading) at the route's samples.
    States(Vec<[f64; 3]>),
    /// Its odometer's increments, m, and its settings.
    Increments {
        odo_dist_m: Vec<f64>,
        settings: NavSettings,
    },
}

/// [`LagPass`] of the joint fit's lag moved by [`LAG_STEP_S`] (when
/// [`route_sigma_has_lag`]), taken while the ingested odometer is at hand: the pass's
/// increments for a run of up to `increments_max_samples` samples, else its states. Taken
/// for the fit the stage keeps only (a fit redone for a boresight, an arm or a point left
/// out had its own).
pub(super) fn lag_pass(
    run: &JointRun,
    problem: &Problem<'_>,
    rederive: &Rederive<'_>,
    case: &NavCase,
    increments_max_samples: usize,
) -> Option<LagPass> {
    route_sigma_has_lag(run).then(|| {
        let d = &case.derived;
        let odometer = rederive.odometer_at(run.lag.lag_s + LAG_STEP_S);
        let settings = problem.settings(&run.fit.result.x);
        if d.dt_s.len() <= increments_max_samples {
            return LagPass::Increments {
                odo_dist_m: odometer.increments().collect(),
                settings,
            };
        }
        let samples = route_samples(d.dt_s.len(), route_stride(&d.dt_s));
        LagPass::States(states_along(
            &d.nav_inputs(),
            odometer.increments(),
            &settings,
            &samples,
        ))
    })
}

/// σ of the joint's corrected route (`base`, taken from the pass at its settings): the fit's
/// covariance through one moved pass per estimated setting, and the lag's variance
/// through the pass at the moved lag (`lag`, [`lag_pass`], when [`route_sigma_has_lag`]):
/// its states, or a lane beside the moved passes on its increments.
pub(super) fn joint_route_sigma(
    problem: &Problem<'_>,
    run: &JointRun,
    lag: Option<&LagPass>,
    base: &RouteBase<'_>,
) -> Option<RouteSigma> {
    let fit = &run.fit;
    let cov = fit.covariance.as_ref()?;
    let x = fit.result.x;
    // The mark moves no pass (only what the control points are compared with): its
    // settings leave the route, and their rows the covariance (the others' marginal).
    let kept: Vec<usize> = (0..fit.free.len())
        .filter(|&i| !fit.free[i].is_mark_arm())
        .collect();
    let free: Vec<_> = kept.iter().map(|&i| fit.free[i]).collect();
    let mut moved: Vec<Moved<'_>> = disupt::moved_by_steps(&x, &free)
        .iter()
        .zip(&free)
        .map(|(xs, s)| Moved {
            inputs: problem.inputs,
            settings: problem.settings(xs),
            step: s.fd_step(),
        })
        .collect();
    let m = moved.len();
    let mut c = if kept.len() == fit.free.len() {
        cov.clone()
    } else {
        cov.select_rows(&kept).select_columns(&kept)
    };
    let mut ran = Vec::new();
    // Present only when the route σ has a lag part: the last parameter either way.
    if let Some(lag) = lag {
        match lag {
            LagPass::States(states) => ran.push(Ran {
                states,
                step: LAG_STEP_S,
            }),
            LagPass::Increments {
                odo_dist_m,
                settings,
            } => moved.push(Moved {
                inputs: NavInputs {
                    odo_dist_m,
                    ..problem.inputs
                },
                settings: *settings,
                step: LAG_STEP_S,
            }),
        }
        c = c.resize(m + 1, m + 1, 0.0);
        c[(m, m)] = run.lag.sigma_s * run.lag.sigma_s;
        // The lag's covariance with the settings, where its search gave it.
        if let Some(lc) = &fit.lag_covariance {
            for (a, &i) in kept.iter().enumerate() {
                c[(a, m)] = lc[i];
                c[(m, a)] = lc[i];
            }
        }
    }
    // How the kept settings (and the lag, where the uptake has its row and the σ its
    // pass) took up the heading's walk.
    let uptake = (fit.walk_uptake.as_ref()).map(|u| {
        let mut rows = kept.clone();
        if lag.is_some() && u.settings == fit.free.len() + 1 {
            rows.push(fit.free.len());
        }
        u.select(&rows)
    });
    Some(route_sigma(base, &moved, &ran, &c, uptake.as_ref()))
}

/// Samples between the route σ's values: 0.1 s.
pub(super) fn route_stride(dt_s: &[f64]) -> usize {
    (0.1 / dt_s.first().copied().unwrap_or(0.01)).round() as usize
}

/// What the joint fit runs on: the methods' shared problem and its spec (with the control
/// points the fit leaves out), the re-derives at other odometer lags, the case and the
/// parameters.
#[derive(Clone, Copy)]
pub(super) struct JointInputs<'p> {
    pub(super) problem: &'p Problem<'p>,
    pub(super) spec: &'p ProblemSpec<'p>,
    pub(super) rederive: &'p Rederive<'p>,
    pub(super) case: &'p NavCase,
    pub(super) dparams: &'p disupt::DisuptParams,
}

/// A classic method's name and result.
pub(super) type ClassicResult = (&'static str, Result<MethodResult, disupt::DisuptError>);

/// OEPI and OWPI (those `method` asks for) and the joint fit, concurrently (they share the
/// problem's first linearisation). The joint fit estimates the odometer's lag when asked
/// and the run has two control points or more, and is redone without the control points
/// inconsistent with the rest ([`exclude_inconsistent`]; its hold-out's passes beside
/// OEPI's and OWPI's). `after_classic` runs on OEPI's and OWPI's results as soon as they
/// are known, beside the joint fit (which takes longer).
pub(super) fn run_methods<T: Send>(
    method: Method,
    joint: JointInputs<'_>,
    after_classic: impl FnOnce(&[ClassicResult]) -> T + Send,
) -> (
    Vec<ClassicResult>,
    T,
    Option<Result<Excluding, disupt::DisuptError>>,
) {
    let classic: Vec<Method> = [Method::Oepi, Method::Owpi]
        .into_iter()
        .filter(|w| method == *w || method == Method::All)
        .collect();
    let want_joint = matches!(method, Method::Joint | Method::All);
    let JointInputs {
        problem,
        case,
        dparams,
        ..
    } = joint;
    let travelled_m: f64 = case.derived.odo_dist_m.iter().map(|d| d.abs()).sum();
    if travelled_m < disupt::MIN_TRAVEL_M {
        let refused = || disupt::DisuptError::TooLittleMotion(travelled_m);
        let names = classic.iter().map(|&w| match w {
            Method::Oepi => "oepi",
            _ => "owpi",
        });
        let classic: Vec<ClassicResult> = names.map(|name| (name, Err(refused()))).collect();
        let after = after_classic(&classic);
        return (classic, after, want_joint.then(|| Err(refused())));
    }
    // Every method starts from the problem's first linearisation (OEPI and OWPI at their
    // first step, the joint fit and its lag search at theirs). Built here, before them,
    // its two batches of passes run side by side; built by the first method to ask for
    // it, they ran one after the other on its core while the other methods waited (the
    // other core idle).
    if !classic.is_empty() || want_joint {
        problem.base_linearization();
    }
    let ((classic, after), joint) = rayon::join(
        || {
            let classic = classic
                .par_iter()
                .map(|&w| match w {
                    Method::Oepi => ("oepi", disupt::oepi(problem, dparams)),
                    _ => ("owpi", disupt::owpi(problem, dparams)),
                })
                .collect::<Vec<_>>();
            let after = after_classic(&classic);
            (classic, after)
        },
        || {
            want_joint.then(|| {
                let start = match run_joint(joint) {
                    Ok(run) => Excluding::of(run),
                    Err(e @ disupt::DisuptError::OutOfBounds(_)) => {
                        without_the_point_out_of_bounds(joint, e)?
                    }
                    Err(e) => return Err(e),
                };
                exclude_inconsistent(joint, start)
            })
        },
    );
    (classic, after, joint)
}

/// The joint fit checked for a boresight ([`run_joint_yaw_checked`]), then, when it held the
/// vehicle's mark at the configured arm, checked for the arm its control points show
/// ([`disupt::JointFit::mark_arm_seen`], no pass): seen beyond [`MARK_ARM_REFIT_SIGMA`]
/// (and `joint_mark_arm` not set), the fit is redone with the mark free, its lag searched
/// again, and kept when its estimate is beyond [`MARK_ARM_SIGMA`]. The check holds the
/// lag, which takes part of an arm along the vehicle; the refit does not.
pub(super) fn run_joint(x: JointInputs<'_>) -> Result<JointRun, disupt::DisuptError> {
    let mut run = run_joint_yaw_checked(x)?;
    if run.params.joint_mark_arm == Some(true) {
        return Ok(run);
    }
    let Ok(Some(seen)) = on_fitted_problem(&run, &x, |p| run.fit.mark_arm_seen(p)) else {
        return Ok(run);
    };
    let mut check = MarkArmCheck {
        seen,
        estimated: None,
        refit: false,
        refit_error: None,
    };
    if seen.distance_sigma > MARK_ARM_REFIT_SIGMA && run.params.joint_mark_arm.is_none() {
        let with_arm = disupt::DisuptParams {
            joint_mark_arm: Some(true),
            ..run.params
        };
        // As for the boresight's refit: the fit's derive is let go meanwhile.
        let lag_derive = run.derived.take().map(|_| run.lag.lag_s);
        match run_joint_yaw_checked(JointInputs {
            dparams: &with_arm,
            ..x
        }) {
            Ok(refit) => {
                check.estimated = refit.fit.mark_arm_estimate();
                if check
                    .estimated
                    .is_some_and(|a| a.distance_sigma > MARK_ARM_SIGMA)
                {
                    check.refit = true;
                    let odo_yaw = run.odo_yaw.take();
                    run = refit;
                    run.odo_yaw = run.odo_yaw.take().or(odo_yaw);
                }
            }
            Err(e) => check.refit_error = Some(e.to_string()),
        }
        if !check.refit {
            run.derived = lag_derive.map(|lag_s| derive_at_lag(x.rederive, lag_s));
        }
    }
    run.mark_arm = Some(check);
    Ok(run)
}

/// The joint fit ([`fit_joint`]), checked for an odometer yaw boresight when it held it at
/// zero ([`disupt::JointFit::odo_yaw_seen`], one pass): seen beyond [`ODO_YAW_REFIT_Z`] σ,
/// the fit is redone with the boresight free. The control points see a boresight and an
/// azimuth error only as their sum, so the boresight-free fit's azimuth takes the
/// boresight whole, with a σ that does not include it (measured: a 1.5° boresight, the
/// joint azimuth 0.72–1.60° off at σ 0.02–0.18°; refit, 0.03–0.22° off at σ 0.21–0.23°).
fn run_joint_yaw_checked(x: JointInputs<'_>) -> Result<JointRun, disupt::DisuptError> {
    let dparams = x.dparams;
    let mut run = fit_joint(x)?;
    if dparams.joint_odo_yaw {
        return Ok(run);
    }
    let tally = std::sync::atomic::AtomicUsize::new(0);
    let Ok(Some(seen)) = on_fitted_problem(&run, &x, |p| run.fit.odo_yaw_seen(p, &tally)) else {
        return Ok(run);
    };
    let mut check = OdoYawCheck {
        seen,
        refit: false,
        refit_error: None,
    };
    if seen.z() > ODO_YAW_REFIT_Z {
        let with_yaw = disupt::DisuptParams {
            joint_odo_yaw: true,
            ..*dparams
        };
        // The fit's derive at its lag is let go while the refit runs (its odometer's
        // increments, 35 MB at 12 hours, beside the refit's own), and derived again
        // should the refit fail.
        let lag_derive = run.derived.take().map(|_| run.lag.lag_s);
        match fit_joint(JointInputs {
            dparams: &with_yaw,
            ..x
        }) {
            Ok(refit) => {
                check.refit = true;
                run = refit;
            }
            Err(e) => {
                check.refit_error = Some(e.to_string());
                run.derived = lag_derive.map(|lag_s| derive_at_lag(x.rederive, lag_s));
            }
        }
    }
    run.odo_yaw = Some(check);
    Ok(run)
}

/// The derive at the odometer lag `lag_s` a joint fit was fitted on
/// ([`joint_with_lag`]'s, the same bit for bit).
fn derive_at_lag(rederive: &Rederive<'_>, lag_s: f64) -> Derived {
    rederive.at(lag_s).without_block_series()
}

/// `f` of the problem `run`'s fit was fitted on: the stage's, or the one on the derive at
/// the estimated odometer lag.
fn on_fitted_problem<T>(
    run: &JointRun,
    x: &JointInputs<'_>,
    f: impl FnOnce(&Problem<'_>) -> T,
) -> T {
    match &run.derived {
        Some(d) => f(&x.spec.on(d)),
        None => f(x.problem),
    }
}

/// The joint fit, at the estimated odometer lag when there are two control points or more
/// and it is asked for; refused when it leaves its bounds ([`disupt::within_bounds`]).
fn fit_joint(x: JointInputs<'_>) -> Result<JointRun, disupt::DisuptError> {
    let JointInputs {
        problem,
        spec,
        rederive,
        dparams,
        ..
    } = x;
    if dparams.joint_odo_lag && problem.cps_used() >= 2 {
        // On the methods' shared problem: the lag-free fit starts from the same first
        // linearisation as OEPI and OWPI, built once.
        let f = joint_with_lag(rederive, problem, spec, dparams)?;
        let run = JointRun {
            lag: Lag {
                lag_s: f.lag_s,
                sigma_s: f.sigma_s.unwrap_or(0.0),
            },
            profile: Some(f.profile),
            derived: Some(f.derived),
            fit: f.fit,
            params: *dparams,
            odo_yaw: None,
            mark_arm: None,
            rebridged: rederive.rebridges().map(|r| r.changes_at(f.lag_s)),
        };
        disupt::within_bounds(&run.fit, &problem.x0(), dparams)?;
        return Ok(run);
    }
    let fit = joint_fit(problem, dparams, &JointOptions::default())?;
    disupt::within_bounds(&fit, &problem.x0(), dparams)?;
    Ok(JointRun {
        fit,
        lag: Lag::default(),
        profile: None,
        derived: None,
        params: *dparams,
        odo_yaw: None,
        mark_arm: None,
        rebridged: None,
    })
}
