//! Stage 4, disupt: OEPI, OWPI and the joint estimator on one run →
//! `disupt.json`, `disupt.md` (the paper's Tables 1 and 2) and `corrected_nav.parquet`.

mod coarse_azimuth;
mod exclusions;
mod heights;
mod joint_run;
mod meeting;
mod report;
mod reviews;

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use serde::Serialize;
use unz_formats::atomic::{write_atomic, write_json_atomic};
use unz_formats::manifest::{LogFormat, OdometerKind};
use unz_stages::derive::Derived;
use unz_stages::disupt::{self, HeightError, OdoPitchFit, Problem, ProblemSpec, X};
use unz_stages::earth::Geodetic;
use unz_stages::odo_lag::Rederive;
use unz_stages::odo_rebridge::Rebridges;
use unz_stages::route_sigma::{RouteBase, RouteSigma};
use unz_stages::strapdown::{self, NavInputs, NavSettings};
use unz_stages::units::DEG_PER_H;

pub use coarse_azimuth::{Coarse, CoarseRefused, coarse_azimuth, coarse_refused_note};
use joint_run::{
    ClassicResult, JointInputs, joint_route_sigma, lag_pass, route_stride, run_methods,
};
use meeting::Meeting;
pub use report::{
    DisuptOut, MARK_ARM_REFIT_SIGMA, MARK_ARM_SIGMA, MarkArmCheck, MethodOut, ODO_YAW_REFIT_Z,
    OdoYawCheck, Outcome, SettingsOut, SigmaOut, joint_mark_arm_note, mark_arm_note,
    odo_pitch_note, odo_yaw_note, rebridged_note,
};
use report::{Lag, markdown, method_out, settings_out};
use reviews::{Reviewed, classic_reviewed, review_batch, review_passes, untracked_reviews};

use crate::artifacts::{StageName, files};
use crate::derive_io::{StoredDerive, read_velocity_ranges};
use crate::flow::{
    Cores, IngestedSeries, NavCase, Overrides, Params, RunCtx, ensure_derive, load_case,
    site_gravity_mps2,
};
use crate::method_tables::{
    KRYT1_SERIES, KeptTrack, MethodKryt1, TRACKS, TracksWriter, track_samples, track_times,
    write_kryt1_series,
};
use crate::nav_writer::{NavWriter, NavWritten, SigmaApart, SigmaColumns};
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
        excluded_cps: &[],
        drift_z_prior_deg_h: prior,
        gyro_walk: Some(&case.gyro_walk),
    }
}

/// Brings derive up to date and returns the files a whole-run optimisation reads: the
/// manifest, the derived series (the increments the ingest's IMU table's, repaired) and
/// epochs, the control-point marks and the odometer.
pub fn case_inputs(ctx: &RunCtx, params: &Params) -> anyhow::Result<Vec<PathBuf>> {
    let derive_dir = ensure_derive(ctx, params)?;
    let ingest_dir = ctx.layout().dir(StageName::Ingest);
    Ok(vec![
        ctx.manifest.path.clone(),
        derive_dir.join(files::DERIVED),
        derive_dir.join(files::IMU_REPAIRS),
        derive_dir.join(files::EPOCHS),
        derive_dir.join(files::BLOCKS),
        ingest_dir.join(files::IMU),
        ingest_dir.join(files::MARKS),
        ingest_dir.join(files::ODOMETER),
    ])
}

/// Samples of a run up to which its review passes run before the joint fit's hold-out
/// is done: the initial settings', OWPI's and OEPI's in one batch of lanes after OEPI
/// and OWPI, while the joint fit ends; the joint's beside its hold-out (two hours at
/// 100 Hz: their tracks are then held through the joint fit, and its segments, about 11
/// MB, and the ingested odometer, about 10 MB, through the reviews; a longer run lets
/// them go first, then runs its reviews in two batches side by side).
pub const REVIEWS_BESIDE_HOLDOUT_MAX_SAMPLES: usize = 720_000;

/// Samples of a run up to which the corrected route's boresight probe, then its pass and
/// the tables, run beside the route's σ, whose columns of `corrected_nav.parquet` are
/// encoded apart once it is known (about four hours at 100 Hz: the file's first row group,
/// about 20 MB encoded, is then held until the σ's; a longer run probes first, then
/// writes the tables beside the σ and the corrected navigation). Measured: the 40-minute
/// disupt process 10 ms faster with the probe beside the σ (of 0.25 s) and 21 ms more with
/// the pass beside it, four hours 0.1 s and 0.3 s (of 2.5 s), but twelve hours about 0.1
/// s slower with the probe beside the σ.
pub const TAIL_BESIDE_SIGMA_MAX_SAMPLES: usize = 1_500_000;

/// How many times OWPI's Kryt1 OEPI's may be before its settings are not used: over 21
/// runs (17 simulated, Kingston, logs begun while driving) OEPI's was at most 1.36 times
/// OWPI's (OEPI within 0.3° of the truth); on 24 routes looping back to within 10–70 m of
/// their start, every OEPI more than 3.5° off had at least 3.67 times OWPI's.
pub const OEPI_KRYT1_OVER_OWPI_MAX: f64 = 2.0;

/// Why OEPI's settings (of Kryt1 `oepi_kryt1_rad`) do not correct the run, when they fit
/// the log's pitch and roll much worse than OWPI's (`owpi_kryt1_rad`, the Kryt1 minimum,
/// when OWPI ran: more than [`OEPI_KRYT1_OVER_OWPI_MAX`] times) or worse than the initial
/// settings' (`before_kryt1_rad`). OEPI fits its azimuth and vertical drift by the control
/// points alone; when those say little of them (points near the start: a route looping
/// back to its start point) or are wrong, OEPI follows them where the log's pitch and roll
/// do not (measured on such loops: OEPI 4–20° off, OWPI within 1.2°).
fn oepi_refusal(
    oepi_kryt1_rad: f64,
    owpi_kryt1_rad: Option<f64>,
    before_kryt1_rad: f64,
) -> Option<String> {
    let than = if let Some(owpi) =
        owpi_kryt1_rad.filter(|&owpi| oepi_kryt1_rad > OEPI_KRYT1_OVER_OWPI_MAX * owpi)
    {
        format!(
            "more than {OEPI_KRYT1_OVER_OWPI_MAX} times worse than OWPI's (Kryt1 {oepi_kryt1_rad:.2} against {owpi:.2})"
        )
    } else if oepi_kryt1_rad > before_kryt1_rad {
        format!(
            "worse than the initial settings' (Kryt1 {oepi_kryt1_rad:.2} against {before_kryt1_rad:.2})"
        )
    } else {
        return None;
    };
    Some(format!(
        "its settings fit the log's pitch and roll {than}: its azimuth and \
         vertical drift, fitted by the control points alone, are not what the log shows (the \
         control points lie too near the start to fix the azimuth, or are wrong)"
    ))
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
        // 6: of a control point marked more than once, the last mark at rest.
        // 7: each hold-out's predicted σ and whether the point is consistent; a start
        //    levelled in motion is fitted over the log's first minute.
        // 8: a coarse azimuth the pitch and roll refuse is not taken, nor OEPI's settings
        //    when they fit the pitch and roll far worse than OWPI's or the initial
        //    settings'; a run that never drives is not corrected.
        // 9: the coarse turn Kryt1 refuses at the initial drifts is judged again with the
        //    horizontal drifts free.
        // 10: the joint fit's boresight check, and its refit beyond 3σ.
        // 11: the odometer's bridged failures bridged again at each lag the joint tries.
        // 12: control points inconsistent with the rest left out of the joint fit.
        // 13: the vehicle's mark: compared at its lever arm, checked and estimated.
        // 14: a point the route comes back to: each visit, held out and left out together;
        //     the hold-outs carry their stop's time.
        // 15: two points off searched: a pair out of bounds, or one more beside the most
        //     inconsistent when the fit without it leaves its bounds.
        // 16: a failure bridged again refuses a bridge whose speed no land vehicle has,
        //     or across IMU samples more than a second apart.
        // 17: the corrected route's odometer pitch boresight, from the control points'
        //     heights.
        // 18: the heights' fit starts from the vehicle's configured angle; each point's
        //     slope reported.
        // 19: a mounted unit's manifest angles and drifts are turned into the body's.
        // 20: a static start given past the odometer's first sign of motion is cut there.
        // 21: two control points far beyond their hold-out spread are said to disagree.
        // 22: a drift given beyond its bound, which the fit takes back, is blamed.
        // 23: the joint fit takes lost and replaced samples' fills' tilt as unknowns.
        // 24: a fill's miss told by consecutive pairs where too few samples about it
        // have both neighbours kept (a log losing lines regularly).
        // 25: the joint's σ take the gyros' angle random walk and the lag's uncertainty.
        // 26: the hold-outs' predicted spread takes the gyros' walk.
        // 27: the corrected route's σ weighs the heading walk's turn against the fit's
        // uptake of it.
        version: 27,
        params_hash: params_hash(&(params.before_export(), method, dparams))?,
        inputs,
        outputs: &[
            files::DISUPT_REPORT,
            files::DISUPT_TABLES,
            files::CORRECTED_NAV,
            TRACKS,
            KRYT1_SERIES,
        ],
        hashed_as_read: vec![],
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
        // The derive's output first (its own reads side by side), then the run's segments
        // (on both cores: the search's first pass would integrate them on one, the other
        // reading the odometer), then the coarse search of the azimuth (mostly one core's
        // passes) beside the reading of the ingested odometer (the lag's re-derives read
        // it). The segments stay in the derive's memo for every later problem on it.
        let case = load_case(ctx, params, &Overrides::default())?;
        // A coarse search over ±180° of azimuth by the control points first: the run's
        // initial azimuth may be arbitrarily wrong (no static start, a bad manifest).
        let start_problem = problem_of(&case, params);
        start_problem.integrate_segments();
        let (coarse, odometer) = rayon::join(
            || coarse_azimuth(&start_problem, &dparams),
            || IngestedSeries::load_odometer_tags(&ctx.layout().dir(StageName::Ingest)),
        );
        let odometer = odometer?;
        // The odometer's bridged failures are bridged again at each lag the joint fit
        // tries (the ingest's bridges took the lag their readings showed).
        let rebridges = Rebridges::new(
            &case.derived,
            &odometer.distance_m,
            &odometer.failed,
            site_gravity_mps2(m),
            -params.derive.odo_time_offset_s,
            |rows| read_velocity_ranges(&StoredDerive::of(&ctx.layout()), rows),
        )?;
        // The derive stage's output is the configured derive, whole: re-derives at other
        // odometer timings start from it and move the odometer's part only.
        let rederive = Rederive::of_odometer(
            &case.derived,
            &odometer.t_ns,
            &odometer.distance_m,
            params.derive,
            site_gravity_mps2(m),
        )
        .with_rebridges(rebridges);
        lap("loaded and coarse");
        let mut start = case.settings;
        match coarse {
            Coarse::Taken(az) => {
                start.initial.heading_rad = az.to_radians();
                ctx.say(
                    "disupt",
                    &format!("coarse azimuth search: start at {az:.1}°"),
                );
            }
            Coarse::Refused(r) => ctx.say("disupt", &coarse_refused_note(&r)),
            Coarse::Kept => {}
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
        // A short run's review passes of the initial settings, OWPI's and OEPI's (those
        // that ran) follow OEPI and OWPI on their core, while the joint fit (the longer
        // work) ends; a long run's wait until the hold-out is done (see below). With the
        // cores shared with other runs (which use that gap), a short run's review passes
        // all run in one batch of lanes beside the hold-out: the joint's lane is then
        // one more lane in a batch, not a batch of its own (the same files). The samples
        // every method's track keeps (`tracks.parquet` takes their times): a long run's
        // are not held through the methods.
        let beside_holdout = case.derived.t_s.len() <= REVIEWS_BESIDE_HOLDOUT_MAX_SAMPLES;
        let early_kept = beside_holdout.then(|| track_samples(&case.derived));
        let shared = ctx.cores == Cores::Shared;
        let reviews_early = beside_holdout && !shared;
        // Their tracks go into `tracks.parquet` at once, while the joint fit ends (its
        // file is written again should one of them be the corrected route, whose heights
        // its boresight moves).
        let start = case.settings.start();
        let (tracks_path, kryt1s_path) = (dir.join(TRACKS), dir.join(KRYT1_SERIES));
        let early_times = early_kept
            .as_ref()
            .filter(|_| reviews_early)
            .map(|keep| track_times(&case.derived, keep));
        // With the joint fit asked for, each track goes to the file without a copy: the
        // joint's route, when the fit is made, is the corrected one and the file stands;
        // when it is not (or the file fails), the tracks are reviewed again at the end (a
        // lane is its pass alone, bit for bit). Without it, each track is cloned: a
        // corrected route among them takes its boresight and the file is written again.
        let joint_wanted = matches!(method, Method::Joint | Method::All);
        let early_reviews = |classic: &[ClassicResult]| {
            early_kept.as_ref().filter(|_| reviews_early).map(|keep| {
                let lanes = classic_reviewed(x_before, &case.derived, classic);
                let mut outcomes = untracked_reviews(&problem, &lanes, &case.fixes, keep);
                // A file that fails here is written at the end, which says why.
                let tracks = early_times.as_deref().and_then(|t_ns| {
                    let mut file = TracksWriter::create(&tracks_path, t_ns, start).ok()?;
                    for o in &mut outcomes {
                        let track = if joint_wanted {
                            std::mem::take(&mut o.track)
                        } else {
                            o.track.clone()
                        };
                        file.push(track).ok()?;
                    }
                    Some(file)
                });
                (outcomes, tracks)
            })
        };
        let t_methods = std::time::Instant::now();
        let (classic_results, early, joint_result) = run_methods(
            method,
            JointInputs {
                problem: &problem,
                spec: &spec,
                rederive: &rederive,
                case: &case,
                dparams: &dparams,
            },
            early_reviews,
        );
        ctx.say(
            "disupt",
            &format!(
                "methods took {:.2} s{}",
                t_methods.elapsed().as_secs_f64(),
                crate::memory::rss_suffix()
            ),
        );
        let (early_outcomes, early_tracks) =
            early.map_or((None, None), |(outcomes, tracks)| (Some(outcomes), tracks));
        let early_lanes = early_outcomes.as_ref().map_or(0, Vec::len);
        // The joint fit without the control points it left out, and its hold-out when the
        // search for them computed it.
        let mut found = exclusions::Exclusions::default();
        let joint_result = joint_result.map(|r| {
            r.map(|x| {
                found = x.found;
                x.run
            })
        });
        let excluded = std::mem::take(&mut found.excluded);
        if !excluded.is_empty() {
            let ids: Vec<String> = excluded
                .iter()
                .map(|&i| case.fixes[i].id.to_string())
                .collect();
            ctx.say(
                "disupt",
                &format!(
                    "control points left out of the joint fit, inconsistent with the rest: {}",
                    ids.join(", ")
                ),
            );
        }
        if let Some(e) = &found.refit_error {
            ctx.say("disupt", e);
        }
        let kept_samples = early_kept.unwrap_or_else(|| track_samples(&case.derived));
        let joint_run = joint_result.as_ref().and_then(|r| r.as_ref().ok());
        if let Some(note) = joint_run.and_then(|r| r.odo_yaw.as_ref().and_then(odo_yaw_note)) {
            ctx.say("disupt", &note);
        }
        if let Some(note) = joint_run
            .and_then(|r| r.mark_arm.as_ref())
            .and_then(|c| mark_arm_note(c, params.vehicle.mark_arm()))
        {
            ctx.say("disupt", &note);
        }
        let joint_derived = joint_run
            .and_then(|r| r.derived.as_ref())
            .unwrap_or(&case.derived);
        let joint_spec = ProblemSpec {
            excluded_cps: &excluded,
            ..spec
        };
        let joint_problem = joint_spec.on(joint_derived);
        // One exact pass per method's settings, side by side (the joint's on its own
        // derive's odometer): its trajectory, Kryt1 series and control-point errors, for
        // review. In order of preference for the corrected navigation (the initial
        // settings, OWPI, OEPI, then joint): the last one is the corrected navigation.
        let mut methods = std::collections::BTreeMap::new();
        let mut skipped = std::collections::BTreeMap::new();
        let mut reviewed = classic_reviewed(x_before, &case.derived, &classic_results);
        let mut classic_ok = Vec::new();
        for (name, result) in classic_results.into_iter().rev() {
            match result {
                Ok(r) => classic_ok.push((name, r)),
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
        // The joint fit's hold-out (unless the exclusions' search left it): the last work
        // on the segments; beside it, the route σ's pass at the moved lag, the last to read
        // the ingested odometer (a short run's: its increments only, its pass a lane of the
        // σ's batch; a long run's: the pass). A short run's review passes still to run (the
        // joint's alone, or all of them with the cores shared) run beside both; a long
        // run's after them, once the segments and the ingested odometer are let go (at 12
        // hours 50 MB and more beside the reviews' tracks).
        let found_holdout = found.holdout.take();
        let holdout_and_lag = || {
            rayon::join(
                || {
                    joint_run.map(|run| match found_holdout {
                        Some(h) => Ok(h),
                        None => disupt::holdout(&joint_problem, &run.fit, &run.params),
                    })
                },
                || {
                    joint_run.and_then(|run| {
                        lag_pass(
                            run,
                            &problem,
                            &rederive,
                            &case,
                            REVIEWS_BESIDE_HOLDOUT_MAX_SAMPLES,
                        )
                    })
                },
            )
        };
        let reviews = || {
            // The last review pass is the corrected navigation's. When it is the joint's
            // with a covariance, the route's σ reads it as it runs; corrected_nav.parquet is
            // written by a pass of its own once the σ is known (no track of the run's
            // length is kept).
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
            let outcomes = match early_outcomes {
                // The joint's alone, after the others'.
                Some(mut outcomes) => {
                    let joint = &reviewed[outcomes.len()..];
                    outcomes.extend(review_batch(
                        &problem,
                        joint,
                        &case.fixes,
                        &kept_samples,
                        &mut route_base,
                    ));
                    outcomes
                }
                // A short run's in one batch (the cores shared).
                None if beside_holdout && shared => review_batch(
                    &problem,
                    &reviewed,
                    &case.fixes,
                    &kept_samples,
                    &mut route_base,
                ),
                None => review_passes(
                    &problem,
                    &reviewed,
                    &case.fixes,
                    &kept_samples,
                    &mut route_base,
                ),
            };
            (outcomes, route_base)
        };
        let ((holdout, lag_pass), (outcomes, route_base)) = if beside_holdout {
            let (both, outcomes) = rayon::join(holdout_and_lag, reviews);
            drop(rederive);
            drop(odometer);
            case.derived.segments.clear();
            joint_derived.segments.clear();
            lap("hold-out and reviews");
            (both, outcomes)
        } else {
            let both = holdout_and_lag();
            drop(rederive);
            drop(odometer);
            case.derived.segments.clear();
            joint_derived.segments.clear();
            lap("hold-out");
            let outcomes = reviews();
            lap("reviews");
            (both, outcomes)
        };
        let mut tracks: Vec<KeptTrack> = Vec::new();
        let mut kryt1s: Vec<MethodKryt1> = Vec::new();
        let mut cps_of = std::collections::BTreeMap::new();
        let mut before = (f64::NAN, Vec::new());
        let mut kryt1_of_lane = Vec::with_capacity(reviewed.len());
        let mut heights_of_lane = Vec::with_capacity(reviewed.len());
        for (lane, o) in reviewed.iter().zip(outcomes) {
            kryt1_of_lane.push(o.kryt1_rad);
            heights_of_lane.push(o.heights);
            tracks.push(o.track);
            kryt1s.push(o.kryt1_series);
            if lane.name == "initial" {
                before = (o.kryt1_rad, o.cps);
            } else {
                cps_of.insert(lane.name, o.cps);
            }
        }
        let (before_kryt1, before_cps) = before;
        // The corrected navigation is the last lane's, unless that is OEPI's and the log's
        // pitch and roll refuse it: then the one before it (OWPI's, else the initial).
        let mut not_used = std::collections::BTreeMap::new();
        let mut corrected_lane = reviewed.len() - 1;
        let owpi_kryt1 = reviewed
            .iter()
            .position(|lane| lane.name == "owpi")
            .map(|i| kryt1_of_lane[i]);
        if reviewed[corrected_lane].name == "oepi"
            && let Some(why) = oepi_refusal(kryt1_of_lane[corrected_lane], owpi_kryt1, before_kryt1)
        {
            not_used.insert("oepi".to_owned(), why);
            corrected_lane -= 1;
        }
        let corrected_by = (corrected_lane > 0).then(|| reviewed[corrected_lane].name.to_owned());
        // The tracks written while the joint fit ended stand unless the corrected route
        // (whose heights its boresight moves) is among them; when they do not, those given
        // to the file without a copy are reviewed again.
        let early_tracks =
            early_tracks.filter(|file| corrected_lane == 0 || corrected_lane >= file.methods());
        if early_tracks.is_none() && joint_wanted && early_lanes > 0 {
            let again = untracked_reviews(
                &problem,
                &reviewed[..early_lanes],
                &case.fixes,
                &kept_samples,
            );
            for (t, o) in tracks.iter_mut().zip(again) {
                *t = o.track;
            }
        }
        for (name, r) in &classic_ok {
            let cps = cps_of.remove(name).unwrap_or_default();
            methods.insert(
                (*name).to_owned(),
                method_out(r, &case.settings, Lag::default(), cps),
            );
        }
        let joint_cps = cps_of.remove("joint").unwrap_or_default();
        // The corrected route's heights at the control points (those the joint fit kept,
        // when it is the joint's) give its odometer pitch boresight, which its kept track
        // takes too; the initial settings correct nothing.
        let corrected = &reviewed[corrected_lane];
        let pass = heights::CorrectedPass {
            inputs: NavInputs {
                odo_dist_m: &corrected.derived.odo_dist_m,
                ..case.derived.nav_inputs()
            },
            settings: problem.settings(&corrected.x),
            odo_pitch_deg: params.vehicle.odo_pitch_deg,
            fixes: &case.fixes,
            kept_samples: &kept_samples,
        };
        // The corrected route's odometer pitch boresight (its probe pass), which the kept
        // track's heights take.
        let corrected_heights = std::mem::take(&mut heights_of_lane[corrected_lane]);
        let probe_pitch = |track: &mut KeptTrack| {
            (corrected_lane > 0)
                .then(|| {
                    heights::odo_pitch_of(
                        corrected_heights,
                        |h: &HeightError| {
                            corrected.name == "joint"
                                && excluded
                                    .iter()
                                    .any(|&i| h.is_at(case.fixes[i].id, case.fixes[i].t_s))
                        },
                        &pass,
                        track,
                    )
                })
                .flatten()
        };
        // The methods' tracks and Kryt1 series (the corrected one's heights with its
        // boresight).
        let write_tables = |tracks: Vec<KeptTrack>| -> anyhow::Result<()> {
            let (tracks_written, kryt1s_written) = rayon::join(
                || {
                    // Those written while the joint fit ended, when they stand (above);
                    // else every track, anew.
                    let t_ns: Cow<'_, [i64]> = early_times.as_deref().map_or_else(
                        || track_times(&case.derived, &kept_samples).into(),
                        Cow::Borrowed,
                    );
                    let mut file = match early_tracks {
                        Some(file) => file,
                        None => TracksWriter::create(&tracks_path, &t_ns, start)?,
                    };
                    for t in tracks.into_iter().skip(file.methods()) {
                        file.push(t)?;
                    }
                    file.finish()
                },
                move || write_kryt1_series(&kryt1s_path, &kryt1s),
            );
            tracks_written?;
            kryt1s_written?;
            lap("tables");
            Ok(())
        };
        // The route's σ, when the corrected route is the joint fit's with a covariance. Its
        // base and the pass at the moved lag go once it is made, before the rest of the
        // tail has taken its memory (3 MB at 40 minutes).
        let sigma_later = route_base.is_some();
        let route_sigma = || {
            let (route_base, lag_pass) = (route_base, lag_pass);
            let sigma = joint_run.and_then(|run| {
                route_base.as_ref().and_then(|base| {
                    joint_route_sigma(&joint_problem, run, lag_pass.as_ref(), base)
                })
            });
            drop((route_base, lag_pass));
            lap("route sigma");
            sigma
        };
        // The corrected navigation (the best method's, else the initial settings'), written
        // as its pass runs, with its odometer pitch boresight and the route's σ (`sigma`:
        // given, none, or to come at its end).
        let fix_samples: Vec<usize> = case.fixes.iter().map(|f| f.sample).collect();
        let corrected_path = dir.join(files::CORRECTED_NAV);
        let corrected = CorrectedNav {
            path: &corrected_path,
            derived: &case.derived,
            start,
            fix_samples: &fix_samples,
            pass: &pass,
        };
        let write_corrected = |odo_pitch: &Option<OdoPitchFit>, sigma: Option<RouteSigma>| {
            let columns = sigma
                .as_ref()
                .map_or(SigmaColumns::Without, SigmaColumns::With);
            let mut nav = corrected.create(columns)?;
            corrected.run(odo_pitch, &mut nav);
            nav.finish("corrected")
        };
        let say_pitch = |odo_pitch: &Option<OdoPitchFit>| {
            if let Some(fit) = odo_pitch {
                ctx.say("disupt", &odo_pitch_note(fit));
            }
        };
        // A short run's boresight probe runs beside the route's σ, then its corrected
        // navigation's pass and tables (each about a pass's time on one core): the σ
        // columns are encoded beside the pass, the others as the pass goes, by the
        // pass's core until the other comes free of the σ and the tables
        // (`NavWriter::run_helped`); a long run's probe first, then the tables beside the
        // σ and the corrected navigation (at 12 hours the first order is slower, and the
        // held row groups would grow).
        let (odo_pitch, nav) = if case.derived.t_s.len() <= TAIL_BESIDE_SIGMA_MAX_SAMPLES {
            let later = sigma_later;
            let mut nav = corrected.create(if later {
                SigmaColumns::Later
            } else {
                SigmaColumns::Without
            })?;
            let apart = nav.take_sigma_apart();
            let samples = pass.inputs.pass_samples();
            // The file is finished by whichever comes second, the pass or the σ's columns,
            // while the other core writes the tables.
            let meeting = Meeting::new();
            let finish = |(nav, (sigma, apart)): (NavWriter<'_>, SigmaDone)| match apart {
                Some(apart) => Finished::Written(
                    apart
                        .map_err(Into::into)
                        .and_then(|apart| nav.finish_with_sigma("corrected", apart)),
                ),
                // The σ asked for but not made, or made unasked (neither expected): written
                // again.
                None if later || sigma.is_some() => Finished::Again(sigma),
                None => Finished::Written(nav.finish("corrected")),
            };
            let ((odo_pitch, tables, finished), finished_by_sigma) = rayon::join(
                || {
                    let mut tracks = tracks;
                    let odo_pitch = probe_pitch(&mut tracks[corrected_lane]);
                    let (finished, tables) = rayon::join(
                        || {
                            corrected.run(&odo_pitch, &mut nav);
                            meeting.bring_a(nav).map(finish)
                        },
                        || write_tables(tracks),
                    );
                    (odo_pitch, tables, finished)
                },
                || {
                    let sigma = route_sigma();
                    let apart = match (apart, &sigma) {
                        (Some(mut apart), Some(sigma)) => {
                            Some(apart.write(sigma, samples).map(|()| apart))
                        }
                        _ => None,
                    };
                    // Once encoded, the σ goes (0.8 MB at 40 minutes, for the tail's
                    // writers); it is kept only for a file written again without them.
                    let sigma = sigma.filter(|_| apart.is_none());
                    meeting.bring_b((sigma, apart)).map(finish)
                },
            );
            tables?;
            say_pitch(&odo_pitch);
            let nav = match finished.or(finished_by_sigma) {
                Some(Finished::Written(nav)) => nav?,
                Some(Finished::Again(sigma)) => write_corrected(&odo_pitch, sigma)?,
                None => anyhow::bail!("the corrected navigation's pass and its σ never met"),
            };
            (odo_pitch, nav)
        } else {
            let mut tracks = tracks;
            let odo_pitch = probe_pitch(&mut tracks[corrected_lane]);
            say_pitch(&odo_pitch);
            let (tables, nav) = rayon::join(
                || write_tables(tracks),
                || write_corrected(&odo_pitch, route_sigma()),
            );
            tables?;
            (odo_pitch, nav?)
        };
        if let Some(Ok(run)) = &joint_result {
            let mut out = method_out(&run.fit.result, &case.settings, run.lag, joint_cps);
            out.holdout = holdout.transpose()?;
            out.exclusion_error = found.refit_error.take();
            out.refused_with_all_points = found.refused_with_all.take();
            out.lag_profile = run.profile.clone();
            out.rebridged = run.rebridged;
            methods.insert("joint".to_owned(), out);
        }
        let mut odo_pitch = odo_pitch;
        if let Some(fit) = odo_pitch.as_mut().filter(|f| f.applied) {
            fit.measured(&disupt::height_errors_at(&case.fixes, |k| {
                nav.at(k).map(|s| s.pose)
            }));
        }
        let distance_m = case
            .fixes
            .last()
            .and_then(|f| nav.at(f.sample))
            .map_or(nav.distance_m, |s| s.pose.distance_m);
        let (dx, dy) = before_cps
            .last()
            .map_or((f64::NAN, f64::NAN), |k| (k.dx_m, k.dy_m));
        let joint_gap_tilts = methods
            .contains_key("joint")
            .then(|| joint_problem.gap_tilts.as_ref().map(|g| g.summary()))
            .flatten();
        if let Some(g) = &joint_gap_tilts {
            ctx.say("disupt", &report::gap_tilts_note(g));
        }
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
            not_used,
            coarse_azimuth_deg: coarse.taken_deg(),
            coarse_azimuth_refused: coarse.refused(),
            joint_odo_yaw_check: joint_run.and_then(|r| r.odo_yaw.clone()),
            joint_gap_tilts,
            shared_passes: problem.base_passes(),
            mark_lever_arm_m: params.vehicle.mark_arm(),
            joint_mark_arm_check: joint_run.and_then(|r| r.mark_arm.clone()),
            odo_pitch,
            odo_time_offset_s: params.derive.odo_time_offset_s,
            joint_odo_lag_at_bound_s: joint_run
                .map(|r| r.lag.lag_s)
                .filter(|l| l.abs() >= dparams.odo_lag_bound_s * (1.0 - 1e-9)),
        };
        let md = markdown(&m.name, &out, &dparams);
        write_atomic(&dir.join(files::DISUPT_TABLES), md.as_bytes())?;
        write_json_atomic(&dir.join(files::DISUPT_REPORT), &out)?;
        lap("written");
        Ok(())
    })?;
    Ok(dir)
}

/// The route's σ as its side of the stage's tail leaves it: the σ (if made) and its columns
/// encoded for the corrected navigation's file (when that waits for them).
type SigmaDone = (
    Option<RouteSigma>,
    Option<Result<SigmaApart, unz_formats::FileError>>,
);

/// The corrected navigation's file once its pass and its σ met.
enum Finished {
    /// Put in place (or not, with the error).
    Written(anyhow::Result<NavWritten>),
    /// To be written again with this σ (its columns were not made as the writer expected).
    Again(Option<RouteSigma>),
}

/// The corrected navigation's pass and where it goes.
struct CorrectedNav<'c, 'a> {
    path: &'c Path,
    derived: &'a Derived,
    start: Geodetic,
    fix_samples: &'c [usize],
    pass: &'c heights::CorrectedPass<'a>,
}

impl<'a> CorrectedNav<'_, 'a> {
    /// Its file's writer, with the route's σ columns `sigma`.
    fn create<'s>(&self, sigma: SigmaColumns<'s>) -> anyhow::Result<NavWriter<'s>>
    where
        'a: 's,
    {
        Ok(NavWriter::create(
            self.path,
            self.derived,
            self.start,
            sigma,
            self.fix_samples,
        )?)
    }

    /// Runs the pass with the odometer pitch boresight `odo_pitch` (else the configured
    /// one) into `nav` (helped by a free core: [`NavWriter::run_helped`]).
    fn run(&self, odo_pitch: &Option<OdoPitchFit>, nav: &mut NavWriter<'_>) {
        let settings = NavSettings {
            odo_pitch_rad: odo_pitch
                .as_ref()
                .map_or(self.pass.settings.odo_pitch_rad, |f| f.applied_rad()),
            ..self.pass.settings
        };
        nav.run_helped(|sink| strapdown::run(&self.pass.inputs, &settings, sink));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oepi_is_refused_only_when_the_pitch_and_roll_refuse_it() {
        // Within twice OWPI's and below the initial settings': used.
        assert_eq!(oepi_refusal(1.9, Some(1.0), 10.0), None);
        assert_eq!(oepi_refusal(5.0, None, 10.0), None);
        // More than twice OWPI's, or above the initial settings' (OWPI or not).
        let why = oepi_refusal(2.1, Some(1.0), 10.0).unwrap();
        assert!(why.contains("more than 2 times worse than OWPI's (Kryt1 2.10 against 1.00)"));
        let why = oepi_refusal(11.0, None, 10.0).unwrap();
        assert!(why.contains("worse than the initial settings' (Kryt1 11.00 against 10.00)"));
        assert!(oepi_refusal(11.0, Some(10.0), 10.0).is_some());
    }
}
