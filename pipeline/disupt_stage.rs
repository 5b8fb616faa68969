//! Stage 4, disupt: OEPI, OWPI and the joint estimator on one run →
//! `disupt.json`, `disupt.md` (the paper's Tables 1 and 2) and `corrected_nav.parquet`.

use std::fmt::Write as _;
use std::path::PathBuf;

use rayon::prelude::*;
use serde::Serialize;
use unz_formats::atomic::{write_atomic, write_json_atomic};
use unz_formats::manifest::{LogFormat, OdometerKind};
use unz_stages::criteria::{self, ControlPointFix, Kryt1Series, Kryt2};
use unz_stages::derive::Derived;
use unz_stages::disupt::{
    self, Holdout, JointFit, JointOptions, MethodResult, Problem, ProblemSpec, X, joint_fit,
};
use unz_stages::linearized::Observation;
use unz_stages::odo_lag::{Rederive, joint_with_lag};
use unz_stages::route_sigma::{
    Moved, Ran, RouteBase, RouteSigma, route_samples, route_sigma, states_along,
};
use unz_stages::strapdown::{self, LaneBatch, NavInputs, NavSettings, PassSink, ReviewPass};
use unz_stages::units::DEG_PER_H;

use crate::artifacts::{StageName, files};
use crate::flow::{
    IngestedSeries, NavCase, Overrides, Params, RunCtx, ensure_derive, load_case, site_gravity_mps2,
};
use crate::method_tables::{
    KRYT1_SERIES, KeptTrack, MethodKryt1, TRACKS, TrackBuilder, method_kryt1, track_samples,
    write_kryt1_series, write_tracks,
};
use crate::nav_writer::NavWriter;
use crate::stage::{Stage, params_hash};

/// Which methods to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Optimisation with the exact position information (paper Table 1).
    Oepi,
    /// Optimisation without position information (paper Table 2).
    Owpi,
    /// Joint least squares with covariance.
    Joint,
    /// All three.
    All,
}

/// Settings as reported.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct SettingsOut {
    /// Initial azimuth, degrees.
    pub azimuth_deg: f64,
    /// Gyro drifts, rad/s.
    pub drift_rad_s: [f64; 3],
    /// Odometer multiplier relative to the manifest's scale.
    pub odo_scale: f64,
    /// Odometer yaw boresight, degrees (moved by the joint fit only, when asked).
    pub odo_yaw_deg: f64,
    /// Odometer speed bias added while it moves, m/s (moved by the joint fit only, when
    /// asked).
    pub odo_bias_mps: f64,
    /// Odometer lag, s (positive: the odometer reports late), beyond derive's
    /// `odo_time_offset_s`; estimated by the joint fit only.
    pub odo_lag_s: f64,
    /// 1σ of each (joint only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma: Option<SigmaOut>,
}

/// 1σ of the settings.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct SigmaOut {
    /// degrees.
    pub azimuth_deg: f64,
    /// rad/s.
    pub drift_rad_s: [f64; 3],
    /// Multiplier.
    pub odo_scale: f64,
    /// degrees (0 when not estimated).
    pub odo_yaw_deg: f64,
    /// m/s (0 when not estimated).
    pub odo_bias_mps: f64,
    /// s (0 when not estimated).
    pub odo_lag_s: f64,
}

/// Settings and the errors they give: the run before DISUPT, and each method's result.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct Outcome {
    /// The settings.
    pub x: SettingsOut,
    /// ΔX at the last control point, m.
    #[serde(
        skip_serializing_if = "unz_stages::finite::is_absent",
        default = "unz_stages::finite::absent"
    )]
    pub dx_m: f64,
    /// ΔY at the last control point, m.
    #[serde(
        skip_serializing_if = "unz_stages::finite::is_absent",
        default = "unz_stages::finite::absent"
    )]
    pub dy_m: f64,
    /// Kryt1, rad.
    #[serde(
        skip_serializing_if = "unz_stages::finite::is_absent",
        default = "unz_stages::finite::absent"
    )]
    pub kryt1_rad: f64,
    /// Errors at every control point.
    pub control_points: Vec<Kryt2>,
}

/// One method in `disupt.json`: its [`Outcome`] (flattened) and how it got there.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct MethodOut {
    /// Optimised settings and their errors.
    #[serde(flatten)]
    pub outcome: Outcome,
    /// Table rows.
    pub steps: Vec<disupt::Step>,
    /// Navigation passes.
    pub evaluations: usize,
    /// Joint only: the error at each control point when it was left out of the fit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout: Option<Vec<Holdout>>,
    /// Joint only, with the lag estimated: every lag tried (s) and the fit's cost there.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lag_profile: Option<Vec<[f64; 2]>>,
}

/// `disupt.json`.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct DisuptOut {
    /// Distance travelled to the last control point, m.
    #[serde(
        skip_serializing_if = "unz_stages::finite::is_absent",
        default = "unz_stages::finite::absent"
    )]
    pub distance_m: f64,
    /// The initial settings and their errors.
    pub before: Outcome,
    /// Per method.
    pub methods: std::collections::BTreeMap<String, MethodOut>,
    /// Methods that could not run, with the reason.
    pub skipped: std::collections::BTreeMap<String, String>,
    /// The method whose settings made `corrected_nav.parquet`.
    pub corrected_by: Option<String>,
    /// The start of the searches when a coarse search over ±180° of azimuth by the
    /// control points found a better one than the run's initial azimuth, degrees.
    pub coarse_azimuth_deg: Option<f64>,
    /// Passes of the first linearisation, shared by the methods (not in their own
    /// `evaluations`).
    pub shared_passes: usize,
}

/// The odometer lag of a method and its 1σ, s.
#[derive(Debug, Clone, Copy, Default)]
struct Lag {
    lag_s: f64,
    sigma_s: f64,
}

fn settings_out(x: &X, base: &NavSettings, sigma: Option<&X>, lag: Lag) -> SettingsOut {
    let base_scale = base.odo_scale;
    SettingsOut {
        azimuth_deg: x.azimuth_deg.rem_euclid(360.0),
        drift_rad_s: x.drift_deg_h.map(|d| d * DEG_PER_H),
        odo_scale: base_scale * (1.0 + x.odo_ppm * 1e-6),
        odo_yaw_deg: base.odo_yaw_rad.to_degrees() + x.odo_yaw_deg,
        odo_bias_mps: base.odo_bias_mps + x.odo_bias_mps,
        odo_lag_s: lag.lag_s,
        sigma: sigma.map(|s| SigmaOut {
            azimuth_deg: s.azimuth_deg,
            drift_rad_s: s.drift_deg_h.map(|d| d * DEG_PER_H),
            odo_scale: base_scale * s.odo_ppm * 1e-6,
            odo_yaw_deg: s.odo_yaw_deg,
            odo_bias_mps: s.odo_bias_mps,
            odo_lag_s: lag.sigma_s,
        }),
    }
}

fn table(name: &str, r: &MethodOut) -> String {
    let mut s = format!(
        "## {name}\n\n| step | moved | by | azpocz in | driftx in | drifty in | driftz in | azpopt | driftx opt | drifty opt | driftz opt | ΔX [m] | ΔY [m] | passes |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    );
    for st in &r.steps {
        let d = |x: &X, i: usize| format!("{:.6e}", x.drift_deg_h[i] * DEG_PER_H);
        let _ = writeln!(
            s,
            "| {} | {:?} | {:?} | {:.4} | {} | {} | {} | {:.4} | {} | {} | {} | {:.1} | {:.1} | {} |",
            st.step,
            st.component,
            st.criterion,
            st.input.azimuth_deg,
            d(&st.input, 0),
            d(&st.input, 1),
            d(&st.input, 2),
            st.output.azimuth_deg,
            d(&st.output, 0),
            d(&st.output, 1),
            d(&st.output, 2),
            st.dx_m,
            st.dy_m,
            st.evaluations
        );
    }
    if let Some(sd) = &r.outcome.x.sigma {
        let per_h = |v: f64| v / DEG_PER_H;
        let _ = writeln!(
            s,
            "\n1σ: azimuth {:.3}°, drifts [{:.3}, {:.3}, {:.3}] °/h, odometer {:.0} ppm",
            sd.azimuth_deg,
            per_h(sd.drift_rad_s[0]),
            per_h(sd.drift_rad_s[1]),
            per_h(sd.drift_rad_s[2]),
            sd.odo_scale / r.outcome.x.odo_scale * 1e6
        );
        if sd.odo_yaw_deg > 0.0 {
            let _ = writeln!(
                s,
                "\nOdometer yaw boresight {:.3}° ± {:.3}°.",
                r.outcome.x.odo_yaw_deg, sd.odo_yaw_deg
            );
        }
        if sd.odo_bias_mps > 0.0 {
            let _ = writeln!(
                s,
                "\nOdometer speed bias {:.3} m/s ± {:.3} m/s.",
                r.outcome.x.odo_bias_mps, sd.odo_bias_mps
            );
        }
        if r.lag_profile.is_some() {
            let _ = writeln!(
                s,
                "\nOdometer lag {:.3} s ± {:.3} s (positive: it reports late).",
                r.outcome.x.odo_lag_s, sd.odo_lag_s
            );
        }
    }
    if let Some(h) = &r.holdout {
        let _ = writeln!(
            s,
            "\nHold-out (each control point left out of the fit in turn):\n\n| point | ΔX [m] | ΔY [m] |\n|---|---|---|"
        );
        for p in h {
            let _ = writeln!(s, "| {} | {:.2} | {:.2} |", p.id, p.dx_m, p.dy_m);
        }
        if let Some((median, max)) = disupt::holdout_median_max_m(h) {
            let _ = writeln!(s, "\nHold-out error: median {median:.2} m, max {max:.2} m.");
        }
    }
    let _ = writeln!(s, "\n{} passes.\n", r.evaluations);
    s
}

/// The DISUPT problem of a loaded case, with the static start's vertical drift as a
/// prior (its 1σ: the angle random walk averaged over the static start).
pub fn problem_of<'a>(case: &'a NavCase, params: &Params) -> Problem<'a> {
    spec_of(case, case.settings, params).on(&case.derived)
}

/// The DISUPT problem of `case` around `settings`, to be set on a derive (the case's own,
/// or one with the odometer shifted).
pub fn spec_of<'a>(case: &'a NavCase, settings: NavSettings, params: &Params) -> ProblemSpec<'a> {
    let prior = case.initial.drift_z_at_rest_rad_s.map(|dz| {
        let sd = params.align.arw_rad_sqrt_s / case.initial.static_s.max(1.0).sqrt();
        (dz / DEG_PER_H, sd / DEG_PER_H)
    });
    ProblemSpec {
        settings,
        filter: params.derive.filter,
        kalman: params.kalman,
        fixes: &case.fixes,
        drift_z_prior_deg_h: prior,
    }
}

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

/// Brings derive up to date and returns the files a whole-run optimisation reads: the
/// manifest, the derived series and epochs, and the control-point marks.
pub fn case_inputs(ctx: &RunCtx, params: &Params) -> anyhow::Result<Vec<PathBuf>> {
    let derive_dir = ensure_derive(ctx, params)?;
    let ingest_dir = ctx.layout().dir(StageName::Ingest);
    Ok(vec![
        ctx.manifest.path.clone(),
        derive_dir.join(files::DERIVED),
        derive_dir.join(files::EPOCHS),
        derive_dir.join(files::BLOCKS),
        ingest_dir.join(files::MARKS),
    ])
}

/// The joint fit as the stage ran it: at the estimated odometer lag (with the derive
/// there) or at the configured timing.
struct JointRun {
    fit: JointFit,
    lag: Lag,
    profile: Option<Vec<[f64; 2]>>,
    derived: Option<Derived>,
    /// The route σ's pass at the lag moved by [`LAG_STEP_S`], run where the ingested
    /// odometer is at hand: its states at the route's samples (when
    /// [`route_sigma_has_lag`]).
    lag_states: Option<Vec<[f64; 3]>>,
}

/// A method's entry of `disupt.json`.
fn method_out(r: &MethodResult, base: &NavSettings, lag: Lag, cps: Vec<Kryt2>) -> MethodOut {
    MethodOut {
        outcome: Outcome {
            x: settings_out(&r.x, base, r.sigma.as_ref(), lag),
            dx_m: r.dx_m,
            dy_m: r.dy_m,
            kryt1_rad: r.kryt1,
            control_points: cps,
        },
        steps: r.steps.clone(),
        evaluations: r.evaluations,
        holdout: None,
        lag_profile: None,
    }
}

/// Step of the lag in the route's sensitivity, s.
const LAG_STEP_S: f64 = 0.05;

/// Whether the route's σ of `run` has a lag part: a lag estimated with a σ, and a
/// covariance for the rest.
fn route_sigma_has_lag(run: &JointRun) -> bool {
    run.fit.covariance.is_some() && run.profile.is_some() && run.lag.sigma_s > 0.0
}

/// σ of the joint's corrected route (`base`, taken from the pass at its settings): the fit's
/// covariance through one moved pass per estimated setting, and the lag's variance
/// through the pass at the moved lag (its states, `run.lag_states`, when
/// [`route_sigma_has_lag`]).
fn joint_route_sigma(
    problem: &Problem<'_>,
    run: &JointRun,
    base: &RouteBase<'_>,
) -> Option<RouteSigma> {
    let fit = &run.fit;
    let cov = fit.covariance.as_ref()?;
    let x = fit.result.x;
    let moved: Vec<Moved<'_>> = disupt::moved_by_steps(&x, &fit.free)
        .iter()
        .zip(&fit.free)
        .map(|(xs, s)| Moved {
            inputs: problem.inputs,
            settings: problem.settings(xs),
            step: s.fd_step(),
        })
        .collect();
    let m = moved.len();
    let mut c = cov.clone();
    let mut ran = Vec::new();
    // Present only when the route σ has a lag part (see `run_joint`).
    if let Some(states) = run.lag_states.as_deref() {
        ran.push(Ran {
            states,
            step: LAG_STEP_S,
        });
        c = c.resize(m + 1, m + 1, 0.0);
        c[(m, m)] = run.lag.sigma_s * run.lag.sigma_s;
    }
    Some(route_sigma(base, &moved, &ran, &c))
}

/// Samples between the route σ's values: 0.1 s.
fn route_stride(dt_s: &[f64]) -> usize {
    (0.1 / dt_s.first().copied().unwrap_or(0.01)).round() as usize
}

/// `disupt.md`: the paper's tables per method, then the errors before DISUPT.
fn markdown(run: &str, out: &DisuptOut) -> String {
    let mut md = format!("# DISUPT: {run}\n\n");
    for (name, title) in [("oepi", "OEPI"), ("owpi", "OWPI"), ("joint", "JOINT")] {
        if let Some(o) = out.methods.get(name) {
            md += &table(title, o);
        } else if let Some(e) = out.skipped.get(name) {
            md += &format!("## {title}\n\nnot run: {e}\n\n");
        }
    }
    let (dx, dy) = (out.before.dx_m, out.before.dy_m);
    md + &format!(
        "Before DISUPT: ΔX = {dx:.1} m, ΔY = {dy:.1} m at the last control point, after {:.0} m.\n",
        out.distance_m
    )
}

/// A classic method's name and result.
type ClassicResult = (&'static str, Result<MethodResult, disupt::DisuptError>);

/// OEPI and OWPI (those `method` asks for) and the joint fit, concurrently (they share the
/// problem's first linearisation). The joint fit estimates the odometer's lag when asked
/// and the run has two control points or more.
fn run_methods(
    method: Method,
    problem: &Problem<'_>,
    spec: &ProblemSpec<'_>,
    rederive: &Rederive<'_>,
    case: &NavCase,
    dparams: &disupt::DisuptParams,
) -> (
    Vec<ClassicResult>,
    Option<Result<JointRun, disupt::DisuptError>>,
) {
    let classic: Vec<Method> = [Method::Oepi, Method::Owpi]
        .into_iter()
        .filter(|w| method == *w || method == Method::All)
        .collect();
    let want_joint = matches!(method, Method::Joint | Method::All);
    rayon::join(
        || {
            classic
                .par_iter()
                .map(|&w| match w {
                    Method::Oepi => ("oepi", disupt::oepi(problem, dparams)),
                    _ => ("owpi", disupt::owpi(problem, dparams)),
                })
                .collect::<Vec<_>>()
        },
        || want_joint.then(|| run_joint(problem, spec, rederive, case, dparams)),
    )
}

/// The joint fit, at the estimated odometer lag when there are two control points or more
/// and it is asked for.
fn run_joint(
    problem: &Problem<'_>,
    spec: &ProblemSpec<'_>,
    rederive: &Rederive<'_>,
    case: &NavCase,
    dparams: &disupt::DisuptParams,
) -> Result<JointRun, disupt::DisuptError> {
    if dparams.joint_odo_lag && case.fixes.len() >= 2 {
        // On the methods' shared problem: the lag-free fit starts from the same first
        // linearisation as OEPI and OWPI, built once.
        let f = joint_with_lag(rederive, problem, spec, dparams)?;
        let mut run = JointRun {
            lag: Lag {
                lag_s: f.lag_s,
                sigma_s: f.sigma_s.unwrap_or(0.0),
            },
            profile: Some(f.profile),
            derived: Some(f.derived),
            fit: f.fit,
            lag_states: None,
        };
        if route_sigma_has_lag(&run) {
            // The route σ's pass at the moved lag, now that the ingested odometer is at
            // hand (beside OEPI and OWPI when they still run): only its states at the
            // route's samples are kept, not its odometer increments.
            let d = &case.derived;
            let samples = route_samples(d.dt_s.len(), route_stride(&d.dt_s));
            let odometer = rederive.odometer_at(run.lag.lag_s + LAG_STEP_S);
            run.lag_states = Some(states_along(
                &d.nav_inputs(),
                odometer.increments(),
                &problem.settings(&run.fit.result.x),
                &samples,
            ));
        }
        return Ok(run);
    }
    Ok(JointRun {
        fit: joint_fit(problem, dparams, &JointOptions::default())?,
        lag: Lag::default(),
        profile: None,
        derived: None,
        lag_states: None,
    })
}

/// One set of settings to review: a method's (or the initial ones) and the derive its
/// pass runs on.
struct Reviewed<'d> {
    name: &'static str,
    x: X,
    derived: &'d Derived,
}

/// What a review pass gives of one set of settings.
struct ReviewOutcome {
    kryt1_rad: f64,
    cps: Vec<Kryt2>,
    track: KeptTrack,
    kryt1_series: MethodKryt1,
}

/// The review passes of `reviewed` (at most [`strapdown::MAX_LANES`]), side by side,
/// each on its own derive's odometer (the derives share their IMU series), their tracks
/// at the samples `keep`; the last one's every sample into `track`. Each outcome is what
/// the pass alone gives.
fn review_passes(
    problem: &Problem<'_>,
    reviewed: &[Reviewed<'_>],
    fixes: &[ControlPointFix],
    keep: &[usize],
    track: &mut (impl PassSink + Send),
) -> Vec<ReviewOutcome> {
    let n = reviewed[0].derived.nav_inputs().len();
    let at: Vec<usize> = fixes.iter().map(|f| f.sample).filter(|&k| k < n).collect();
    // Two batches side by side: the tracked (last) method alone, as it also feeds every
    // sample to `track` (the route σ's states: the longer work per sample), and the
    // others (at 12 h: 0.38-0.40 s against 0.48-0.51 in one batch, 0.42-0.44 in halves).
    let (first, rest) = reviewed.split_at(reviewed.len() - 1);
    let (mut passes, rest) = rayon::join(
        || review_lanes(problem, first, keep, &at, &mut None::<strapdown::NavTrack>),
        || review_lanes(problem, rest, keep, &at, track),
    );
    passes.extend(rest);
    reviewed
        .par_iter()
        .zip(passes)
        .map(|(r, mut pass)| {
            let d = r.derived;
            let mut series = Kryt1Series::default();
            let kryt1_rad = criteria::kryt1_from_blocks(
                &d.epochs,
                &problem.lp,
                std::mem::take(&mut pass.criteria.blocks),
                &problem.kalman,
                Some(&mut series),
            );
            let cps = criteria::kryt2_at(fixes, |k| pass.criteria.position_at(k));
            ReviewOutcome {
                kryt1_rad,
                cps,
                track: pass.rows.map(TrackBuilder::finish).unwrap_or_default(),
                kryt1_series: method_kryt1(r.name, d, &series),
            }
        })
        .collect()
}

/// The passes of the methods `reviewed` side by side, the last one also feeding every
/// sample to `track`.
fn review_lanes<'d, S: PassSink>(
    problem: &Problem<'_>,
    reviewed: &[Reviewed<'d>],
    keep: &[usize],
    at: &[usize],
    track: &mut S,
) -> Vec<ReviewPass<Option<TrackBuilder>>> {
    strapdown::in_lanes(
        reviewed.len(),
        &mut ReviewBatch {
            problem,
            reviewed,
            keep,
            at,
            track,
        },
    )
}

/// [`review_passes`]' lanes.
struct ReviewBatch<'r, 'd, 'p, S> {
    problem: &'r Problem<'p>,
    reviewed: &'r [Reviewed<'d>],
    keep: &'r [usize],
    at: &'r [usize],
    track: &'r mut S,
}

impl<'r, 'd, S: PassSink> LaneBatch for ReviewBatch<'r, 'd, '_, S> {
    type Out = ReviewPass<Option<TrackBuilder>>;

    fn run<const N: usize>(&mut self, points: [usize; N]) -> [Self::Out; N] {
        let reviewed = self.reviewed;
        let last = reviewed.len() - 1;
        let settings = points.map(|i| self.problem.settings(&reviewed[i].x));
        let odometers = points.map(|i| &reviewed[i].derived.odo_dist_m[..]);
        let tracked = points.iter().position(|&i| i == last).unwrap_or(0);
        // Each method's trajectory is built as its lane runs (none for a lane that
        // repeats the one before).
        let rows = std::array::from_fn(|l| {
            (l == 0 || points[l] != points[l - 1]).then(|| {
                let r = &reviewed[points[l]];
                TrackBuilder::new(r.name, self.keep.len())
            })
        });
        strapdown::run_review(
            &reviewed[0].derived.nav_inputs(),
            odometers,
            &settings,
            self.problem.lp.block,
            self.at,
            self.keep,
            rows,
            tracked,
            self.track,
        )
    }
}

/// Stage 4.
pub fn ensure_disupt(ctx: &RunCtx, params: &Params, method: Method) -> anyhow::Result<PathBuf> {
    let inputs = case_inputs(ctx, params)?;
    let m = &ctx.manifest;
    let dir = ctx.layout().create(StageName::Disupt)?;
    let dparams = params.disupt;
    let stage = Stage {
        dir: dir.clone(),
        name: "disupt",
        version: 5,
        params_hash: params_hash(&(params, method, dparams))?,
        inputs,
        outputs: &[
            files::DISUPT_REPORT,
            files::DISUPT_TABLES,
            files::CORRECTED_NAV,
            TRACKS,
            KRYT1_SERIES,
        ],
    };
    ctx.run_stage(&stage, || {
        let t0 = std::time::Instant::now();
        let lap = |what: &str| {
            ctx.say(
                "disupt",
                &format!(
                    "{what} at {:.3} s{}",
                    t0.elapsed().as_secs_f64(),
                    crate::memory::rss_suffix()
                ),
            )
        };
        // The derive's output and the ingested odometer (the lag's re-derives read it) are
        // read side by side.
        let (case, odometer) = rayon::join(
            || load_case(ctx, params, &Overrides::default()),
            || IngestedSeries::load_odometer_tags(&ctx.layout().dir(StageName::Ingest)),
        );
        let (case, odometer) = (case?, odometer?);
        // The derive stage's output is the configured derive, whole: re-derives at other
        // odometer timings start from it and move the odometer's part only.
        let rederive = Rederive::of_odometer(
            &case.derived,
            &odometer.t_ns,
            &odometer.distance_m,
            params.derive,
            site_gravity_mps2(m),
        );
        lap("loaded");
        // A coarse search over ±180° of azimuth by the control points first: the run's
        // initial azimuth may be arbitrarily wrong (no static start, a bad manifest).
        let coarse = coarse_azimuth_deg(&problem_of(&case, params));
        lap("coarse");
        let mut start = case.settings;
        if let Some(az) = coarse {
            start.initial.heading_rad = az.to_radians();
            ctx.say(
                "disupt",
                &format!("coarse azimuth search: start at {az:.1}°"),
            );
        }
        let spec = spec_of(&case, start, params);
        let problem = spec.on(&case.derived);
        let x_before = X {
            azimuth_deg: case.settings.initial.heading_rad.to_degrees(),
            ..problem.x0()
        };
        // A speed odometer (OBD-II) has a bias worth estimating; pulses and distances not.
        let mut dparams = dparams;
        dparams.joint_odo_bias = Some(dparams.joint_odo_bias.unwrap_or(
            m.format == LogFormat::KfGins && m.odometer.kind != Some(OdometerKind::DistanceM),
        ));
        let t_methods = std::time::Instant::now();
        let (classic_results, joint_result) =
            run_methods(method, &problem, &spec, &rederive, &case, &dparams);
        ctx.say(
            "disupt",
            &format!(
                "methods took {:.2} s{}",
                t_methods.elapsed().as_secs_f64(),
                crate::memory::rss_suffix()
            ),
        );
        // The ingested odometer and its re-derives go before the review passes (the route
        // σ's pass at the moved lag ran with the joint).
        let joint_run = joint_result.as_ref().and_then(|r| r.as_ref().ok());
        drop(rederive);
        drop(odometer);
        let joint_derived = joint_run
            .and_then(|r| r.derived.as_ref())
            .unwrap_or(&case.derived);
        let joint_problem = spec.on(joint_derived);

        let start = case.settings.start();
        // One exact pass per method's settings, side by side (the joint's on its own
        // derive's odometer): its trajectory, Kryt1 series and control-point errors, for
        // review. In order of preference for the corrected navigation (the initial
        // settings, OWPI, OEPI, then joint): the last one is the corrected navigation.
        let mut methods = std::collections::BTreeMap::new();
        let mut skipped = std::collections::BTreeMap::new();
        let mut reviewed: Vec<Reviewed<'_>> = vec![Reviewed {
            name: "initial",
            x: x_before,
            derived: &case.derived,
        }];
        let mut classic_ok = Vec::new();
        for (name, result) in classic_results.into_iter().rev() {
            match result {
                Ok(r) => {
                    reviewed.push(Reviewed {
                        name,
                        x: r.x,
                        derived: &case.derived,
                    });
                    classic_ok.push((name, r));
                }
                Err(e) => {
                    skipped.insert(name.to_owned(), e.to_string());
                }
            }
        }
        match &joint_result {
            Some(Ok(run)) => reviewed.push(Reviewed {
                name: "joint",
                x: run.fit.result.x,
                derived: joint_derived,
            }),
            Some(Err(e)) => {
                skipped.insert("joint".to_owned(), e.to_string());
            }
            None => {}
        }
        let corrected_by =
            (reviewed.len() > 1).then(|| reviewed[reviewed.len() - 1].name.to_owned());
        // The last review pass is the corrected navigation's. When it is the joint's with a
        // covariance, the route's σ reads it as it runs; corrected_nav.parquet is written by
        // a pass of its own once the σ is known (no track of the run's length is kept).
        let mut route_base = joint_run
            .filter(|run| run.fit.covariance.is_some())
            .map(|run| {
                let dt_s = joint_problem.inputs.dt_s;
                RouteBase::new(
                    &joint_problem.settings(&run.fit.result.x),
                    dt_s,
                    params.align.arw_rad_sqrt_s,
                    route_stride(dt_s),
                )
            });
        // The samples every method's track keeps; `tracks.parquet` takes their times.
        let kept_samples = track_samples(&case.derived);
        let outcomes = review_passes(
            &problem,
            &reviewed,
            &case.fixes,
            &kept_samples,
            &mut route_base,
        );
        lap("reviews");
        let mut tracks: Vec<KeptTrack> = Vec::new();
        let mut kryt1s: Vec<MethodKryt1> = Vec::new();
        let mut cps_of = std::collections::BTreeMap::new();
        let mut before = (f64::NAN, Vec::new());
        for (lane, o) in reviewed.iter().zip(outcomes) {
            tracks.push(o.track);
            kryt1s.push(o.kryt1_series);
            if lane.name == "initial" {
                before = (o.kryt1_rad, o.cps);
            } else {
                cps_of.insert(lane.name, o.cps);
            }
        }
        let (before_kryt1, before_cps) = before;
        for (name, r) in &classic_ok {
            let cps = cps_of.remove(name).unwrap_or_default();
            methods.insert(
                (*name).to_owned(),
                method_out(r, &case.settings, Lag::default(), cps),
            );
        }
        let joint_cps = cps_of.remove("joint").unwrap_or_default();
        // The methods' tracks and Kryt1 series are written and let go first, so that the
        // hold-out's and the route σ's work never holds memory beside them.
        let (tracks_path, kryt1s_path) = (dir.join(TRACKS), dir.join(KRYT1_SERIES));
        let (tracks_written, kryt1s_written) = rayon::join(
            || {
                let d = &case.derived;
                let t_ns: Vec<i64> = kept_samples
                    .iter()
                    .map(|&k| d.ns_of(d.t_s.get(k)))
                    .collect();
                write_tracks(&tracks_path, &t_ns, start, tracks)
            },
            move || write_kryt1_series(&kryt1s_path, &kryt1s),
        );
        tracks_written?;
        kryt1s_written?;
        lap("tables");
        let mut route_sigma = None;
        if let Some(Ok(run)) = &joint_result {
            let mut out = method_out(&run.fit.result, &case.settings, run.lag, joint_cps);
            // The hold-out's fits and the route's σ are independent: side by side.
            let (holdout, sigma) = rayon::join(
                || disupt::holdout(&joint_problem, &run.fit, &dparams),
                || {
                    route_base
                        .as_ref()
                        .and_then(|base| joint_route_sigma(&joint_problem, run, base))
                },
            );
            out.holdout = Some(holdout?);
            out.lag_profile = run.profile.clone();
            methods.insert("joint".to_owned(), out);
            route_sigma = sigma;
        }
        lap("hold-out and route sigma");
        // The corrected navigation (the best method's, else the initial settings') written
        // as its pass runs.
        let corrected = &reviewed[reviewed.len() - 1];
        let last_fix: Vec<usize> = case.fixes.last().map(|f| f.sample).into_iter().collect();
        let mut nav = NavWriter::create(
            &dir.join(files::CORRECTED_NAV),
            &case.derived,
            start,
            route_sigma.as_ref(),
            &last_fix,
        )?;
        let inputs = NavInputs {
            odo_dist_m: &corrected.derived.odo_dist_m,
            ..case.derived.nav_inputs()
        };
        strapdown::run(&inputs, &problem.settings(&corrected.x), &mut nav);
        let nav = nav.finish("corrected")?;
        let distance_m = last_fix
            .first()
            .and_then(|&k| nav.at(k))
            .map_or(nav.distance_m, |s| s.distance_m);
        let (dx, dy) = before_cps
            .last()
            .map_or((f64::NAN, f64::NAN), |k| (k.dx_m, k.dy_m));
        let out = DisuptOut {
            distance_m,
            before: Outcome {
                x: settings_out(&x_before, &case.settings, None, Lag::default()),
                dx_m: dx,
                dy_m: dy,
                kryt1_rad: before_kryt1,
                control_points: before_cps,
            },
            methods,
            skipped,
            corrected_by,
            coarse_azimuth_deg: coarse,
            shared_passes: problem.base_passes(),
        };
        let md = markdown(&m.name, &out);
        write_atomic(&dir.join(files::DISUPT_TABLES), md.as_bytes())?;
        write_json_atomic(&dir.join(files::DISUPT_REPORT), &out)?;
        lap("written");
        Ok(())
    })?;
    Ok(dir)
}
