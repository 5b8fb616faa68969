//! Estimation that real logs need, against simulated truth through the binary: the
//! odometer's lag, runs without a static start, hold-out errors and the route's σ.

use std::path::{Path, PathBuf};

use unz::disupt_stage::DisuptOut;
use unz::flow::NavigateSummary;
use unz_formats::parquet_io::read_batches;
use unz_formats::tables::{f64_column, i64_column, u8_column};
use unz_stages::initial::Source;
use unz_stages::simulate::TrueSettings;

use crate::util::{read_json, run_until, run_until_with, simulated_run, unz_ok, unz_output};

/// A column of a Parquet file, all batches.
fn column(path: &Path, name: &str) -> Vec<f64> {
    column_by(path, name, f64_column)
}

/// A column of a Parquet file, all batches, each read by `read` (a `tables` reader).
fn column_by<T, E: std::fmt::Debug>(
    path: &Path,
    name: &str,
    read: impl Fn(&arrow::record_batch::RecordBatch, &str) -> Result<Vec<T>, E>,
) -> Vec<T> {
    let (_, batches) = read_batches(path).unwrap();
    batches
        .iter()
        .flat_map(|b| read(b, name).unwrap())
        .collect()
}

fn truth(run: &Path) -> TrueSettings {
    read_json(&run.join("truth.json"))
}

fn disupt_json(out: &Path, name: &str) -> DisuptOut {
    read_json(&out.join(name).join("disupt/disupt.json"))
}

/// Horizontal errors of the corrected route against truth at every sample, m.
fn route_errors(run: &Path, out: &Path, name: &str) -> Vec<(f64, f64)> {
    let nav = out.join(name).join("disupt/corrected_nav.parquet");
    let tr = run.join("truth.parquet");
    let (n, e) = (column(&nav, "north_m"), column(&nav, "east_m"));
    let (tn, te) = (column(&tr, "north_m"), column(&tr, "east_m"));
    assert_eq!(n.len(), tn.len());
    n.iter()
        .zip(&e)
        .zip(tn.iter().zip(&te))
        .map(|((a, b), (c, d))| (a - c, b - d))
        .collect()
}

/// The derive's reading of the odometer's lag in `navigate.json` (beyond the offset
/// configured), s; fails when the drive shows none.
fn clock_reading_s(out: &Path, name: &str) -> f64 {
    let nav: NavigateSummary = read_json(&out.join(name).join("navigate/navigate.json"));
    let clock = nav.odometer_clock.expect("the odometer's clock read");
    assert!(clock.shown, "{clock:?}");
    clock.fit.lag_s
}

fn worst_m(errors: &[(f64, f64)]) -> f64 {
    errors.iter().map(|(n, e)| n.hypot(*e)).fold(0.0, f64::max)
}

/// Simulates the run of `seed` with `options`, runs every stage to disupt; returns the
/// run folder and the output folder.
fn process(dir: &Path, seed: u32, options: &[&str]) -> (std::path::PathBuf, std::path::PathBuf) {
    let run = simulated_run(dir, seed, options);
    let out = dir.join("o");
    run_until(&run, &out, "disupt");
    (run, out)
}

/// The joint fit finds a simulated odometer lag of −0.4…+0.4 s within 0.03 s, and the
/// corrected route is then as good as the same run's without a lag. The derive's reading
/// of the clock, from the drive alone, is within 0.1 s of each lag (it read within 0.07 s
/// of none on 51 simulated runs with a static start).
#[test]
fn joint_fit_recovers_the_odometer_lag() {
    let name = "sim-0061";
    let base = ["--cp-at-every-stop", "--azimuth-error-deg", "6"];
    let tmp0 = tempfile::tempdir().unwrap();
    let (run0, out0) = process(tmp0.path(), 61, &base);
    let d0 = disupt_json(&out0, name);
    let worst0 = worst_m(&route_errors(&run0, &out0, name));
    let lag0 = d0.methods["joint"].outcome.x.odo_lag_s;
    eprintln!("no lag: estimated {lag0:.4} s, worst route error {worst0:.2} m");
    let read0 = clock_reading_s(&out0, name);
    assert!(read0.abs() < 0.1, "the clock read {read0} s late");
    assert!(
        lag0.abs() < 0.03,
        "lag {lag0} s estimated where there is none"
    );
    for lag in ["-0.4", "0.25", "0.4"] {
        let tmp = tempfile::tempdir().unwrap();
        let mut opts = base.to_vec();
        opts.extend(["--odo-lag-s", lag]);
        let (run, out) = process(tmp.path(), 61, &opts);
        let d = disupt_json(&out, name);
        let joint = &d.methods["joint"];
        let true_lag = truth(&run).odo_lag_s;
        let worst = worst_m(&route_errors(&run, &out, name));
        let sigma = joint.outcome.x.sigma.as_ref().unwrap().odo_lag_s;
        eprintln!(
            "lag {true_lag} s: estimated {:.4} s ± {sigma:.4}, worst route error {worst:.2} m (no lag: {worst0:.2} m)",
            joint.outcome.x.odo_lag_s
        );
        assert!(
            (joint.outcome.x.odo_lag_s - true_lag).abs() < 0.03,
            "lag {} s, truth {true_lag} s",
            joint.outcome.x.odo_lag_s
        );
        assert!(sigma > 0.0 && sigma < 0.05, "σ {sigma} s");
        let read = clock_reading_s(&out, name);
        assert!(
            (read - true_lag).abs() < 0.1,
            "the clock read {read} s, truth {true_lag} s"
        );
        // Back to what the run gives without a lag: the lag's residual error (< 0.03 s)
        // moves the route by at most its share of the turns' velocity changes.
        assert!(
            worst < 1.25 * worst0 + 1.0,
            "worst route error {worst} m, {worst0} m without a lag"
        );
    }
}

/// An odometer 4.5 s late (a logger on another clock), beyond the ±1 s of lag the joint
/// fit searches about the offset configured: the derive fails and names the offset that
/// aligns it. Set as named, the run goes through, and the joint fit finds the lag as it
/// does a lag of tenths of a second (within 0.03 s). Before, the run ended "ok" with the
/// lag at its search's bound, 11 stands of the odometer "while the vehicle moved",
/// hold-out errors of 31 and 57 m, and the blame on the mark's lever arm (23 m).
#[test]
fn an_odometer_on_another_clock_is_named_and_the_offset_named_recovers_its_lag() {
    let name = "sim-0061";
    let tmp = tempfile::tempdir().unwrap();
    let run = simulated_run(
        tmp.path(),
        61,
        &[
            "--cp-at-every-stop",
            "--azimuth-error-deg",
            "6",
            "--odo-lag-s",
            "4.5",
        ],
    );
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("failed"));
    assert!(
        err.contains("the log's odometer count runs ")
            && err.contains(" s late against the IMU's increments in the same records"),
        "{err}"
    );
    let offset_s = crate::util::named_offset_s(&err);
    // The clock's fit was within 0.07 s of none on 51 simulated runs with a static start
    // (4.6 s here); the joint fit searches ±1 s about it.
    assert!((offset_s + 4.5).abs() < 0.25, "{err}");
    let config = tmp.path().join("offset.toml");
    std::fs::write(
        &config,
        format!("[derive]\nodo_time_offset_s = {offset_s}\n"),
    )
    .unwrap();
    let out = tmp.path().join("o");
    run_until_with(
        &run,
        &out,
        "disupt",
        &["--config", config.to_str().unwrap()],
    );
    let joint = &disupt_json(&out, name).methods["joint"];
    let lag_s = joint.outcome.x.odo_lag_s;
    let sigma_s = joint.outcome.x.sigma.as_ref().unwrap().odo_lag_s;
    // The lag estimated beyond the offset set: the whole lag is their difference.
    let whole_s = lag_s - offset_s;
    eprintln!("lag 4.5 s, offset named {offset_s} s: estimated {whole_s:.4} ± {sigma_s:.4} s");
    assert!((whole_s - 4.5).abs() < 0.03, "lag {whole_s} s, truth 4.5 s");
    assert!(sigma_s > 0.0 && sigma_s < 0.05, "σ {sigma_s} s");
}

/// A log that begins while driving, with the manifest azimuth 120° off: levelled in
/// motion, the azimuth found by the coarse search and the joint fit, and the route
/// within 0.2 % of the distance; the hold-out errors and the route's σ are reported and
/// honest.
#[test]
fn runs_without_a_static_start_are_processed() {
    let tmp = tempfile::tempdir().unwrap();
    let name = "sim-0062";
    let (run, out) = process(
        tmp.path(),
        62,
        &["--log-start-s", "400", "--azimuth-error-deg", "120"],
    );
    let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap();
    assert!(manifest.contains("static_s = 0.0"), "{manifest}");
    let nav: NavigateSummary = read_json(&out.join(name).join("navigate/navigate.json"));
    assert!(
        nav.initial.gyrocompass_skipped.is_some(),
        "{:?}",
        nav.initial
    );
    assert_eq!(nav.initial.roll_source, Source::InMotion);
    let t = truth(&run);
    let d = disupt_json(&out, name);
    assert!(d.coarse_azimuth_deg.is_some());
    let joint = &d.methods["joint"];
    let az_err = (joint.outcome.x.azimuth_deg - t.azimuth_deg + 180.0).rem_euclid(360.0) - 180.0;
    let errors = route_errors(&run, &out, name);
    let worst = worst_m(&errors);
    eprintln!(
        "no static start, manifest 120° off: joint azimuth error {az_err:.3}°, worst route error {worst:.1} m over {:.0} m",
        d.distance_m
    );
    assert!(az_err.abs() < 0.2, "joint azimuth off by {az_err}°");
    assert!(
        worst < 0.002 * d.distance_m,
        "worst route error {worst} m over {} m",
        d.distance_m
    );
    let holdout = joint.holdout.as_ref().unwrap();
    assert_eq!(holdout.len(), joint.outcome.control_points.len());
    for h in holdout {
        eprintln!(
            "hold-out at control point {}: {:.2} m",
            h.id,
            h.dx_m.hypot(h.dy_m)
        );
        assert!(h.dx_m.is_finite() && h.dy_m.is_finite());
    }
}

/// The first row of a truth table's column `name`.
fn truth_at_start(run: &Path, name: &str) -> f64 {
    column(&run.join("truth.parquet"), name)[0]
}

/// Logs begun while driving (no static start), the manifest azimuth 117.6° off (not a
/// whole number of the coarse search's 1° steps), two control points, six seeds: levelled
/// in motion over the first minute, every start within 0.3° of the true pitch and roll,
/// every joint azimuth within 0.2° of the truth and every route within 0.2 % of its
/// distance (issue 11's targets). Measured: levelling ≤ 0.17° off, azimuth ≤ 0.10°
/// (σ 0.03–0.17°), route ≤ 0.08 %. Levelled from the first epoch's references alone, the
/// same logs started up to 2.8° off and two of the six joint fits left their bounds.
/// The derive's reading of the odometer's clock is within 0.15 s of the truth (no lag):
/// it read 0.34 s late on sim-0204 when F's start-up, a block's odometer pulses at
/// speed, was left in (up to 0.67 s on 14 such logs; ≤ 0.23 s without it).
#[test]
fn logs_begun_while_driving_meet_the_targets_over_seeds() {
    let tmp = tempfile::tempdir().unwrap();
    let options = [
        "--runs",
        "6",
        "--log-start-s",
        "400",
        "--azimuth-error-deg",
        "117.6",
    ];
    let first = simulated_run(tmp.path(), 200, &options);
    let campaign = first.parent().unwrap();
    let out = tmp.path().join("o");
    run_until(campaign, &out, "disupt");
    for seed in 200..206 {
        let name = format!("sim-{seed:04}");
        let run = campaign.join(&name);
        let nav: NavigateSummary = read_json(&out.join(&name).join("navigate/navigate.json"));
        let i = &nav.initial;
        let level = i.in_motion_level.expect("levelled in motion over a window");
        assert!(level.epochs >= 10, "{level:?}");
        let pitch_err = i.pitch_deg - truth_at_start(&run, "pitch_deg");
        let roll_err = i.roll_deg - truth_at_start(&run, "roll_deg");
        let d = disupt_json(&out, &name);
        let joint = d
            .methods
            .get("joint")
            .unwrap_or_else(|| panic!("{name}: joint not run: {:?}", d.skipped.get("joint")));
        let t = truth(&run);
        let az_err =
            (joint.outcome.x.azimuth_deg - t.azimuth_deg + 180.0).rem_euclid(360.0) - 180.0;
        let worst = worst_m(&route_errors(&run, &out, &name));
        let read = clock_reading_s(&out, &name);
        assert!(
            (read - t.odo_lag_s).abs() < 0.15,
            "{name}: the clock read {read} s, truth {} s",
            t.odo_lag_s
        );
        eprintln!(
            "{name}: levelled {pitch_err:+.3}° / {roll_err:+.3}° off ({} epochs), joint azimuth \
             {az_err:+.3}°, worst route error {worst:.1} m over {:.0} m",
            level.epochs, d.distance_m
        );
        assert!(pitch_err.abs() < 0.3 && roll_err.abs() < 0.3, "{name}");
        assert!(az_err.abs() < 0.2, "{name}: joint azimuth off by {az_err}°");
        assert!(
            worst < 0.002 * d.distance_m,
            "{name}: worst route error {worst} m over {} m",
            d.distance_m
        );
    }
}

/// Moves control point `id` of the manifest `run.toml` `north_m` north (its survey off).
fn move_control_point(manifest: &Path, id: i64, north_m: f64) {
    edit_manifest(manifest, |m| {
        let points = m["control_point"].as_array_mut().unwrap();
        let p = points
            .iter_mut()
            .find(|p| p["id"].as_integer() == Some(id))
            .unwrap();
        let lat = p["latitude_deg"].as_float().unwrap();
        p["latitude_deg"] = toml::Value::Float(lat + north_m / 111_250.0);
    });
}

/// The joint's hold-out, and the ids of the control points it left out.
fn left_out(d: &DisuptOut) -> (Vec<unz_stages::disupt::Holdout>, Vec<u32>) {
    let holdout = d.methods["joint"].holdout.clone().unwrap();
    let ids = holdout
        .iter()
        .filter(|h| h.excluded)
        .map(|h| h.id)
        .collect();
    (holdout, ids)
}

/// Rewrites the manifest `run.toml` through `f`.
fn edit_manifest(manifest: &Path, f: impl FnOnce(&mut toml::Table)) {
    let mut m: toml::Table = toml::from_str(&std::fs::read_to_string(manifest).unwrap()).unwrap();
    f(&mut m);
    std::fs::write(manifest, toml::to_string(&m).unwrap()).unwrap();
}

/// Control points surveyed off, among eleven, are left out of the joint fit, and the
/// corrected route is then as good as with the survey intact (measured: worst error
/// 0.27 m, intact 0.28 m; two points off, 0.26 m). Kept in (`joint_exclude_inconsistent`
/// off), the point is named and spreads its error over the route (4.46 m). Each exclusion
/// is said in `disupt.json` (`holdout[].excluded`), `disupt.md`, the campaign's note and
/// its `joint_excluded_points` column. The same run intact calls none (every hold-out
/// ≤ 0.3σ). A point a kilometre off, which drags the fit out of its bounds, is found by
/// leaving each point out in turn (measured: 0.26 m); two such, by leaving out each pair
/// (0.28 m); and two off of which one drags the fit without the other out of its bounds,
/// by leaving one more out beside the most inconsistent (0.28 m).
#[test]
fn control_points_surveyed_off_are_left_out_of_the_fit() {
    let tmp = tempfile::tempdir().unwrap();
    let name = "sim-0063";
    let run = simulated_run(tmp.path(), 63, &["--cp-at-every-stop"]);
    let campaign = run.parent().unwrap();
    let manifest = run.join("run.toml");
    let run_into = |out: &str| -> (PathBuf, DisuptOut, f64) {
        let out = tmp.path().join(out);
        run_until(campaign, &out, "disupt");
        let d = disupt_json(&out, name);
        let worst = worst_m(&route_errors(&run, &out, name));
        (out, d, worst)
    };
    let (_, clean, worst_clean) = run_into("clean");
    let holdout = clean.methods["joint"].holdout.clone().unwrap();
    assert!(holdout.len() >= 4);
    for h in &holdout {
        let e = h.error_sigma.unwrap();
        assert!(e < 1.0 && !h.inconsistent && !h.excluded, "{h:?}");
        assert!(h.sigma_north_m.unwrap() >= 1.0 && h.sigma_east_m.unwrap() >= 1.0);
    }

    // Point 6 surveyed 10 m north of its mark.
    move_control_point(&manifest, 6, 10.0);
    let (out, d, worst) = run_into("one");
    let holdout = d.methods["joint"].holdout.clone().unwrap();
    for h in &holdout {
        eprintln!(
            "control point {}: {:.2} m, {:.1}σ{}",
            h.id,
            h.dx_m.hypot(h.dy_m),
            h.error_sigma.unwrap(),
            if h.excluded { ", left out" } else { "" }
        );
        assert_eq!(
            (h.excluded, h.inconsistent),
            (h.id == 6, h.id == 6),
            "{h:?}"
        );
        if h.id != 6 {
            // Without the point off, the others agree again.
            assert!(h.error_sigma.unwrap() < 1.0, "{h:?}");
        }
    }
    // The fit without point 6 keeps ten of eleven points, whose route differs from the
    // intact survey's by centimetres (0.1 m: a tenth of the points' 1-m σ).
    eprintln!("worst route error: intact {worst_clean:.2} m, point 6 left out {worst:.2} m");
    assert!(
        worst < worst_clean + 0.1,
        "{worst} m against {worst_clean} m"
    );
    let excluded_column =
        |out: &Path| column(&out.join("campaign.parquet"), "joint_excluded_points");
    assert_eq!(excluded_column(&out), [1.0]);
    assert_eq!(excluded_column(&tmp.path().join("clean")), [0.0]);
    let max_holdout = column(&out.join("campaign.parquet"), "joint_holdout_max_m")[0];
    assert!(
        max_holdout < 1.0,
        "the point left out is not in the hold-out's max: {max_holdout}"
    );
    let note = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        note.contains(
            "control point left out of the joint fit, inconsistent with the rest of the run"
        ) && note.contains(": 6 ("),
        "{note}"
    );
    // The campaign's points that disagree: point 6, visited by this one run, left out.
    let section = &note[note
        .find("## Control points that disagree")
        .expect("the section")..];
    assert!(
        section
            .lines()
            .any(|l| l.starts_with("| 6 |") && l.contains("| 1 | 1 | 1 | 10.0 | 10.0 |")),
        "{section}"
    );
    let html = std::fs::read_to_string(out.join("campaign.html")).unwrap();
    assert!(
        html.contains("<span class=\"note\">control point left out of the joint fit"),
        "{html}"
    );
    let tables = std::fs::read_to_string(out.join(name).join("disupt/disupt.md")).unwrap();
    let marked: Vec<&str> = tables.lines().filter(|l| l.contains(" ✗")).collect();
    assert!(
        marked.len() == 1
            && marked[0].starts_with("| 6 |")
            && marked[0].ends_with(" ✗ left out of the fit |"),
        "{tables}"
    );

    // Kept in the fit, the point is named and pulls the route.
    edit_manifest(&manifest, |m| {
        let mut disupt = toml::Table::new();
        disupt.insert("joint_exclude_inconsistent".into(), false.into());
        let mut params = toml::Table::new();
        params.insert("disupt".into(), disupt.into());
        m.insert("params".into(), params.into());
    });
    let (out, d, worst_kept) = run_into("kept");
    let holdout = d.methods["joint"].holdout.clone().unwrap();
    for h in &holdout {
        assert_eq!((h.excluded, h.inconsistent), (false, h.id == 6), "{h:?}");
    }
    eprintln!("worst route error with point 6 kept: {worst_kept:.2} m");
    assert!(worst_kept > worst + 2.0, "{worst_kept} m against {worst} m");
    assert_eq!(excluded_column(&out), [0.0]);
    let note = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        note.contains("control point inconsistent with the rest of the run")
            && note.contains(": 6 ("),
        "{note}"
    );

    // Two points off (6, and 9 8 m south), the exclusion on again: both left out, one at
    // a time.
    edit_manifest(&manifest, |m| {
        m.remove("params");
    });
    move_control_point(&manifest, 9, -8.0);
    let (_, d, worst_two) = run_into("two");
    let (holdout, excluded) = left_out(&d);
    assert_eq!(excluded, [6, 9], "{holdout:?}");
    assert!(
        holdout.iter().all(|h| h.excluded == h.inconsistent),
        "{holdout:?}"
    );
    eprintln!("worst route error with points 6 and 9 left out: {worst_two:.2} m");
    assert!(
        worst_two < worst_clean + 0.1,
        "{worst_two} m against {worst_clean} m"
    );

    // Point 6 a kilometre off (a digit typed wrong), 9 intact again: the fit with it
    // leaves its bounds (the previous build fell back to OEPI, 35 m off), so no hold-out
    // can judge it; left out in turn, it is the one whose absence brings the fit within.
    move_control_point(&manifest, 6, 990.0);
    move_control_point(&manifest, 9, 8.0);
    let (_, d, worst_typo) = run_into("typo");
    assert_eq!(d.corrected_by.as_deref(), Some("joint"), "{:?}", d.skipped);
    // The report says why the point was looked for: the fit with it was refused.
    let why = d.methods["joint"].refused_with_all_points.clone().unwrap();
    assert!(why.starts_with("the fit left its bounds"), "{why}");
    let tables =
        std::fs::read_to_string(tmp.path().join("typo").join(name).join("disupt/disupt.md"))
            .unwrap();
    assert!(
        tables.contains("With every control point the fit was refused: the fit left its bounds"),
        "{tables}"
    );
    let (holdout, excluded) = left_out(&d);
    assert_eq!(excluded, [6], "{holdout:?}");
    let six = holdout.iter().find(|h| h.id == 6).unwrap();
    assert!((six.dx_m.hypot(six.dy_m) - 1000.0).abs() < 1.0, "{six:?}");
    eprintln!("worst route error with point 6 a kilometre off, left out: {worst_typo:.2} m");
    assert!(
        worst_typo < worst_clean + 0.1,
        "{worst_typo} m against {worst_clean} m"
    );

    // Two points a kilometre off (6, and 4): no single point's absence brings the fit
    // within its bounds; a pair's does (the previous build fell back to OEPI, 78 m off).
    // The joint's route with `ids` left out, as good as with the survey intact.
    let both_left_out = |name: &str, ids: [u32; 2]| -> DisuptOut {
        let (_, d, worst) = run_into(name);
        assert_eq!(d.corrected_by.as_deref(), Some("joint"), "{:?}", d.skipped);
        let (holdout, excluded) = left_out(&d);
        assert_eq!(excluded, ids, "{holdout:?}");
        eprintln!("worst route error with points {ids:?} off, left out ({name}): {worst:.2} m");
        assert!(
            worst < worst_clean + 0.1,
            "{worst} m against {worst_clean} m"
        );
        d
    };
    move_control_point(&manifest, 4, 1000.0);
    both_left_out("pair", [4, 6]);

    // Point 2 a kilometre off and 5 700 m south: the fit with both stays within its
    // bounds, but without 2 alone (the most inconsistent) it leaves them, dragged by 5;
    // without both it is within. The previous build kept both: 39 m off.
    move_control_point(&manifest, 4, -1000.0);
    move_control_point(&manifest, 6, -1000.0);
    move_control_point(&manifest, 2, 1000.0);
    move_control_point(&manifest, 5, -700.0);
    let d = both_left_out("dragged", [2, 5]);
    assert!(d.methods["joint"].refused_with_all_points.is_none());
}

/// The corrected route's σ: at least 95 % of the epochs lie within 3σ of the truth.
/// Control points surveyed under the vehicle's mark, 1.5 m ahead of the navigated point,
/// 1 m left and 0.3 m below (1.8 m horizontally): with the mark's lever arm configured
/// (`[params.vehicle]`, which the simulator writes), every control point's error is the
/// mark's, and the corrected route is the same run's with the points under the navigated
/// point. With the arm left out, the mark's 1.8 m spreads
/// over the route (measured: 2.38 m worst, against 0.28 m).
#[test]
fn control_points_are_compared_with_the_vehicles_mark() {
    let tmp = tempfile::tempdir().unwrap();
    let name = "sim-0063";
    let (bare_run, bare_out) = process(&tmp.path().join("bare"), 63, &["--cp-at-every-stop"]);
    let (run, out) = process(
        &tmp.path().join("arm"),
        63,
        &["--cp-at-every-stop", "--mark-lever-arm-m", "1.5,-1.0,0.3"],
    );
    let worst_bare = worst_m(&route_errors(&bare_run, &bare_out, name));
    let worst = worst_m(&route_errors(&run, &out, name));
    eprintln!(
        "worst route error: mark at the navigated point {worst_bare:.3} m, ahead {worst:.3} m"
    );
    assert!(
        (worst - worst_bare).abs() < 0.02,
        "{worst} m against {worst_bare} m"
    );
    let d = disupt_json(&out, name);
    assert_eq!(d.mark_lever_arm_m, Some([1.5, -1.0, 0.3]));
    assert_eq!(disupt_json(&bare_out, name).mark_lever_arm_m, None);
    // With the mark where the manifest says, its control points show no arm worth a refit
    // (measured 0.04σ both).
    for d in [&d, &disupt_json(&bare_out, name)] {
        let c = d.joint_mark_arm_check.as_ref().unwrap();
        assert!(!c.refit && c.seen.distance_sigma < 2.0, "{c:?}");
    }
    let md = std::fs::read_to_string(out.join(name).join("disupt/disupt.md")).unwrap();
    assert!(
        md.contains("1.50 m forward, -1.00 m right and 0.30 m down"),
        "{md}"
    );

    // The errors at the points, of the mark and of the navigated point: with the joint's
    // settings, one route, so they agree to the manifest's rounding (0.1 mm) and the
    // heading's error turning the arm (0.01° of 1.8 m: 0.3 mm).
    let joint_points = |d: &DisuptOut| d.methods["joint"].outcome.control_points.clone();
    let same =
        |a: &[unz_stages::criteria::Kryt2], b: &[unz_stages::criteria::Kryt2], tol_m: f64| {
            assert_eq!(a.len(), b.len());
            assert!(a.len() >= 4);
            for (a, b) in a.iter().zip(b) {
                assert!(
                    (a.dx_m - b.dx_m).abs() < tol_m && (a.dy_m - b.dy_m).abs() < tol_m,
                    "{a:?} {b:?}"
                );
            }
        };
    same(
        &joint_points(&d),
        &joint_points(&disupt_json(&bare_out, name)),
        2e-3,
    );
    // Before DISUPT, the heading's error turns the arm (the manifest's azimuth is 4–8°
    // off: up to 0.25 m of 1.8 m); the navigation, the criteria (which read its attitude
    // back in f32: 1e-7 rad of 1.8 m) and DISUPT's start agree on it.
    let nav =
        |o: &Path| -> NavigateSummary { read_json(&o.join(name).join("navigate/navigate.json")) };
    let criteria = |o: &Path| -> unz::flow::CriteriaSummary {
        read_json(&o.join(name).join("criteria/criteria.json"))
    };
    run_until(&run, &out, "criteria");
    let navigated = nav(&out).control_points;
    same(&criteria(&out).control_points, &navigated, 1e-6);
    same(&d.before.control_points, &navigated, 1e-6);
    same(&navigated, &nav(&bare_out).control_points, 0.26);
    assert_eq!(nav(&out).mark_lever_arm_m, Some([1.5, -1.0, 0.3]));

    // The arm left out of the manifest: the points are 1.8 m from where the navigation
    // compares them, and their errors turn with the heading at each stop. Held at the
    // configured arm (`joint_mark_arm = false`), the fit spreads them over the route.
    edit_manifest(&run.join("run.toml"), |m| {
        m.remove("params");
    });
    let held = tmp.path().join("held.toml");
    std::fs::write(&held, "[disupt]\njoint_mark_arm = false\n").unwrap();
    run_until_with(&run, &out, "disupt", &["--config", held.to_str().unwrap()]);
    let ignored = worst_m(&route_errors(&run, &out, name));
    let d = disupt_json(&out, name);
    let check = d.joint_mark_arm_check.clone().unwrap();
    eprintln!("worst route error with the arm left out and held: {ignored:.3} m; {check:?}");
    assert!(
        ignored > worst_bare + 1.0,
        "{ignored} m against {worst_bare} m"
    );
    assert_eq!(d.mark_lever_arm_m, None);
    assert!(!check.refit && check.estimated.is_none());
    // The check holds the fit's lag, which takes part of the arm along the vehicle
    // (measured: 0.74 ± 0.31 m forward, −1.14 ± 0.31 m right; 4.4σ).
    assert!(
        check.seen.distance_sigma > unz::disupt_stage::MARK_ARM_REFIT_SIGMA,
        "{check:?}"
    );
    let md = std::fs::read_to_string(out.join(name).join("disupt/disupt.md")).unwrap();
    assert!(md.contains("which the joint fit did not estimate"), "{md}");

    // By default the fit is redone with the mark free: it finds the arm within its σ
    // (measured 1.48 ± 0.31 m forward, −1.00 ± 0.31 m right) and the route is the one with
    // the arm configured.
    run_until(&run, &out, "disupt");
    let found = worst_m(&route_errors(&run, &out, name));
    let d = disupt_json(&out, name);
    let check = d.joint_mark_arm_check.clone().unwrap();
    eprintln!("worst route error with the arm left out and estimated: {found:.3} m; {check:?}");
    assert!(check.refit, "{check:?}");
    let a = check.estimated.unwrap();
    assert!(
        (a.forward_m - 1.5).abs() < 3.0 * a.sigma_forward_m
            && (a.right_m + 1.0).abs() < 3.0 * a.sigma_right_m
            && a.sigma_forward_m < 0.5
            && a.sigma_right_m < 0.5,
        "{a:?}"
    );
    assert_eq!(
        d.methods["joint"].outcome.x.mark_arm_m,
        Some([a.forward_m, a.right_m])
    );
    assert!(
        (found - worst_bare).abs() < 0.1,
        "{found} m against {worst_bare} m"
    );
    let md = std::fs::read_to_string(out.join(name).join("disupt/disupt.md")).unwrap();
    assert!(md.contains("the joint fit estimates it"), "{md}");
    let note = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(note.contains("the vehicle's mark is not where"), "{note}");
    // The campaign gives the mark to configure (no arm configured: the estimate itself).
    let col = |n: &str| column(&out.join("campaign.parquet"), n)[0];
    assert_eq!(
        (col("joint_mark_forward_m"), col("joint_mark_right_m")),
        (a.forward_m, a.right_m)
    );
    assert_eq!(col("joint_mark_forward_sigma_m"), a.sigma_forward_m);
    assert!(
        note.contains("## The vehicle's mark") && note.contains("1 of the 1 runs"),
        "{note}"
    );
    // The review draws the mark on the vehicle, where the control points are compared.
    run_until(&run, &out, "review");
    if let Some(py) = crate::util::python() {
        let rrd = out.join(name).join("review").join(format!("{name}.rrd"));
        let info = crate::util::python_json(&py, "check_rrd.py", &[&rrd]);
        let statics = info["static"].as_array().unwrap();
        assert!(
            statics.iter().any(|e| e == "/world/vehicle/mark"),
            "{statics:?}"
        );
    }
}

/// The corrected route's σ (north, east, heading, every second) against the truth's errors
/// of the run `name` in `out`: the share of epochs within 3σ of each, and the RMS of the
/// errors in units of σ over the epochs whose σ is above 1 cm and 0.001° (the static
/// start's σ are micrometres).
fn route_sigma_z(run: &Path, out: &Path, name: &str) -> ([f64; 3], [f64; 3], [f64; 3]) {
    let nav = out.join(name).join("disupt/corrected_nav.parquet");
    let sigma = [
        column(&nav, "sigma_north_m"),
        column(&nav, "sigma_east_m"),
        column(&nav, "sigma_heading_deg"),
    ];
    assert!(sigma.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
    let heading = column(&nav, "heading_deg");
    let true_heading = column(&run.join("truth.parquet"), "heading_deg");
    let errors = route_errors(run, out, name);
    let n = errors.len();
    let (mut inside, mut z2, mut counted) = ([0usize; 3], [0.0; 3], [0usize; 3]);
    let epochs = (0..n).step_by(100).count();
    for k in (0..n).step_by(100) {
        let dh = (heading[k] - true_heading[k] + 180.0).rem_euclid(360.0) - 180.0;
        let e = [errors[k].0, errors[k].1, dh];
        let floor = [1e-2, 1e-2, 1e-3];
        for q in 0..3 {
            inside[q] += usize::from(e[q].abs() <= 3.0 * sigma[q][k] + floor[q] / 10.0);
            if sigma[q][k] > floor[q] {
                z2[q] += (e[q] / sigma[q][k]).powi(2);
                counted[q] += 1;
            }
        }
    }
    eprintln!(
        "{name}: σ at the end {:.2} m, {:.2} m, {:.4}°",
        sigma[0][n - 1],
        sigma[1][n - 1],
        sigma[2][n - 1]
    );
    (
        inside.map(|i| i as f64 / epochs as f64),
        std::array::from_fn(|q| (z2[q] / counted[q].max(1) as f64).sqrt()),
        sigma.map(|s| s[n - 1]),
    )
}

/// The corrected route's σ covers its errors, and says how large they are: with the
/// control points' σ at the configured 1 m (the simulated survey is exact, so the σ are
/// cautious there), and at 0.1 m, where the σ must also not overstate the errors. The
/// gyros' heading walk turns the route from the start (about 8 m over this run's 15 km),
/// and the fit answers much of that turn through the control points: the σ weigh the
/// two together (`stages/src/route_sigma.rs`). Taken apart, as before, the σ at 0.1 m
/// were 0.9–1.2 m at the end where the errors were centimetres, and the errors' RMS in σ
/// 0.35, 0.19 and 0.25 (north, east, heading); now 1.10, 0.49 and 0.71.
#[test]
fn route_sigma_covers_the_truth() {
    let tmp = tempfile::tempdir().unwrap();
    let name = "sim-0063";
    let (run, out) = process(tmp.path(), 63, &["--cp-at-every-stop"]);
    let (inside, z, end) = route_sigma_z(&run, &out, name);
    eprintln!("σ of 1 m at the points: within 3σ {inside:.3?}, RMS z {z:.2?}");
    assert!(inside.iter().all(|&s| s >= 0.95), "{inside:?}");
    // At the last control point, the route is known as well as the points together say.
    assert!(end[0] < 1.0 && end[1] < 1.0, "{end:?}");

    let config = tmp.path().join("points.toml");
    std::fs::write(&config, "[disupt]\nposition_sigma_m = 0.1\n").unwrap();
    let exact = tmp.path().join("o01");
    run_until_with(
        &run,
        &exact,
        "disupt",
        &["--config", config.to_str().unwrap()],
    );
    let (inside, z, end) = route_sigma_z(&run, &exact, name);
    eprintln!("σ of 0.1 m at the points: within 3σ {inside:.3?}, RMS z {z:.2?}");
    assert!(inside.iter().all(|&s| s >= 0.95), "{inside:?}");
    // Honest, not cautious: the errors' RMS at least half their σ, north and east
    // together and in heading (one run's walk: its epochs are far from independent).
    let position_z = ((z[0] * z[0] + z[1] * z[1]) / 2.0).sqrt();
    assert!(position_z >= 0.5 && z[2] >= 0.5, "{z:?}");
    assert!(position_z <= 2.0 && z[2] <= 2.0, "{z:?}");
    assert!(end[0] < 0.3 && end[1] < 0.3, "{end:?}");
}

/// A run with neither a static start nor a control point is an error that says so.
#[test]
fn no_static_start_and_no_control_point_is_an_error() {
    let tmp = tempfile::tempdir().unwrap();
    let run = simulated_run(
        tmp.path(),
        64,
        &["--duration-s", "600", "--log-start-s", "200"],
    );
    let manifest = run.join("run.toml");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let cut = text.find("[[control_point]]").unwrap();
    std::fs::write(&manifest, &text[..cut]).unwrap();
    let out = tmp.path().join("o");
    let o = unz_output(&[
        "navigate",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("neither a static start nor a control point"),
        "{err}"
    );
}

/// A static start given longer than the vehicle stood (`static_s = 150` in a run that
/// drove off at 90 s: a manifest copied from another run, or a typo) averaged the drive
/// into the alignment: the joint fit left its bounds and OEPI's azimuth was 4.85° off.
/// The static start now ends a second before the odometer shows the vehicle moving, as
/// navigate.json and the campaign's note say, and the methods find the truth as with the
/// manifest's own 85 s (measured: the joint fit 0.0007° off, OEPI 0.0006°; with 85 s,
/// 0.005° both). The bound, 0.05°, is ten times the run's own error and a hundredth of
/// what the drive's average cost.
#[test]
fn a_static_start_given_past_the_drive_off_ends_where_the_vehicle_moved() {
    let tmp = tempfile::tempdir().unwrap();
    let name = "sim-0080";
    let run = simulated_run(tmp.path(), 80, &["--duration-s", "200"]);
    edit_manifest(&run.join("run.toml"), |m| {
        m["initial"]["static_s"] = 150.0.into();
    });
    let out = tmp.path().join("o");
    let o = unz_output(&["run", run.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let nav: NavigateSummary = read_json(&out.join(name).join("navigate/navigate.json"));
    // The simulated vehicle drives off at 90 s, gently; its odometer passes 10 cm over a
    // second within 3 s (92.76 s; 5 cm from the start at 92.25 s).
    let cut = nav.initial.static_cut.expect("the static start cut");
    assert_eq!(cut.given_s, 150.0);
    assert!((90.0..93.0).contains(&cut.moved_s), "{cut:?}");
    assert!(
        (nav.initial.static_s - (cut.moved_s - 1.0)).abs() < 0.011,
        "{:?}",
        nav.initial
    );
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(summary.contains(&cut.said()), "{summary}");
    assert!(
        String::from_utf8_lossy(&o.stderr).contains(&format!("{name}: navigate: {}", cut.said())),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let t = truth(&run);
    let d = disupt_json(&out, name);
    for method in ["joint", "oepi"] {
        let got = d
            .methods
            .get(method)
            .unwrap_or_else(|| panic!("{method}: {:?}", d.skipped));
        let err = (got.outcome.x.azimuth_deg - t.azimuth_deg + 180.0).rem_euclid(360.0) - 180.0;
        eprintln!("{method}: azimuth {err:+.4}° off the truth");
        assert!(err.abs() < 0.05, "{method}: azimuth {err}° off the truth");
    }
}

/// A route that loops back past its start point, with its only control point there
/// (seed 127: 20 m from the start after 9 km), surveyed 10 m off as a real point may be
/// (or the route's own error at it): the control points then hardly say anything of the
/// azimuth. The coarse search's turn (a match of the point at some other azimuth) is
/// refused because the pitch and roll refuse it, and OEPI, which follows the point alone,
/// does not correct the run; OWPI (the log's pitch and roll) does. The old code turned
/// the start by 20° and corrected the run by OEPI 13.3° off the truth.
#[test]
fn a_route_looping_back_to_its_only_control_point_is_not_turned_by_it() {
    let tmp = tempfile::tempdir().unwrap();
    let name = "sim-0127";
    let run = simulated_run(tmp.path(), 127, &["--azimuth-error-deg", "5.3"]);
    let t = truth(&run);
    // The truth's closest pass by the start after 3 km (the truth read once).
    let (_, truth_batches) = read_batches(&run.join("truth.parquet")).unwrap();
    let truth_column = |name: &str| -> Vec<f64> {
        truth_batches
            .iter()
            .flat_map(|b| f64_column(b, name).unwrap())
            .collect()
    };
    let (north, east, dist) = (
        truth_column("north_m"),
        truth_column("east_m"),
        truth_column("distance_m"),
    );
    let k = (0..north.len())
        .filter(|&k| dist[k] > 3000.0)
        .min_by(|&a, &b| north[a].hypot(east[a]).total_cmp(&north[b].hypot(east[b])))
        .unwrap();
    let away_m = north[k].hypot(east[k]);
    assert!(
        away_m < 25.0 && dist[k] > 8000.0,
        "{away_m} m after {} m",
        dist[k]
    );
    let (lat, lon, h) = (
        truth_column("lat_deg")[k],
        truth_column("lon_deg")[k],
        truth_column("h_m")[k],
    );
    let t_ns: Vec<i64> = truth_batches
        .iter()
        .flat_map(|b| unz_formats::tables::i64_column(b, "t_ns").unwrap().to_vec())
        .collect();
    let t_s = t_ns[k] as f64 * 1e-9;
    let manifest = run.join("run.toml");
    let mut m: toml::Table = toml::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    let mut point = toml::Table::new();
    point.insert("id".into(), 9.into());
    point.insert("latitude_deg".into(), (lat + 10.0 / 111_250.0).into());
    point.insert("longitude_deg".into(), lon.into());
    point.insert("height_m".into(), h.into());
    point.insert("t_s".into(), t_s.into());
    m.insert(
        "control_point".into(),
        vec![toml::Value::Table(point)].into(),
    );
    std::fs::write(&manifest, toml::to_string(&m).unwrap()).unwrap();
    let out = tmp.path().join("o");
    // The campaign, every stage: its summary carries the note.
    run_until(run.parent().unwrap(), &out, "review");
    let d = disupt_json(&out, name);
    let err = |az: f64| (az - t.azimuth_deg + 180.0).rem_euclid(360.0) - 180.0;
    let refused = d.coarse_azimuth_refused.expect("the coarse turn refused");
    assert!(d.coarse_azimuth_deg.is_none());
    assert!(
        refused.kryt1_rad > refused.start_kryt1_rad && err(refused.azimuth_deg).abs() > 5.0,
        "{refused:?}"
    );
    let by = d.corrected_by.as_deref().unwrap();
    let corrected = err(d.methods[by].outcome.x.azimuth_deg);
    eprintln!(
        "loop: corrected by {by}, azimuth {corrected:+.2}° off; OEPI {:+.2}°, refused coarse \
         turn {:+.1}° off; not used: {:?}",
        err(d.methods["oepi"].outcome.x.azimuth_deg),
        err(refused.azimuth_deg),
        d.not_used
    );
    // OWPI's over this route: 0.63° (its Kryt1-only fit; the manifest is 5.3° off).
    assert!(corrected.abs() < 1.5, "{corrected}°");
    assert!(d.not_used.contains_key("oepi"), "{:?}", d.not_used);
    let tables = std::fs::read_to_string(out.join(name).join("disupt/disupt.md")).unwrap();
    assert!(
        tables.contains("Note: OEPI not used for the corrected navigation")
            && tables.contains("Note: coarse azimuth search: turning the route"),
        "{tables}"
    );
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains("oepi not used: its settings fit the log's pitch and roll"),
        "{summary}"
    );
}

/// A right coarse turn is taken where only the horizontal drifts made Kryt1 refuse it. On
/// a 15-minute run (seed 5, the manifest 5.5° off), Kryt1 at the initial (zero) horizontal
/// drifts is larger at the control points' turn (1.34 rad against 1.05 at the start):
/// the manifest's wrong azimuth misapplies the Earth's rate by about as much as the
/// drifts. With the drifts free the turn has the less (0.30 against 0.38), so it is taken,
/// and no note of a route looping back reaches the user. The previous build refused it and
/// told the user the control points lay too near the start.
#[test]
fn a_right_coarse_turn_is_taken_where_only_the_drifts_made_kryt1_refuse_it() {
    let tmp = tempfile::tempdir().unwrap();
    let name = "sim-0005";
    let run = simulated_run(tmp.path(), 5, &["--duration-s", "900"]);
    let t = truth(&run);
    let out = tmp.path().join("o");
    run_until(&run, &out, "disupt");
    let d = disupt_json(&out, name);
    let err = |az: f64| (az - t.azimuth_deg + 180.0).rem_euclid(360.0) - 180.0;
    assert!(
        d.coarse_azimuth_refused.is_none(),
        "{:?}",
        d.coarse_azimuth_refused
    );
    // The coarse grid's step is 1°: its turn within a step of the truth (0.49° measured).
    let coarse = d.coarse_azimuth_deg.expect("the coarse turn taken");
    assert!(err(coarse).abs() < 1.0, "{coarse}");
    // The methods' own accuracy from there (the joint's 0.017° measured; 0.1° is the
    // azimuth target of the simulated accuracy cases).
    let by = d.corrected_by.as_deref().unwrap();
    let corrected = err(d.methods[by].outcome.x.azimuth_deg);
    assert!(corrected.abs() < 0.1, "{by}: {corrected}°");
    let tables = std::fs::read_to_string(out.join(name).join("disupt/disupt.md")).unwrap();
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    for text in [&tables, &summary] {
        assert!(!text.contains("coarse azimuth search"), "{text}");
    }
}

/// An IMU turned 1.5° on the vehicle (seed 311), which the joint fit holds at zero by
/// default: the control points see the boresight and the azimuth only as their sum, and
/// the fit's azimuth took it (0.72° off at σ 0.18°). Its residuals show the
/// boresight (9.4σ), so the fit is redone with it free: the azimuth within a few tenths
/// of a degree and its σ honest, with a note in `disupt.md` and the campaign summary. A
/// run without a boresight (seed 108, 0.0σ) keeps the boresight-free fit and says nothing.
#[test]
fn an_odometer_boresight_the_residuals_show_is_estimated() {
    let tmp = tempfile::tempdir().unwrap();
    let turned = simulated_run(tmp.path(), 311, &["--odo-boresight-deg", "1.5"]);
    let plain = simulated_run(tmp.path(), 108, &[]);
    let out = tmp.path().join("o");
    run_until(turned.parent().unwrap(), &out, "disupt");
    let err = |az: f64, t: &TrueSettings| (az - t.azimuth_deg + 180.0).rem_euclid(360.0) - 180.0;

    let t = truth(&turned);
    let d = disupt_json(&out, "sim-0311");
    let check = d
        .joint_odo_yaw_check
        .clone()
        .expect("the boresight checked");
    eprintln!("boresight 1.5°: {check:?}");
    assert!(check.refit && check.refit_error.is_none(), "{check:?}");
    assert!(
        check.seen.odo_yaw_deg.abs() > 3.0 * check.seen.sigma_deg
            && (check.seen.odo_yaw_deg - 1.5).abs() < 3.0 * check.seen.sigma_deg,
        "{check:?}"
    );
    let j = &d.methods["joint"].outcome.x;
    let sd = j.sigma.as_ref().unwrap();
    let az = err(j.azimuth_deg, &t);
    eprintln!(
        "joint: azimuth {az:+.3}° ± {:.3}°, boresight {:.3}° ± {:.3}°",
        sd.azimuth_deg, j.odo_yaw_deg, sd.odo_yaw_deg
    );
    assert!(az.abs() < 0.5 && az.abs() < 3.0 * sd.azimuth_deg, "{az}");
    assert!((j.odo_yaw_deg - 1.5).abs() < 3.0 * sd.odo_yaw_deg, "{j:?}");
    let tables = std::fs::read_to_string(out.join("sim-0311/disupt/disupt.md")).unwrap();
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    for text in [&tables, &summary] {
        assert!(
            text.contains("show an odometer yaw boresight of +")
                && text.contains("the joint fit estimates it"),
            "{text}"
        );
    }

    let t = truth(&plain);
    let d = disupt_json(&out, "sim-0108");
    let check = d
        .joint_odo_yaw_check
        .clone()
        .expect("the boresight checked");
    assert!(
        !check.refit && check.seen.odo_yaw_deg.abs() < 3.0 * check.seen.sigma_deg,
        "{check:?}"
    );
    let j = &d.methods["joint"].outcome.x;
    assert_eq!(j.odo_yaw_deg, 0.0);
    assert!(err(j.azimuth_deg, &t).abs() < 0.1);
    let tables = std::fs::read_to_string(out.join("sim-0108/disupt/disupt.md")).unwrap();
    // (Its Heights section may name the odometer's pitch boresight.)
    assert!(!tables.contains("yaw boresight"), "{tables}");
    // The runs' rows name it once (sim-0311's note); below them, the IMU's yaw pooled
    // over the two runs finds them disagreeing: two installations.
    let rows = summary.split("\n## ").next().unwrap();
    let (_, pooled) = summary.split_once("\n## The IMU's yaw").expect("pooled");
    assert_eq!(rows.matches("boresight").count(), 1, "{summary}");
    assert!(pooled.contains("disagree beyond their σ"), "{summary}");
}

/// A run whose vehicle never drives (a static test, a run stopped after its alignment:
/// 120 s, 60 s of it the static start, 0 m by the odometer) is not "corrected": at rest
/// the azimuth and the horizontal drifts are confounded and its control point is its
/// start. Every method is refused with the reason, once in the campaign's note, and the
/// corrected navigation keeps the initial settings (the old code had OEPI correct it,
/// 3° off the truth, beside a joint fit "out of its bounds").
#[test]
fn a_run_that_never_drives_is_not_corrected() {
    let tmp = tempfile::tempdir().unwrap();
    let name = "sim-0009";
    let run = simulated_run(tmp.path(), 9, &["--duration-s", "120", "--static-s", "60"]);
    let out = tmp.path().join("o");
    // The campaign, every stage: its summary carries the note.
    run_until(run.parent().unwrap(), &out, "review");
    let nav: NavigateSummary = read_json(&out.join(name).join("navigate/navigate.json"));
    assert!(nav.distance_m < 1.0, "{}", nav.distance_m);
    let d = disupt_json(&out, name);
    assert!(d.methods.is_empty(), "{:?}", d.methods.keys());
    assert_eq!(d.corrected_by, None);
    let names: Vec<&str> = d.skipped.keys().map(String::as_str).collect();
    assert_eq!(names, ["joint", "oepi", "owpi"]);
    for why in d.skipped.values() {
        assert!(
            why.starts_with("the vehicle travelled 0.0 m by its odometer, less than 50 m"),
            "{why}"
        );
    }
    // The corrected navigation is the initial settings' (heading at the first sample).
    let heading = column(
        &out.join(name).join("disupt/corrected_nav.parquet"),
        "heading_deg",
    )[0];
    let initial = d.before.x.azimuth_deg;
    assert!(
        ((heading - initial + 180.0).rem_euclid(360.0) - 180.0).abs() < 1e-3,
        "{heading} against {initial}"
    );
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains("| joint, oepi, owpi not run: the vehicle travelled 0.0 m")
            && summary.matches("the vehicle travelled").count() == 1,
        "{summary}"
    );
}

/// An odometer failed for a minute while driving, its count held (the readings after it
/// short by what was driven meanwhile), flagged by the log or not (a wheel sensor broken
/// at a stop, found by the IMU as the vehicle drives off): the ingest bridges it with
/// the inertial along-track speed, and the corrected route is as good as the same run's
/// without the failure, where a held count put the control points hundreds of metres
/// off. The campaign's summary says the failure was bridged, with its length and distance.
#[test]
fn an_odometer_failure_while_driving_is_bridged_by_the_inertial_speed() {
    let name = "sim-0063";
    let tmp0 = tempfile::tempdir().unwrap();
    let (run0, out0) = process(tmp0.path(), 63, &[]);
    let worst0 = worst_m(&route_errors(&run0, &out0, name));
    let az0 = disupt_json(&out0, name).methods["joint"]
        .outcome
        .x
        .azimuth_deg;
    let odo0 = column(
        &out0.join(name).join("ingest/odometer.parquet"),
        "distance_m",
    );
    for flagged in [true, false] {
        let tmp = tempfile::tempdir().unwrap();
        let run = simulated_run(tmp.path(), 63, &[]);
        // The first minute from 600 s on over which the vehicle drives at least 400 m: it
        // stands at its start, so unflagged the count stops at rest and stays stopped as
        // the vehicle drives off (found by the IMU).
        let truth_m = column(&run.join("truth.parquet"), "distance_m");
        let len = 6000;
        let k0 = (60_000..truth_m.len() - len)
            .find(|&k| truth_m[k + len] - truth_m[k] > 400.0)
            .unwrap();
        let driven_m = truth_m[k0 + len] - truth_m[k0];
        crate::util::hold_count(&run.join(format!("{name}.unz")), k0, len, flagged);
        let out = tmp.path().join("o");
        run_until(&run, &out, "disupt");

        let ingest: unz_formats::IngestReport =
            read_json(&out.join(name).join("ingest/ingest.json"));
        let f = ingest.odometer_failures.unwrap();
        assert_eq!((f.bridged, f.not_bridged), (1, 0));
        if flagged {
            assert_eq!((f.bridged_samples, f.stuck, f.stuck_samples), (6000, 0, 0));
        } else {
            // From the IMU's watch (5 s) before it found the vehicle moving, after it
            // drove off (here 2.5 s: it pulls away gently), to the last sample held: the
            // failure covers the drive.
            let off = (k0..k0 + len)
                .find(|&k| truth_m[k] > truth_m[k0] + 0.01)
                .unwrap();
            let driving = (k0 + len + 1 - off) as u64;
            assert_eq!((f.stuck, f.stuck_samples), (1, f.bridged_samples));
            assert!(
                (driving..driving + 500).contains(&f.stuck_samples),
                "{} failed, {driving} driven",
                f.stuck_samples
            );
        }
        // The odometer's own distance across it (its nominal scale), within the bridge's
        // error over a minute (stages/tests/odo_bridge.rs: 0.69 m rms, 1.6 m at most, 1.1
        // and 3.1 m with the odometer's scale 1 % off).
        let odo = column(
            &out.join(name).join("ingest/odometer.parquet"),
            "distance_m",
        );
        let across_err = odo[k0 + len] - odo0[k0 + len] - (odo[k0 - 1] - odo0[k0 - 1]);
        let errors = route_errors(&run, &out, name);
        let worst = worst_m(&errors);
        let az = disupt_json(&out, name).methods["joint"]
            .outcome
            .x
            .azimuth_deg;
        eprintln!(
            "odometer failed (flagged: {flagged}) {:.0}–{:.0} s over {driven_m:.0} m: bridged \
             {:.1} m, its error {across_err:.3} m; worst route error {worst:.2} m (without the \
             failure {worst0:.2} m); joint azimuth {:.4}° against {:.4}°",
            k0 as f64 * 0.01,
            (k0 + len) as f64 * 0.01,
            f.bridged_distance_m,
            az,
            az0
        );
        assert!(across_err.abs() < 2.0, "bridge off by {across_err} m");
        assert!(
            worst < 1.25 * worst0 + 2.0,
            "worst route error {worst} m, {worst0} m without the failure"
        );
        assert!(
            (az - az0).abs() < 0.05,
            "joint azimuth {az}°, {az0}° without"
        );
        let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
        let said = if flagged {
            "the odometer is flagged failed (status bit 1) on 6000 samples (60.0 s); bridged \
             by the inertial along-track speed: 1 failure (60.0 s, "
                .to_owned()
        } else {
            format!(
                "the odometer's distance stood while the vehicle moved, unflagged: 1 \
                 time ({} samples, {:.1} s); bridged by the inertial along-track speed: 1 \
                 failure (",
                f.stuck_samples,
                f.stuck_samples as f64 * 0.01
            )
        };
        assert!(summary.contains(&said), "{summary}");
        assert!(!summary.contains("no distance over them"), "{summary}");
    }
}

/// A 40-minute simulated run `seed` with its odometer 0.4 s late, processed to disupt
/// with `args` twice: as simulated (`.0`), and with its count held and flagged failed for
/// a minute that begins at a stop and ends driving (`.1`); the failure's first sample
/// (`.2`).
struct LateFailure {
    name: String,
    clean: (PathBuf, PathBuf),
    failed: (PathBuf, PathBuf),
    k0: usize,
    _dir: tempfile::TempDir,
}

/// The failure's samples.
const LATE_FAILURE_LEN: usize = 6000;

impl LateFailure {
    fn run(seed: u32, args: &[&str]) -> Self {
        let name = format!("sim-{seed:04}");
        let dir = tempfile::tempdir().unwrap();
        let run_to_disupt = |run: &Path, out: &Path| {
            crate::util::run_until_with(run, out, "disupt", args);
        };
        let run0 = simulated_run(&dir.path().join("clean"), seed, &["--odo-lag-s", "0.4"]);
        let out0 = dir.path().join("o-clean");
        run_to_disupt(&run0, &out0);
        let run = simulated_run(&dir.path().join("failed"), seed, &["--odo-lag-s", "0.4"]);
        let truth_m = column(&run.join("truth.parquet"), "distance_m");
        let len = LATE_FAILURE_LEN;
        let k0 = (60_000..truth_m.len() - len)
            .find(|&k| truth_m[k + len] - truth_m[k] > 400.0)
            .unwrap();
        // Standing at the failure's start.
        assert!(truth_m[k0] - truth_m[k0 - 1000] < 0.01);
        crate::util::hold_count(&run.join(format!("{name}.unz")), k0, len, true);
        let out = dir.path().join("o");
        run_to_disupt(&run, &out);
        Self {
            name,
            clean: (run0, out0),
            failed: (run, out),
            k0,
            _dir: dir,
        }
    }

    /// How far the ingest's bridge is off across the failure, m.
    fn ingest_bridge_off_m(&self) -> f64 {
        let odometer = |out: &Path| {
            column(
                &out.join(&self.name).join("ingest/odometer.parquet"),
                "distance_m",
            )
        };
        let (odo0, odo) = (odometer(&self.clean.1), odometer(&self.failed.1));
        let (k0, k1) = (self.k0 - 1, self.k0 + LATE_FAILURE_LEN);
        odo[k1] - odo0[k1] - (odo[k0] - odo0[k0])
    }

    /// The worst errors of the corrected route against truth, m: with the failure, and
    /// without.
    fn worst_route_m(&self) -> (f64, f64) {
        let worst = |(run, out): &(PathBuf, PathBuf)| worst_m(&route_errors(run, out, &self.name));
        (worst(&self.failed), worst(&self.clean))
    }
}

/// An odometer 0.4 s late, flagged failed for a minute that begins at a stop: the
/// readings around the failure do not show the lag (the vehicle stands in those before,
/// drives at a constant speed in those after), so a bridge that holds the lag near zero
/// is off by the lag times the speed (3.7 m here). With the lag configured (`[derive]
/// odo_time_offset_s = -0.4`), the ingest's bridge searches about it: within 1.5 m, and
/// the route back to the same run's without the failure.
#[test]
fn an_odometer_failure_is_bridged_about_the_configured_lag() {
    let config_dir = tempfile::tempdir().unwrap();
    let config = config_dir.path().join("unz.toml");
    std::fs::write(&config, "[derive]\nodo_time_offset_s = -0.4\n").unwrap();
    let case = LateFailure::run(64, &["--config", config.to_str().unwrap()]);
    let across_err = case.ingest_bridge_off_m();
    let (worst, worst0) = case.worst_route_m();
    eprintln!(
        "lag configured: bridge {across_err:.3} m off; worst route error {worst:.2} m \
         ({worst0:.2} m without the failure)"
    );
    assert!(across_err.abs() < 1.5, "bridge off by {across_err} m");
    assert!(
        worst < 1.25 * worst0 + 2.0,
        "worst route error {worst} m, {worst0} m without the failure"
    );
}

/// The same failure without the lag configured (seed 65): the ingest's bridge holds the
/// lag near zero and is 3.6 m off, and the previous build's joint fit, scoring each lag
/// on that bridge, estimated the lag at −0.09 s (0.30 s without the failure) and left the
/// corrected route 9.6 m off (2.2 m without). The disupt stage now bridges the failure
/// again at each lag the joint fit tries: the lag is the run's without the failure, the
/// bridge changes by the ingest's error, and the route is back to the run's without it.
#[test]
fn an_odometer_failure_is_bridged_again_at_the_estimated_lag() {
    let case = LateFailure::run(65, &[]);
    let across_err = case.ingest_bridge_off_m();
    let (worst, worst0) = case.worst_route_m();
    let joint = |out: &Path| {
        let d = disupt_json(out, &case.name);
        d.methods["joint"].clone()
    };
    let (j, j0) = (joint(&case.failed.1), joint(&case.clean.1));
    let (lag, lag0) = (j.outcome.x.odo_lag_s, j0.outcome.x.odo_lag_s);
    let rebridged = j.rebridged.expect("the failure bridged again");
    eprintln!(
        "lag estimated: {lag:.3} s ({lag0:.3} s without the failure); ingest's bridge \
         {across_err:.2} m off, changed by {:.2} m; worst route error {worst:.2} m \
         ({worst0:.2} m without the failure)",
        rebridged.largest_change_m
    );
    assert!(j0.rebridged.is_none());
    assert_eq!((rebridged.failures, rebridged.left), (1, 0));
    // `odometer.parquet` names the failure's rows bridged, and no other.
    let (_, batches) = read_batches(
        &case
            .failed
            .1
            .join(&case.name)
            .join("ingest/odometer.parquet"),
    )
    .unwrap();
    let source: Vec<u8> = batches
        .iter()
        .flat_map(|b| u8_column(b, "distance_source").unwrap())
        .collect();
    let bridged: Vec<usize> = (0..source.len()).filter(|&k| source[k] != 0).collect();
    assert_eq!(bridged.len(), LATE_FAILURE_LEN);
    assert_eq!(bridged[0], case.k0);
    assert!(bridged.iter().all(|&k| source[k] == 1));
    // The ingest's bridge is off by about the lag times the speed after the failure;
    // bridged again, within 1.5 m (as with the lag configured).
    assert!(
        across_err.abs() > 2.0,
        "the ingest's bridge {across_err} m off"
    );
    let rebridged_err = across_err + rebridged.largest_change_m;
    assert!(
        rebridged_err.abs() < 1.5,
        "bridged again {rebridged_err} m off"
    );
    // The lag's σ is 0.03–0.06 s on these runs.
    assert!(
        (lag - lag0).abs() < 0.05,
        "lag {lag} s, {lag0} s without the failure"
    );
    assert!(
        worst < 1.25 * worst0 + 2.0,
        "worst route error {worst} m, {worst0} m without the failure"
    );
    let md =
        std::fs::read_to_string(case.failed.1.join(&case.name).join("disupt/disupt.md")).unwrap();
    assert!(
        md.contains(
            "The joint fit bridged the odometer's failures again at each lag it tried: 1 (at \
             its lag, the distance across one changed by -3."
        ),
        "{md}"
    );
    let summary = std::fs::read_to_string(case.failed.1.join("campaign.md")).unwrap();
    assert!(
        summary.contains("; the joint fit bridged the odometer's failures again at each lag"),
        "{summary}"
    );
    // The campaign's table has both, for queries over a campaign.
    let campaign_column = |name: &str| column(&case.failed.1.join("campaign.parquet"), name);
    assert_eq!(campaign_column("odometer_failed_samples"), [6000.0]);
    assert_eq!(
        campaign_column("joint_rebridge_change_m"),
        [rebridged.largest_change_m]
    );
    // The review shows the failure on the speed's plot: the 10-Hz blocks that hold its
    // 6000 samples (600, or 601 where it begins inside one), and nothing held.
    let run = case.failed.0.to_str().unwrap();
    unz_ok(&["review", run, "--out", case.failed.1.to_str().unwrap()]);
    let Some(py) = crate::util::python() else {
        return;
    };
    let rrd = case
        .failed
        .1
        .join(&case.name)
        .join(format!("review/{}.rrd", case.name));
    let info = crate::util::python_json(&py, "check_rrd.py", &[&rrd]);
    let rows = &info["temporal_rows"];
    let bridged = rows["/plots/speed/bridged"].as_i64().unwrap();
    assert!((600..=601).contains(&bridged), "{bridged} blocks bridged");
    assert!(rows.get("/plots/speed/held").is_none(), "{info}");
}

/// A route driven out and back (`unz simulate --out-and-back`) stops at its mid-route
/// point both ways, and the crew marks it each time. Both marks are at rest, 4 km of
/// driving apart, and the navigation puts them at the same place: each is a visit,
/// compared with the point, and the point is held out at both at once. The previous
/// build used the last visit only: 3.27 m worst on this run, against 1.93 m with both
/// (seeds 63–69: 0.49–3.27 m against 0.24–1.93 m, every one better).
#[test]
fn a_point_the_route_comes_back_to_is_compared_at_each_visit() {
    let tmp = tempfile::tempdir().unwrap();
    let name = "sim-0067";
    let (run, out) = process(tmp.path(), 67, &["--out-and-back"]);
    let nav: NavigateSummary = read_json(&out.join(name).join("navigate/navigate.json"));
    let ids: Vec<u32> = nav.control_points.iter().map(|c| c.id).collect();
    // The mid-route point both ways, the far point, and the start the route came home to.
    assert_eq!(ids, [1, 1, 2, 3], "{:?}", nav.control_points);
    let r = &nav.repeated_marks[0];
    assert_eq!((r.id, r.marks, r.visits_t_s.len()), (1, 2, 2), "{r:?}");
    assert!(r.elsewhere_t_s.is_empty());
    let visits: Vec<f64> = nav.control_points[..2].iter().map(|c| c.t_s).collect();
    assert_eq!(visits, r.visits_t_s);
    assert!(visits[1] - visits[0] > 600.0, "{visits:?}");

    let worst = worst_m(&route_errors(&run, &out, name));
    eprintln!("worst route error with both visits: {worst:.2} m");
    // Measured 1.93 m; the last visit alone gave 3.27 m.
    assert!(worst < 2.4, "{worst} m");
    let d = disupt_json(&out, name);
    let joint = &d.methods["joint"];
    assert_eq!(joint.outcome.control_points.len(), 4);
    // The point held out at both visits at once: each visit's error is the fit's without
    // the point, which predicts them alike (the same settings, σ from one covariance).
    let h = joint.holdout.as_ref().unwrap();
    let ones: Vec<_> = h.iter().filter(|p| p.id == 1).collect();
    assert_eq!(ones.len(), 2);
    assert_eq!((ones[0].t_s, ones[1].t_s), (visits[0], visits[1]));
    // Held out together, both visits are far from the point (16–17 m: the route's
    // error there without it), and within 3σ of what the fit without it predicts.
    for p in &ones {
        let e = p.dx_m.hypot(p.dy_m);
        assert!(e > 5.0 && p.error_sigma.unwrap() < 3.0, "{p:?}");
    }
    let md = std::fs::read_to_string(out.join(name).join("disupt/disupt.md")).unwrap();
    assert!(
        md.contains(&format!("| 1 at t_s = {:.1} |", visits[0])),
        "{md}"
    );
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    let note = format!(
        "control point 1 visited 2 times (marked 2), at t_s = {:.2}, {:.2}",
        visits[0], visits[1]
    );
    assert!(summary.contains(&note), "{summary}");
}

/// A manifest may list thousands of control points (its megabyte holds about 9 000). The
/// hold-out's exact passes run a chunk at a time: held all at once, their observations
/// (each the run's epochs and every point) took a 10-minute run's disupt process with
/// 3 000 points to 613 MB (5 050 points: 2.0 GB). Now it stays near its usual 50 MB, and
/// every point has its hold-out.
#[test]
fn thousands_of_control_points_hold_out_in_bounded_memory() {
    let tmp = tempfile::tempdir().unwrap();
    let run = simulated_run(tmp.path(), 7, &["--duration-s", "600"]);
    // The truth read once, its columns taken from its batches.
    let (_, batches) = read_batches(&run.join("truth.parquet")).unwrap();
    let truth_column = |name: &str| -> Vec<f64> {
        (batches.iter())
            .flat_map(|b| f64_column(b, name).unwrap())
            .collect()
    };
    let (lat, lon, h) = (
        truth_column("lat_deg"),
        truth_column("lon_deg"),
        truth_column("h_m"),
    );
    let t_ns: Vec<i64> = (batches.iter())
        .flat_map(|b| i64_column(b, "t_ns").unwrap())
        .collect();
    // A point every 0.17 s of the drive, where the truth was (the static start left out).
    let manifest = run.join("run.toml");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let mut text = text[..text.find("[[control_point]]").unwrap()].to_owned();
    let samples: Vec<usize> = (9_500..t_ns.len()).step_by(17).collect();
    for (id, &k) in samples.iter().enumerate() {
        text += &format!(
            "[[control_point]]\nid = {}\nlatitude_deg = {:.9}\nlongitude_deg = {:.9}\n\
             height_m = {:.3}\nt_s = {:.2}\n",
            id + 1,
            lat[k],
            lon[k],
            h[k],
            (t_ns[k] - t_ns[0]) as f64 * 1e-9
        );
    }
    std::fs::write(&manifest, text).unwrap();
    let out = tmp.path().join("o");
    let o = unz_output(&[
        "disupt",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{log}");
    // The process's peak as its last phase line gives it ("peak 48 MB)").
    let peak_mb: f64 = log
        .rsplit_once("peak ")
        .and_then(|(_, rest)| rest.split_once(" MB"))
        .and_then(|(mb, _)| mb.parse().ok())
        .unwrap_or_else(|| panic!("no peak in {log}"));
    assert!(peak_mb < 150.0, "peak {peak_mb} MB");
    let d: DisuptOut = read_json(&out.join("sim-0007/disupt/disupt.json"));
    assert_eq!(
        d.methods["joint"].holdout.as_ref().unwrap().len(),
        samples.len()
    );
}

/// Seconds of GPS week at a simulated run's time origin, as its text log's tags.
const TEXT_T0_S: f64 = 100_000.0;

/// The simulated binary run `run` (its ingest stage's output in `ingest`) written again
/// in `dst` as a KF-GINS text log — its ingested IMU increments, the same time base
/// shifted to seconds of week — with its odometer as a speed file of one line a second,
/// the mean speed over the second before each tag (an OBD-II logger's), and its control
/// points timed by its marks (the text form of `scripts/joint_sigma_coverage.py`).
fn as_text_run(run: &Path, ingest: &Path, dst: &Path) {
    use std::fmt::Write as _;
    use unz_formats::tables::vec3_column;
    std::fs::create_dir_all(dst).unwrap();
    let (_, imu) = read_batches(&ingest.join("imu.parquet")).unwrap();
    let mut text = String::new();
    for b in &imu {
        let t = i64_column(b, "t_ns").unwrap();
        let (th, dv) = (
            vec3_column(b, "dtheta_rad").unwrap(),
            vec3_column(b, "dvel_mps").unwrap(),
        );
        for k in 0..t.len() {
            let (a, v) = (th[k], dv[k]);
            writeln!(
                text,
                "{:.3} {:.12e} {:.12e} {:.12e} {:.12e} {:.12e} {:.12e}",
                TEXT_T0_S + t[k] as f64 * 1e-9,
                a[0],
                a[1],
                a[2],
                v[0],
                v[1],
                v[2]
            )
            .unwrap();
        }
    }
    std::fs::write(dst.join("imu.txt"), text).unwrap();
    let odo = ingest.join("odometer.parquet");
    let t_s: Vec<f64> = column_by(&odo, "t_ns", i64_column)
        .iter()
        .map(|&t| t as f64 * 1e-9)
        .collect();
    let dist_m = column(&odo, "distance_m");
    let mut dt: Vec<f64> = t_s.windows(2).map(|w| w[1] - w[0]).collect();
    dt.sort_by(f64::total_cmp);
    let step = ((1.0 / dt[dt.len() / 2]).round() as usize).max(1);
    let mut speeds = String::new();
    for j in (step..t_s.len()).step_by(step) {
        let v = (dist_m[j] - dist_m[j - step]) / (t_s[j] - t_s[j - step]);
        writeln!(speeds, "{:.3} {v:.4}", TEXT_T0_S + t_s[j]).unwrap();
    }
    std::fs::write(dst.join("odometer.txt"), speeds).unwrap();
    let name = run.file_name().unwrap().to_str().unwrap();
    let binary = format!("raw = \"{name}.unz\"\nformat = \"unz-binary\"");
    let mut manifest = std::fs::read_to_string(run.join("run.toml")).unwrap();
    assert!(manifest.contains(&binary), "{manifest}");
    manifest = manifest.replace(&binary, "raw = \"imu.txt\"\nformat = \"kf-gins\"");
    manifest += "\n[odometer]\nfile = \"odometer.txt\"\nkind = \"speed_mps\"\n";
    let marks = ingest.join("marks.parquet");
    let (_, batches) = read_batches(&marks).unwrap();
    for b in &batches {
        let t = i64_column(b, "t_ns").unwrap();
        let ids =
            unz_formats::tables::values_of::<arrow::datatypes::UInt32Type>(b, "point_id").unwrap();
        for (t_ns, id) in t.iter().zip(ids) {
            let at = format!("id = {id}\n");
            let timed = format!("{at}t_s = {:.3}\n", TEXT_T0_S + *t_ns as f64 * 1e-9);
            manifest = manifest.replacen(&at, &timed, 1);
        }
    }
    std::fs::write(dst.join("run.toml"), manifest).unwrap();
    std::fs::copy(run.join("truth.json"), dst.join("truth.json")).unwrap();
}

/// The joint fit's azimuth and drifts less the truth's, in units of its σ, for each run
/// of `runs` (processed into `out`).
fn joint_z(runs: &[PathBuf], out: &Path) -> Vec<[f64; 4]> {
    runs.iter()
        .map(|run| {
            let name = run.file_name().unwrap().to_str().unwrap();
            let t = truth(run);
            let x = &disupt_json(out, name).methods["joint"].outcome.x;
            let s = x.sigma.as_ref().expect("the joint fit's σ");
            let z = [
                (x.azimuth_deg - t.azimuth_deg) / s.azimuth_deg,
                (x.drift_rad_s[0] - t.drift_rad_s[0]) / s.drift_rad_s[0],
                (x.drift_rad_s[1] - t.drift_rad_s[1]) / s.drift_rad_s[1],
                (x.drift_rad_s[2] - t.drift_rad_s[2]) / s.drift_rad_s[2],
            ];
            eprintln!(
                "{name}: azimuth {:+.3}° ± {:.3}°, lag {:+.3} s ± {:.3}; z {z:+.2?}",
                x.azimuth_deg - t.azimuth_deg,
                s.azimuth_deg,
                x.odo_lag_s,
                s.odo_lag_s
            );
            z
        })
        .collect()
}

/// The joint fit's σ cover the truth over five simulated 40-minute runs (seeds 51–55),
/// as binary logs and as the same runs written as text logs with a 1-Hz speed file (a
/// mean over each second: 0.5 s of effective lag, found by the lag search). The z of the
/// azimuth and the three drifts (20 a form) have an RMS within 0.3…1.5 and none beyond
/// 3.5. Honest σ give an RMS about 1 (0.64…1.37 at 1 % and 99 % for 20 independent z;
/// the four of a run are correlated, so wider), a |z| beyond 3.5 once in 2000. Before
/// the gyros' walk and the lag's uncertainty entered the covariance (session 87), the
/// RMS was 2.22 binary and 5.84 text, one azimuth 8.8σ off: the residuals' scatter
/// missed the heading's random walk the fit absorbs, and the σ were conditional on the
/// lag found. Measured since: 0.47 and 0.88. The lower bound keeps the σ from being
/// bought by widening them past use: at most about three times too wide. The hold-outs'
/// predicted spread takes the gyros' walk too: every point's hold-out error stays within
/// the 3.7σ at which a point is called inconsistent (the text runs' reached 4.4σ
/// without the walk; 3.1σ with it, where the refits keep a lag 0.06 s off).
#[test]
fn joint_sigma_covers_the_truth_over_seeds_binary_and_text() {
    let tmp = tempfile::tempdir().unwrap();
    let sims = tmp.path().join("binary");
    unz_ok(&[
        "simulate",
        "--out",
        sims.to_str().unwrap(),
        "--seed",
        "51",
        "--runs",
        "5",
    ]);
    let out_binary = tmp.path().join("out-binary");
    unz_ok(&[
        "run",
        sims.to_str().unwrap(),
        "--out",
        out_binary.to_str().unwrap(),
    ]);
    let texts = tmp.path().join("text");
    let names: Vec<String> = (51..=55).map(|s| format!("sim-{s:04}")).collect();
    let binary_runs: Vec<PathBuf> = names.iter().map(|n| sims.join(n)).collect();
    let text_runs: Vec<PathBuf> = names.iter().map(|n| texts.join(n)).collect();
    for (run, text) in binary_runs.iter().zip(&text_runs) {
        let name = run.file_name().unwrap();
        as_text_run(run, &out_binary.join(name).join("ingest"), text);
    }
    let out_text = tmp.path().join("out-text");
    unz_ok(&[
        "run",
        texts.to_str().unwrap(),
        "--out",
        out_text.to_str().unwrap(),
    ]);
    for (form, runs, out) in [
        ("binary", &binary_runs, &out_binary),
        ("text", &text_runs, &out_text),
    ] {
        let z: Vec<f64> = joint_z(runs, out).into_iter().flatten().collect();
        let rms = (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt();
        let worst = z.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        eprintln!(
            "{form}: RMS z {rms:.2}, largest |z| {worst:.2} of {}",
            z.len()
        );
        assert!((0.3..=1.5).contains(&rms), "{form}: RMS z {rms}");
        assert!(worst <= 3.5, "{form}: |z| {worst}");
        // Every point is correct: none beyond the hold-out's call of inconsistency.
        let holdouts: Vec<f64> = (runs.iter())
            .flat_map(|run| {
                let name = run.file_name().unwrap().to_str().unwrap();
                let d = disupt_json(out, name);
                let h = d.methods["joint"].holdout.clone().expect("hold-outs");
                h.iter().map(|h| h.error_sigma.unwrap()).collect::<Vec<_>>()
            })
            .collect();
        eprintln!("{form}: hold-outs {holdouts:.1?} σ");
        let call = unz_stages::disupt::HOLDOUT_INCONSISTENT_SIGMA;
        assert!(holdouts.iter().all(|e| *e <= call), "{form}: {holdouts:?}");
    }
}
