//! DISUPT and sweeps end to end through the binary on a short simulated run.

use std::path::{Path, PathBuf};

use unz::disupt_stage::DisuptOut;
use unz::flow::Params;
use unz_stages::simulate::TrueSettings;

use crate::util::{
    mcap_chunk_compressions, mcap_messages, python, python_json, read_json, run_until,
    run_until_with, simulated_run, unz_ok, unz_output,
};

#[test]
fn disupt_and_sweep_through_the_binary() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    let run = simulated_run(
        tmp.path(),
        77,
        &["--duration-s", "900", "--azimuth-error-deg", "6"],
    );
    let true_az = read_json::<TrueSettings>(&run.join("truth.json")).azimuth_deg;
    unz_ok(&[
        "disupt",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    // Read back through its one typed definition: a missing field fails here.
    let d: DisuptOut = read_json(&out.join("sim-0077/disupt/disupt.json"));
    let before = d.before.dx_m.hypot(d.before.dy_m);
    assert!(before.is_finite(), "{:?}", d.before);
    let names: Vec<&str> = d.methods.keys().map(String::as_str).collect();
    assert_eq!(names, ["joint", "oepi", "owpi"]);
    for (m, r) in &d.methods {
        assert!(
            r.outcome.dx_m.is_finite() && r.outcome.dy_m.is_finite(),
            "{m}"
        );
        assert!(!r.steps.is_empty() && r.evaluations > 0, "{m}");
    }
    let sigma = d.methods["joint"].outcome.x.sigma.as_ref().unwrap();
    assert!(sigma.azimuth_deg > 0.0, "{sigma:?}");
    let oepi = &d.methods["oepi"];
    let err = oepi.outcome.x.azimuth_deg - true_az;
    let after = oepi.outcome.dx_m.hypot(oepi.outcome.dy_m);
    assert!(err.abs() < 0.5, "OEPI azimuth off by {err}°");
    assert!(
        after < 0.2 * before,
        "OEPI: {after} m after, {before} m before"
    );
    assert_eq!(oepi.steps.len(), 4);
    let md = std::fs::read_to_string(out.join("sim-0077/disupt/disupt.md")).unwrap();
    assert!(md.contains("## OEPI") && md.contains("## OWPI") && md.contains("ΔX"));
    assert!(out.join("sim-0077/disupt/corrected_nav.parquet").is_file());

    // Kryt2 over the azimuth: the minimum lies at the true azimuth (grid step 0.5°).
    let az0 = true_az.round();
    let over = format!("azimuth_deg={}:{}:21", az0 - 5.0, az0 + 5.0);
    unz_ok(&[
        "sweep",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--over",
        &over,
    ]);
    let (_, batches) =
        unz_formats::parquet_io::read_batches(&out.join("sim-0077/sweep/sweep.parquet")).unwrap();
    let b = &batches[0];
    assert_eq!(b.num_rows(), 21);
    let az = unz_formats::tables::f64_column(b, "azimuth_deg").unwrap();
    let k2 = unz_formats::tables::f64_column(b, "kryt2_m").unwrap();
    let best = (0..21).min_by(|&i, &j| k2[i].total_cmp(&k2[j])).unwrap();
    assert!(
        (az[best] - true_az).abs() <= 0.5,
        "Kryt2 smallest at {}°, truth {true_az}°",
        az[best]
    );
}

/// `joint_odo_yaw = true` in the run's `[params.disupt]` makes the joint fit estimate the
/// boresight the simulator put in, and `disupt.json` report it with its σ.
#[test]
fn joint_estimates_an_odometer_boresight_when_configured() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    let run = simulated_run(
        tmp.path(),
        79,
        &["--azimuth-error-deg", "6", "--odo-boresight-deg", "2"],
    );
    let truth: TrueSettings = read_json(&run.join("truth.json"));
    assert_eq!(truth.odo_boresight_deg, 2.0);
    let manifest = run.join("run.toml");
    let mut text = std::fs::read_to_string(&manifest).unwrap();
    text.push_str("\n[params.disupt]\njoint_odo_yaw = true\n");
    std::fs::write(&manifest, text).unwrap();
    unz_ok(&[
        "disupt",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--method",
        "joint",
    ]);
    let d: DisuptOut = read_json(&out.join("sim-0079/disupt/disupt.json"));
    let x = &d.methods["joint"].outcome.x;
    let (yaw, sd) = (x.odo_yaw_deg, x.sigma.as_ref().unwrap().odo_yaw_deg);
    assert!(sd > 0.0 && sd < 0.5, "σ {sd}°");
    assert!(
        (yaw - 2.0).abs() < 3.0 * sd,
        "boresight {yaw}° ± {sd}°, truth 2°"
    );
    assert_eq!(d.before.x.odo_yaw_deg, 0.0);
}

/// Three simulated runs (seeds 70–72, `options` added) in `dir/c`, run to disupt into
/// `dir/o`: the campaign folder, the output folder and its `campaign.md`.
fn pooled_campaign(dir: &Path, options: &[&str]) -> (PathBuf, PathBuf, String) {
    let campaign = dir.join("c");
    let mut args = vec![
        "simulate",
        "--out",
        campaign.to_str().unwrap(),
        "--seed",
        "70",
        "--runs",
        "3",
    ];
    args.extend_from_slice(options);
    unz_ok(&args);
    let out = dir.join("o");
    run_until(&campaign, &out, "disupt");
    let md = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    (campaign, out, md)
}

/// The campaign's run sim-0071 run to disupt with the config file `config` into `dir/oc`:
/// that output folder.
fn configured_run(dir: &Path, campaign: &Path, config: &Path) -> PathBuf {
    let out = dir.join("oc");
    run_until_with(
        &campaign.join("sim-0071"),
        &out,
        "disupt",
        &["--config", config.to_str().unwrap()],
    );
    out
}

/// The campaign's settings file in `out` (`campaign-settings.toml`), as the config's
/// parser reads it: its path and its parameters.
fn campaign_settings(out: &Path) -> (PathBuf, Params) {
    let file = out.join(unz::campaign_settings::FILE);
    let table = unz::config::load(Some(&file)).unwrap();
    let params = unz::config::effective(&table, None).unwrap();
    (file, params)
}

/// The word after `what` in `md` (up to a backtick, a space or an asterisk).
fn after<'a>(md: &'a str, what: &str) -> &'a str {
    md.split(what)
        .nth(1)
        .and_then(|s| s.split(['`', ' ', '*']).next())
        .unwrap_or_else(|| panic!("no {what} in {md}"))
}

/// Three simulated runs of an IMU turned on the vehicle (the odometer 2° right of its x):
/// each joint fit estimates the boresight (1.75–2.08°, σ 0.19–0.29°), the campaign pools
/// them into the IMU's yaw to configure, and with it the increments are the vehicle's:
/// the residuals then show no boresight.
#[test]
fn a_campaign_pools_the_imus_yaw_on_the_vehicle() {
    let tmp = tempfile::tempdir().unwrap();
    let (campaign, out, md) = pooled_campaign(tmp.path(), &["--odo-boresight-deg", "2"]);
    // The settings file: the pooled yaw in the campaign's (default) mounting, and nothing
    // else the runs do not show (their lags are none within their σ).
    let (file, settings) = campaign_settings(&out);
    let [roll, pitch, yaw] = settings.vehicle.imu_mounting_deg;
    // The mean of three runs' σ 0.19–0.29°: 0.13°; the IMU is turned 2° to the left.
    assert!((yaw + 2.0).abs() < 0.4, "{md}");
    assert_eq!((roll, pitch), (0.0, 0.0));
    assert_eq!(settings.derive.odo_time_offset_s, 0.0, "{md}");
    assert_eq!(settings.vehicle.odo_pitch_deg, 0.0, "{md}");
    assert!(
        md.contains(&format!(
            "set `[vehicle] imu_mounting_deg = [0, 0, {yaw:.2}]`"
        )) && md.contains("3 runs' joint fits")
            && !md.contains("disagree"),
        "{md}"
    );
    let configured = configured_run(tmp.path(), &campaign, &file);
    let d: DisuptOut = read_json(&configured.join("sim-0071/disupt/disupt.json"));
    let check = d.joint_odo_yaw_check.expect("checked");
    assert!(!check.refit && check.seen.z() < 3.0, "{check:?}");
    assert!(check.seen.odo_yaw_deg.abs() < 0.5, "{check:?}");
}

/// A simulated IMU pitched 1.5° nose down on its mount (`--odo-pitch-deg 1.5`): the
/// vehicle's path climbs 1.5° above the IMU's x, which dead reckoning leaves out, 340–360 m
/// of height after 13–14 km. The horizontal criteria cannot see it (the corrected route's
/// horizontal errors are the same without it); the control points' heights fit the angle
/// and the corrected navigation takes it. Measured on seeds 70–72: 1.488–1.507°, heights
/// within 0.20–0.54 m RMS of the truth over the whole run.
#[test]
fn the_control_points_heights_give_the_odometers_pitch() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    let run = simulated_run(tmp.path(), 71, &["--odo-pitch-deg", "1.5"]);
    let truth: TrueSettings = read_json(&run.join("truth.json"));
    assert_eq!(truth.odo_pitch_deg, 1.5);
    unz_ok(&[
        "disupt",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let dir = out.join("sim-0071/disupt");
    let d: DisuptOut = read_json(&dir.join("disupt.json"));
    let fit = d.odo_pitch.expect("fitted");
    assert!(fit.applied, "{fit:?}");
    // Two points 6.9 and 13.2 km along: a metre of height error at each is 0.008° and
    // 0.004°; the heights of the truth's route are the simulator's, exact.
    assert!((fit.odo_pitch_deg - 1.5).abs() < 0.03, "{fit:?}");
    for p in &fit.points {
        let without = -p.distance_m * 1.5f64.to_radians().tan();
        assert!((p.dh_before_m - without).abs() < 3.0, "{p:?}");
        assert!(p.dh_m.abs() < 1.0, "{p:?}");
        assert!(p.holdout_dh_m.is_some_and(|h| h.abs() < 1.5), "{p:?}");
    }
    // The whole route's height against the truth's.
    let rms = height_rms_m(
        &dir.join("corrected_nav.parquet"),
        &run.join("truth.parquet"),
    );
    assert!(rms < 1.0, "height RMS {rms} m");
}

/// The corrected route's kept track (`tracks.parquet`) has its corrected navigation's
/// heights, its odometer pitch boresight in them, whichever method corrects it: the joint
/// fit (its track written after the others', which the stage writes while the joint fit
/// ends) or OWPI (one of those: its file written again). The other methods' tracks keep
/// their own heights: the boresight (1.5° here) moves the route's by tens of metres.
#[test]
fn the_corrected_routes_kept_track_takes_its_boresight() {
    use unz::method_tables::read_tracks;
    use unz_formats::parquet_io::read_batches;
    use unz_formats::tables::{f32_column, i64_column};

    let tmp = tempfile::tempdir().unwrap();
    let run = simulated_run(
        tmp.path(),
        71,
        &["--odo-pitch-deg", "1.5", "--duration-s", "900"],
    );
    for (method, corrector) in [("owpi", "owpi"), ("all", "joint")] {
        let out = tmp.path().join(method);
        unz_ok(&[
            "disupt",
            run.to_str().unwrap(),
            "--method",
            method,
            "--out",
            out.to_str().unwrap(),
        ]);
        let dir = out.join("sim-0071/disupt");
        let d: DisuptOut = read_json(&dir.join("disupt.json"));
        assert_eq!(d.corrected_by.as_deref(), Some(corrector));
        assert!(d.odo_pitch.as_ref().is_some_and(|f| f.applied), "{d:?}");
        let (_, nav) = read_batches(&dir.join("corrected_nav.parquet")).unwrap();
        let t_nav: Vec<i64> = nav
            .iter()
            .flat_map(|b| i64_column(b, "t_ns").unwrap())
            .collect();
        let h_nav: Vec<f32> = nav
            .iter()
            .flat_map(|b| f32_column(b, "h_m").unwrap())
            .collect();
        let tracks = read_tracks(&dir.join("tracks.parquet")).unwrap();
        assert_eq!(tracks.len(), if method == "all" { 4 } else { 2 });
        for t in &tracks {
            let worst_m = t
                .t_ns
                .iter()
                .zip(&t.h_m)
                .map(|(k, h)| {
                    let i = t_nav.binary_search(k).expect("a kept sample's time");
                    f64::from((h - h_nav[i]).abs())
                })
                .fold(0.0, f64::max);
            assert_eq!(t.t_ns.len(), 9001, "{}", t.method);
            // The track's heights extrapolate its probe pass's to the angle fitted last:
            // within a few f32 steps of the pass at that angle (1.5e-5 m at 100 m).
            if t.method == corrector {
                assert!(worst_m < 1e-3, "{method}: {} {worst_m} m", t.method);
            } else {
                assert!(worst_m > 50.0, "{method}: {} {worst_m} m", t.method);
            }
        }
    }
}

/// RMS of a navigation's heights (`h_m`) against the truth's at the truth's times, m.
fn height_rms_m(nav: &Path, truth: &Path) -> f64 {
    use unz_formats::parquet_io::read_batches;
    use unz_formats::tables::{f64_column, i64_column};

    let column = |path: &Path, name: &str| -> Vec<f64> {
        let (_, b) = read_batches(path).unwrap();
        b.iter()
            .flat_map(|b| f64_column(b, name).unwrap())
            .collect()
    };
    let times = |path: &Path| -> Vec<i64> {
        let (_, b) = read_batches(path).unwrap();
        b.iter()
            .flat_map(|b| i64_column(b, "t_ns").unwrap())
            .collect()
    };
    let (t_nav, h_nav) = (times(nav), column(nav, "h_m"));
    let (t_true, h_true) = (times(truth), column(truth, "h_m"));
    let errors: Vec<f64> = t_true
        .iter()
        .zip(&h_true)
        .filter_map(|(t, h)| {
            let k = t_nav.binary_search(t).ok()?;
            Some(h_nav[k] - h)
        })
        .collect();
    assert!(errors.len() > 50_000, "{} common samples", errors.len());
    (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt()
}

/// Three simulated runs of one vehicle whose path climbs 1.5° above the IMU's x and whose
/// odometer reports 0.4 s late: the campaign pools their heights' fits into the angle to
/// configure, and their joint fits' lags into the offset; with them set, the navigate
/// stage's route (before any control point is used) has the right heights, and the disupt
/// stage's fits move them by no more than their points show.
#[test]
fn a_campaign_pools_the_odometers_pitch_and_lag_and_the_settings_give_the_heights() {
    let tmp = tempfile::tempdir().unwrap();
    let (campaign, out, md) = pooled_campaign(
        tmp.path(),
        &["--odo-pitch-deg", "1.5", "--odo-lag-s", "0.4"],
    );
    // The settings file holds both, as the sections write them.
    let (file, settings) = campaign_settings(&out);
    let pooled_deg = settings.vehicle.odo_pitch_deg;
    let offset = settings.derive.odo_time_offset_s;
    assert_eq!(
        after(&md, "set `[vehicle] odo_pitch_deg = "),
        format!("{pooled_deg:.3}")
    );
    assert_eq!(
        after(&md, "set `[derive] odo_time_offset_s = "),
        format!("{offset:.3}")
    );
    // The lag: the runs' 0.17–0.45 s (σ 0.12–0.22 s) pool within their mean's 3σ.
    let lag_s: f64 = after(&md, "inverse-variance mean: **").parse().unwrap();
    let lag_sigma_s: f64 = after(&md, &format!("**{lag_s:.3} ± ")).parse().unwrap();
    assert!(
        (lag_s - 0.4).abs() < 3.0 * lag_sigma_s && lag_sigma_s < 0.15,
        "{md}"
    );
    assert_eq!(offset, -lag_s);
    // The runs fit 1.488–1.507° (each within 0.015° of the truth: a point's 0.2 m of
    // height after 13 km, and the start's levelling); their mean is nearer.
    assert!((pooled_deg - 1.5).abs() < 0.01, "{md}");
    assert!(md.contains("3 of the 3 runs") && !md.contains("3σ"), "{md}");
    // The report shows the sections too.
    let html = std::fs::read_to_string(out.join("campaign.html")).unwrap();
    for heading in [
        "The vehicle's odometer pitch",
        "The odometer's lag",
        "The settings to configure",
    ] {
        assert!(html.contains(&format!("<h2>{heading}</h2>")), "{html}");
    }
    assert!(
        html.contains(&format!(
            "<code>[vehicle] odo_pitch_deg = {pooled_deg:.3}</code>"
        )),
        "{html}"
    );
    // The angle as configured: the navigate stage's heights are the truth's within the
    // angle's error over the route (0.01° is 2.3 m at 13 km) and the dead reckoning's own
    // with the initial settings (its gyro drifts not yet corrected: 4–10 m RMS on seeds
    // 70–72 with the true angle), where without it they are 182–216 m RMS off.
    let configured = configured_run(tmp.path(), &campaign, &file);
    let run = campaign.join("sim-0071");
    let truth = run.join("truth.parquet");
    let nav = |out: &Path| out.join("sim-0071/navigate/nav.parquet");
    let (without, with) = (
        height_rms_m(&nav(&out), &truth),
        height_rms_m(&nav(&configured), &truth),
    );
    assert!(without > 100.0, "{without} m");
    assert!(with < 15.0, "{with} m RMS with the configured angle");
    // The disupt stage starts from it: what its points show beyond it is a hundredth of a
    // degree (taken or not), and the corrected heights stay within a metre.
    let d: DisuptOut = read_json(&configured.join("sim-0071/disupt/disupt.json"));
    // Its joint fit's lag is beyond the offset: 0.4 s in all within its 3σ.
    assert_eq!(d.odo_time_offset_s, -lag_s);
    let x = &d.methods["joint"].outcome.x;
    let sigma_s = x.sigma.as_ref().unwrap().odo_lag_s;
    assert!((x.odo_lag_s + lag_s - 0.4).abs() < 3.0 * sigma_s, "{x:?}");
    let fit = d.odo_pitch.expect("fitted");
    assert_eq!(fit.configured_deg, pooled_deg);
    assert!((fit.odo_pitch_deg - 1.5).abs() < 0.03, "{fit:?}");
    assert!(fit.change_deg().abs() < 0.03, "{fit:?}");
    let corrected = configured.join("sim-0071/disupt/corrected_nav.parquet");
    let rms = height_rms_m(&corrected, &truth);
    assert!(rms < 1.0, "corrected heights {rms} m RMS");

    // A search too narrow for the lag stops at its bound: said, and not pooled.
    let narrow = tmp.path().join("narrow.toml");
    std::fs::write(&narrow, "[disupt]\nodo_lag_bound_s = 0.1\n").unwrap();
    let bounded = tmp.path().join("ob");
    run_until_with(
        &campaign,
        &bounded,
        "disupt",
        &["--config", narrow.to_str().unwrap()],
    );
    let md = std::fs::read_to_string(bounded.join("campaign.md")).unwrap();
    let d: DisuptOut = read_json(&bounded.join("sim-0071/disupt/disupt.json"));
    assert_eq!(d.joint_odo_lag_at_bound_s, Some(0.1), "{md}");
    assert!(
        md.contains("sim-0071 | ok")
            && md.contains("odometer lag stopped at its search's bound (+0.100 s beyond"),
        "{md}"
    );
    // All three runs' lags (0.17–0.45 s) lie beyond 0.1 s: none is pooled.
    assert_eq!(
        md.matches("stopped at its search's bound").count(),
        3,
        "{md}"
    );
    assert!(!md.contains("## The odometer's lag"), "{md}");
    // The settings file keeps the campaign's config and has no lag to set.
    let (_, settings) = campaign_settings(&bounded);
    assert_eq!(settings.disupt.odo_lag_bound_s, 0.1);
    assert_eq!(settings.derive.odo_time_offset_s, 0.0);
    assert!((settings.vehicle.odo_pitch_deg - 1.5).abs() < 0.01, "{md}");
}

/// A campaign run in shards (`--shard I/3`, as on a cluster) and merged pools its runs as
/// the whole campaign does: `unz campaign merge` writes the same sections beside the
/// merged summary, and the same settings on the config it is given.
#[test]
fn a_sharded_campaign_pools_its_runs_as_one() {
    let tmp = tempfile::tempdir().unwrap();
    let (campaign, out, md) = pooled_campaign(
        tmp.path(),
        &["--odo-pitch-deg", "1.5", "--odo-lag-s", "0.4"],
    );
    let mut outs = Vec::new();
    for i in 0..3 {
        let shard = tmp.path().join(format!("s{i}"));
        run_until_with(&campaign, &shard, "disupt", &["--shard", &format!("{i}/3")]);
        outs.extend(
            Some(shard)
                .filter(|s| s.join("campaign.parquet").exists())
                .map(|s| s.display().to_string()),
        );
    }
    // No shard holds all three runs.
    for shard in &outs {
        let summary = Path::new(shard).join("campaign.parquet");
        let (_, batches) = unz_formats::parquet_io::read_batches(&summary).unwrap();
        assert!(batches.iter().map(|b| b.num_rows()).sum::<usize>() < 3);
    }
    let config = tmp.path().join("shared.toml");
    std::fs::write(&config, "[disupt]\nazimuth_bound_deg = 20.0\n").unwrap();
    let into = tmp.path().join("all.parquet");
    let mut args = vec!["campaign", "merge"];
    args.extend(outs.iter().map(String::as_str));
    args.extend(["--into", into.to_str().unwrap()]);
    args.extend(["--config", config.to_str().unwrap()]);
    unz_ok(&args);
    let merged = std::fs::read_to_string(tmp.path().join("all.md")).unwrap();
    let sections = |md: &str| md[md.find("\n## ").expect("sections")..].to_owned();
    assert!(merged.starts_with("# 3 runs of "), "{merged}");
    assert_eq!(
        sections(&merged),
        sections(&md).replace("campaign-settings.toml", "all-settings.toml")
    );
    // The pooled angle and offset as the whole campaign's, on the config given.
    let (_, whole) = campaign_settings(&out);
    let table = unz::config::load(Some(&tmp.path().join("all-settings.toml"))).unwrap();
    let pooled = unz::config::effective(&table, None).unwrap();
    assert_eq!(pooled.vehicle, whole.vehicle);
    assert_eq!(
        pooled.derive.odo_time_offset_s,
        whole.derive.odo_time_offset_s
    );
    assert_ne!(pooled.derive.odo_time_offset_s, 0.0);
    assert_eq!(pooled.disupt.azimuth_bound_deg, 20.0);
}

#[test]
fn export_writes_foxglove_channels() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    let run = simulated_run(tmp.path(), 78, &["--duration-s", "300"]);
    unz_ok(&["run", run.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let dir = out.join("sim-0078/export");
    // The corrected trajectory is written once, by the disupt stage.
    assert!(!dir.join("corrected_nav.parquet").exists());
    let nav_path = out.join("sim-0078/disupt/corrected_nav.parquet");
    assert!(nav_path.is_file());
    // lz4 chunks by default; `[export] mcap_compression` re-runs the export alone, the same
    // messages in zstd chunks, smaller.
    let lz4_path = dir.join("corrected.mcap");
    let chunks = mcap_chunk_compressions(&lz4_path);
    assert!(
        !chunks.is_empty() && chunks.iter().all(|c| c == "lz4"),
        "{chunks:?}"
    );
    let lz4 = (
        mcap_messages(&lz4_path),
        std::fs::metadata(&lz4_path).unwrap().len(),
    );
    let cfg = tmp.path().join("zstd.toml");
    std::fs::write(&cfg, "[export]\nmcap_compression = \"zstd\"\n").unwrap();
    let zstd_run = unz_output(&[
        "run",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--config",
        cfg.to_str().unwrap(),
    ]);
    assert!(zstd_run.status.success());
    let said = String::from_utf8_lossy(&zstd_run.stderr);
    for stage in ["ingest", "derive", "navigate", "criteria", "disupt"] {
        assert!(
            said.contains(&format!("{stage}: up to date")),
            "{stage}: {said}"
        );
    }
    assert!(!said.contains("export: up to date"), "{said}");
    // Each stage after them asks for the ingest and the derive; one run checks them once.
    for stage in ["ingest", "derive"] {
        let checks = said.matches(&format!("{stage}: up to date")).count();
        assert_eq!(checks, 1, "{stage} checked {checks} times: {said}");
    }
    let zstd_path = dir.join("corrected.mcap");
    let chunks = mcap_chunk_compressions(&zstd_path);
    assert!(chunks.iter().all(|c| c == "zstd"), "{chunks:?}");
    assert!(mcap_messages(&zstd_path) == lz4.0, "the same messages");
    assert!(std::fs::metadata(&zstd_path).unwrap().len() < lz4.1);
    unz_ok(&[
        "export",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let Some(py) = python() else { return };
    let topics = ["/corrected/fix", "/corrected/pose", "/criteria"].map(Path::new);
    let mcap = dir.join("corrected.mcap");
    let args: Vec<&Path> = std::iter::once(mcap.as_path()).chain(topics).collect();
    let info = python_json(&py, "check_mcap.py", &args);
    let ch = &info["channels"];
    assert_eq!(
        ch["/corrected/fix"]["schema_name"],
        "sensor_msgs/msg/NavSatFix"
    );
    assert_eq!(
        ch["/corrected/pose"]["schema_name"],
        "geometry_msgs/msg/PoseStamped"
    );
    assert_eq!(ch["/corrected/fix"]["schema_encoding"], "ros2msg");
    assert_eq!(ch["/corrected/fix"]["message_encoding"], "cdr");
    // 300 s at 10 Hz, and the criteria at 1 s epochs.
    assert_eq!(ch["/corrected/fix"]["count"], 3000);
    assert_eq!(ch["/corrected/pose"]["count"], 3000);
    assert_eq!(ch["/criteria"]["count"], 300);
    assert_eq!(info["decoded"], 3000 * 3 + 300);
    // The first fix decodes to the corrected route's first sample (exact: f64 both ways).
    let (_, b) = unz_formats::parquet_io::read_batches(&nav_path).unwrap();
    let lat = unz_formats::tables::f64_column(&b[0], "lat_deg").unwrap()[0];
    let lon = unz_formats::tables::f64_column(&b[0], "lon_deg").unwrap()[0];
    let fix = &info["first"]["/corrected/fix"];
    assert_eq!(fix["latitude"].as_f64(), Some(lat), "{fix}");
    assert_eq!(fix["longitude"].as_f64(), Some(lon), "{fix}");
    assert_eq!(fix["header"]["frame_id"], "wgs84");
    let q = &info["first"]["/corrected/pose"]["pose"]["orientation"];
    let norm: f64 = ["x", "y", "z", "w"]
        .iter()
        .map(|c| q[c].as_f64().unwrap().powi(2))
        .sum();
    assert!((norm - 1.0).abs() < 1e-12, "{q}");
    // Rerun's own MCAP importer: the fixes become geographic points, the poses 3D poses.
    let rr = python_json(&py, "rerun_mcap.py", &[&mcap]);
    assert_eq!(rr["/corrected/fix"]["rows"], 3000, "{rr}");
    let cols = |e: &str| rr[e]["columns"].as_array().unwrap().clone();
    assert!(
        cols("/corrected/fix").contains(&"GeoPoints:positions".into()),
        "{rr}"
    );
    assert!(
        cols("/corrected/pose").contains(&"InstancePoses3D:quaternions".into()),
        "{rr}"
    );
    assert_eq!(rr["/criteria"]["rows"], 300, "{rr}");
    assert_eq!(info["monotonic"], true);
    // Log times in UTC, as raw.mcap's (the simulated header starts in 2026), not 1970.
    let raw = python_json(
        &py,
        "check_mcap.py",
        &[&out.join("sim-0078/ingest/raw.mcap")],
    );
    let (first, raw_first) = (
        info["first_log_time"].as_u64().unwrap(),
        raw["first_log_time"].as_u64().unwrap(),
    );
    assert!(first > 1_700_000_000_000_000_000, "{first}");
    assert!(
        first.abs_diff(raw_first) < 1_000_000_000,
        "{first} vs {raw_first}"
    );
}
