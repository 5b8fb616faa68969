//! Stage 4, disupt: OEPI, OWPI and the joint estimator on one run →
//! `disupt.json`, `disupt.md` (the paper's Tables 1 and 2) and `corrected_nav.parquet`.

use std::fmt::Write as _;
use std::path::PathBuf;

use rayon::prelude::*;
use serde::Serialize;
use unz_formats::atomic::{write_atomic, write_json_atomic};
use unz_stages::criteria::{self, Kryt1Scratch, Kryt1Series, Kryt2};
use unz_stages::disupt::{self, MethodResult, Problem, X};
use unz_stages::filter::LowPass;
use unz_stages::simulate::DEG_PER_H;
use unz_stages::strapdown::{NavSettings, NavTrack};

use crate::flow::{NavCase, Overrides, Params, RunCtx, ensure_derive, load_case, write_nav};
use crate::method_tables::{
    KRYT1_SERIES, MethodKryt1, MethodTrack, TRACKS, method_kryt1, method_track, write_kryt1_series,
    write_tracks,
};
use crate::runs::stage_dir;
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
#[derive(Debug, Clone, Serialize)]
pub struct SettingsOut {
    /// Initial azimuth, degrees.
    pub azimuth_deg: f64,
    /// Gyro drifts, rad/s.
    pub drift_rad_s: [f64; 3],
    /// Odometer multiplier relative to the manifest's scale.
    pub odo_scale: f64,
    /// Odometer yaw boresight, degrees (moved by the joint fit only, when asked).
    pub odo_yaw_deg: f64,
    /// 1σ of each (joint only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma: Option<SigmaOut>,
}

/// 1σ of the settings.
#[derive(Debug, Clone, Serialize)]
pub struct SigmaOut {
    /// degrees.
    pub azimuth_deg: f64,
    /// rad/s.
    pub drift_rad_s: [f64; 3],
    /// Multiplier.
    pub odo_scale: f64,
    /// degrees (0 when not estimated).
    pub odo_yaw_deg: f64,
}

/// One method in `disupt.json`.
#[derive(Debug, Clone, Serialize)]
pub struct MethodOut {
    /// Optimised settings.
    pub x: SettingsOut,
    /// ΔX at the last control point, m.
    pub dx_m: f64,
    /// ΔY at the last control point, m.
    pub dy_m: f64,
    /// Kryt1, rad.
    pub kryt1_rad: f64,
    /// Errors at every control point.
    pub control_points: Vec<Kryt2>,
    /// Table rows.
    pub steps: Vec<disupt::Step>,
    /// Navigation passes.
    pub evaluations: usize,
    /// Wall time, s.
    pub wall_s: f64,
}

/// `disupt.json`.
#[derive(Debug, Clone, Serialize)]
pub struct DisuptOut {
    /// Distance travelled to the last control point, m.
    pub distance_m: f64,
    /// Errors with the initial settings.
    pub before: Before,
    /// Per method.
    pub methods: std::collections::BTreeMap<String, MethodOut>,
    /// Methods that could not run, with the reason.
    pub skipped: std::collections::BTreeMap<String, String>,
    /// The method whose settings made `corrected_nav.parquet`.
    pub corrected_by: Option<String>,
    /// Passes of the first linearisation, shared by the methods (not in their own
    /// `evaluations`).
    pub shared_passes: usize,
    /// Wall time of the three methods together (they run concurrently), s.
    pub wall_s: f64,
}

/// Errors before DISUPT.
#[derive(Debug, Clone, Serialize)]
pub struct Before {
    /// Settings.
    pub x: SettingsOut,
    /// ΔX at the last control point, m.
    pub dx_m: f64,
    /// ΔY at the last control point, m.
    pub dy_m: f64,
    /// Kryt1, rad.
    pub kryt1_rad: f64,
    /// Errors at every control point.
    pub control_points: Vec<Kryt2>,
}

fn settings_out(x: &X, base: &NavSettings, sigma: Option<&X>) -> SettingsOut {
    let base_scale = base.odo_scale;
    SettingsOut {
        azimuth_deg: x.azimuth_deg.rem_euclid(360.0),
        drift_rad_s: x.drift_deg_h.map(|d| d * DEG_PER_H),
        odo_scale: base_scale * (1.0 + x.odo_ppm * 1e-6),
        odo_yaw_deg: base.odo_yaw_rad.to_degrees() + x.odo_yaw_deg,
        sigma: sigma.map(|s| SigmaOut {
            azimuth_deg: s.azimuth_deg,
            drift_rad_s: s.drift_deg_h.map(|d| d * DEG_PER_H),
            odo_scale: base_scale * s.odo_ppm * 1e-6,
            odo_yaw_deg: s.odo_yaw_deg,
        }),
    }
}

fn table(name: &str, r: &MethodResult) -> String {
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
    if let Some(sd) = &r.sigma {
        let _ = writeln!(
            s,
            "\n1σ: azimuth {:.3}°, drifts [{:.3}, {:.3}, {:.3}] °/h, odometer {:.0} ppm",
            sd.azimuth_deg, sd.drift_deg_h[0], sd.drift_deg_h[1], sd.drift_deg_h[2], sd.odo_ppm
        );
        if sd.odo_yaw_deg > 0.0 {
            let _ = writeln!(
                s,
                "\nOdometer yaw boresight {:.3}° ± {:.3}°.",
                r.x.odo_yaw_deg, sd.odo_yaw_deg
            );
        }
    }
    let _ = writeln!(s, "\n{} passes in {:.2} s.\n", r.evaluations, r.wall_s);
    s
}

/// The DISUPT problem of a loaded case, with the static start's vertical drift as a
/// prior (its 1σ: the angle random walk averaged over the static start).
pub fn problem_of<'a>(case: &'a NavCase, params: &Params) -> Problem<'a> {
    let lp = LowPass::new(&params.derive.filter, case.derived.nominal_dt_s);
    let mut problem = Problem::new(
        case.inputs(),
        case.settings,
        &case.derived.epochs,
        lp,
        params.kalman,
        &case.fixes,
    );
    if let Some(dz) = case.initial.drift_z_at_rest_rad_s {
        let sd = params.align.arw_rad_sqrt_s / case.initial.static_s.max(1.0).sqrt();
        problem.drift_z_prior_deg_h = Some((dz / DEG_PER_H, sd / DEG_PER_H));
    }
    problem
}

/// Brings derive up to date and returns the files a whole-run optimisation reads: the
/// manifest, the derived series and epochs, and the control-point marks.
pub fn case_inputs(ctx: &RunCtx, params: &Params) -> anyhow::Result<Vec<PathBuf>> {
    let derive_dir = ensure_derive(ctx, params)?;
    let ingest_dir = ctx.out.join(&ctx.manifest.name).join("ingest");
    Ok(vec![
        ctx.manifest.path.clone(),
        derive_dir.join("derived.parquet"),
        derive_dir.join("epochs.parquet"),
        ingest_dir.join("marks.parquet"),
    ])
}

/// Stage 4.
pub fn ensure_disupt(ctx: &RunCtx, params: &Params, method: Method) -> anyhow::Result<PathBuf> {
    let inputs = case_inputs(ctx, params)?;
    let m = &ctx.manifest;
    let dir = stage_dir(&ctx.out, &m.name, "disupt")?;
    let dparams = params.disupt;
    let stage = Stage {
        dir: dir.clone(),
        name: "disupt",
        version: 3,
        params_hash: params_hash(&(params, method, dparams))?,
        inputs,
        outputs: &[
            "disupt.json",
            "disupt.md",
            "corrected_nav.parquet",
            TRACKS,
            KRYT1_SERIES,
        ],
    };
    ctx.run_stage(&stage, || {
        let case = load_case(ctx, params, &Overrides::default())?;
        let problem = problem_of(&case, params);
        let mut methods = std::collections::BTreeMap::new();
        let mut skipped = std::collections::BTreeMap::new();
        let mut md = format!("# DISUPT: {}\n\n", m.name);
        let wanted: &[Method] = match method {
            Method::All => &[Method::Oepi, Method::Owpi, Method::Joint],
            Method::Oepi => &[Method::Oepi],
            Method::Owpi => &[Method::Owpi],
            Method::Joint => &[Method::Joint],
        };
        let mut best: Option<(String, X)> = None;
        let site = (case.settings.lat0_rad, case.settings.lon0_rad, case.settings.h0_m);
        // One exact pass per method's settings: its trajectory, Kryt1 series and control
        // point errors, for review.
        let mut track = NavTrack::default();
        let mut scratch = Kryt1Scratch::default();
        let mut series = Kryt1Series::default();
        let mut tracks: Vec<MethodTrack> = Vec::new();
        let mut kryt1s: Vec<MethodKryt1> = Vec::new();
        let mut review_pass = |name: &str, x: &X, track: &mut NavTrack| -> (f64, Vec<Kryt2>) {
            unz_stages::strapdown::navigate(&case.inputs(), &problem.settings(x), track);
            let k1 = criteria::kryt1(&case.derived.epochs, &problem.lp, track, &problem.kalman, &mut scratch, Some(&mut series));
            tracks.push(method_track(name, &case.derived, track, site));
            kryt1s.push(method_kryt1(name, &case.derived, &series));
            (k1, criteria::kryt2(track, &case.fixes))
        };
        let (before_kryt1, before_cps) = review_pass("initial", &problem.x0(), &mut track);
        // The methods run concurrently (they share the problem's first linearisation).
        let t_methods = std::time::Instant::now();
        let results: Vec<_> = wanted
            .par_iter()
            .map(|&w| match w {
                Method::Oepi => ("oepi", disupt::oepi(&problem, &dparams)),
                Method::Owpi => ("owpi", disupt::owpi(&problem, &dparams)),
                _ => ("joint", disupt::joint(&problem, &dparams)),
            })
            .collect();
        let methods_wall_s = t_methods.elapsed().as_secs_f64();
        // The review passes in order of preference for the corrected navigation (joint,
        // then OEPI, then OWPI), so that the last one leaves the corrected track.
        let rank = |n: &str| ["owpi", "oepi", "joint"].iter().position(|x| *x == n);
        let mut order: Vec<usize> = (0..results.len()).collect();
        order.sort_by_key(|&i| rank(results[i].0));
        let mut cps_of: Vec<Vec<Kryt2>> = vec![Vec::new(); results.len()];
        for i in order {
            if let (name, Ok(r)) = &results[i] {
                cps_of[i] = review_pass(name, &r.x, &mut track).1;
                best = Some(((*name).to_owned(), r.x));
            }
        }
        for ((name, result), cps) in results.into_iter().zip(cps_of) {
            match result {
                Ok(r) => {
                    md += &table(&name.to_uppercase(), &r);
                    methods.insert(
                        name.to_owned(),
                        MethodOut {
                            x: settings_out(&r.x, &case.settings, r.sigma.as_ref()),
                            dx_m: r.dx_m,
                            dy_m: r.dy_m,
                            kryt1_rad: r.kryt1,
                            control_points: cps,
                            steps: r.steps,
                            evaluations: r.evaluations,
                            wall_s: r.wall_s,
                        },
                    );
                }
                Err(e) => {
                    md += &format!("## {}\n\nnot run: {e}\n\n", name.to_uppercase());
                    skipped.insert(name.to_owned(), e.to_string());
                }
            }
        }
        // `track` holds the last review pass: the best method's, else the initial one.
        let distance_m = case.fixes.last().map_or_else(|| track.distance_m.last().copied().unwrap_or(0.0), |f| track.distance_m[f.sample]);
        let (dx, dy) = before_cps.last().map_or((f64::NAN, f64::NAN), |k| (k.dx_m, k.dy_m));
        let out = DisuptOut {
            distance_m,
            before: Before {
                x: settings_out(&problem.x0(), &case.settings, None),
                dx_m: dx,
                dy_m: dy,
                kryt1_rad: before_kryt1,
                control_points: before_cps,
            },
            methods,
            skipped,
            corrected_by: best.map(|b| b.0),
            shared_passes: problem.base_passes(),
            wall_s: methods_wall_s,
        };
        md = format!(
            "{md}Before DISUPT: ΔX = {dx:.1} m, ΔY = {dy:.1} m at the last control point, after {distance_m:.0} m.\n"
        );
        write_tracks(&dir.join(TRACKS), &tracks)?;
        write_kryt1_series(&dir.join(KRYT1_SERIES), &kryt1s)?;
        write_nav(&dir.join("corrected_nav.parquet"), &case.derived, &track, site)?;
        write_atomic(&dir.join("disupt.md"), md.as_bytes())?;
        write_json_atomic(&dir.join("disupt.json"), &out)?;
        Ok(())
    })?;
    Ok(dir)
}
