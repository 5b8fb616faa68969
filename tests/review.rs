//! Review material: the Rerun recording read back by the rerun-sdk of the pinned
//! version, and the campaign report rendered by headless Chromium.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::util::{parquet_rows, python, python_json, unz_ok, unz_output};

#[test]
fn review_recording_reads_back_with_the_pinned_rerun() {
    let tmp = tempfile::tempdir().unwrap();
    let campaign = tmp.path().join("c");
    let out = tmp.path().join("o");
    let (o, c) = (out.to_str().unwrap(), campaign.to_str().unwrap());
    let duration_s = 600.0;
    unz_ok(&[
        "simulate",
        "--out",
        c,
        "--seed",
        "79",
        "--duration-s",
        "600",
    ]);
    let run = campaign.join("sim-0079");
    let r = run.to_str().unwrap();
    unz_ok(&["run", r, "--out", o, "--until", "export"]);
    // The campaign summary carries the joint fit's hold-out errors and odometer lag.
    let (_, batches) =
        unz_formats::parquet_io::read_batches(&out.join("campaign.parquet")).unwrap();
    for col in [
        "joint_holdout_median_m",
        "joint_holdout_max_m",
        "joint_odo_lag_s",
        "joint_odo_lag_sigma_s",
    ] {
        let v = unz_formats::tables::f64_column(&batches[0], col).unwrap();
        assert!(v[0].is_finite(), "{col}: {v:?}");
    }
    // The odometer never failed: no failed sample, nothing bridged again.
    let failed = unz_formats::tables::f64_column(&batches[0], "odometer_failed_samples").unwrap();
    assert_eq!(failed, [0.0]);
    let rebridge = batches[0]
        .column_by_name("joint_rebridge_change_m")
        .unwrap();
    assert!(arrow::array::Array::is_null(rebridge, 0));
    let md = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(md.contains("hold-out median / max [m]"), "{md}");
    assert!(
        !out.join("sim-0079/review").exists(),
        "--until export stops before review"
    );
    unz_ok(&[
        "sweep",
        r,
        "--out",
        o,
        "--over",
        "azimuth_deg=0:300:5,drift_z_rad_s=-1e-6:1e-6:3",
    ]);
    // The review reads the cached tables: nothing before it is recomputed.
    let rev = unz_output(&["review", r, "--out", o]);
    let log = String::from_utf8_lossy(&rev.stderr);
    assert!(rev.status.success(), "{log}");
    for stage in ["ingest", "derive", "navigate", "criteria", "disupt"] {
        assert!(
            log.contains(&format!("sim-0079: {stage}: up to date")),
            "{stage} recomputed:\n{log}"
        );
    }
    assert!(log.contains("sim-0079: review: done"), "{log}");
    let rrd = out.join("sim-0079/review/sim-0079.rrd");
    let bytes = std::fs::metadata(&rrd).unwrap().len();
    // < 30 MB for a 40-minute run: a quarter of that for 10 minutes.
    assert!(bytes < 30_000_000 / 4, "{bytes} bytes");
    // A second review is cached.
    let again = unz_output(&["review", r, "--out", o]);
    assert!(String::from_utf8_lossy(&again.stderr).contains("sim-0079: review: up to date"));

    let Some(py) = python() else { return };
    let info = python_json(&py, "check_rrd.py", &[&rrd]);
    assert_eq!(info["rerun_version"], "0.36.3");
    assert_eq!(info["verified"], true, "{info}");
    assert_eq!(info["recordings"], 1);
    assert_eq!(info["blueprints"], 1, "the recording carries its layout");
    // Expected rows from the cached tables, independently of the writer.
    let samples = parquet_rows(&out.join("sim-0079/derive/derived.parquet"));
    let epochs = parquet_rows(&out.join("sim-0079/criteria/criteria.parquet"));
    let rows = &info["temporal_rows"];
    // The odometer never failed: nothing on the speed's plot but its speed.
    for leaf in ["bridged", "held"] {
        assert!(rows.get(format!("/plots/speed/{leaf}")).is_none(), "{leaf}");
    }
    let decimated = (samples + 9) / 10; // 10 Hz block means of 100 Hz samples
    for e in [
        "speed/u",
        "accel_terms/u_dot",
        "accel_terms/ru",
        "imu/gyro/x",
        "imu/gyro/z",
        "imu/accel/y",
    ] {
        assert_eq!(rows[format!("/plots/{e}")], decimated, "{e}");
        assert_eq!(
            info["timelines"][format!("/plots/{e}")],
            serde_json::json!(["sample", "time"]),
            "{e}"
        );
    }
    for e in [
        "pitch/gyro",
        "pitch/accel",
        "roll/gyro",
        "roll/accel",
        "residuals/d_theta",
        "residuals/kf_d_phi",
        "accel_terms/ax_f",
        "accel_terms/ru_f",
        "kryt1/initial",
        "kryt1/oepi",
        "kryt1/owpi",
        "kryt1/joint",
    ] {
        assert_eq!(rows[format!("/plots/{e}")], epochs, "{e}");
    }
    // The joint fit's route σ at the series rate (time only: it is per sample, not raw).
    for e in [
        "route_sigma/north",
        "route_sigma/east",
        "route_sigma/heading",
    ] {
        assert_eq!(rows[format!("/plots/{e}")], decimated, "{e}");
    }
    // The pose at 2 Hz over the whole run, both ends included.
    for e in ["/world/vehicle", "/map/vehicle"] {
        let n = rows[e].as_i64().unwrap();
        assert!(
            (2.0 * duration_s) as i64 <= n && n <= (2.0 * duration_s) as i64 + 2,
            "{e}: {n}"
        );
    }
    let statics: Vec<&str> = info["static"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    for m in ["initial", "oepi", "owpi", "joint", "truth"] {
        assert!(
            statics.contains(&format!("/map/trajectory/{m}").as_str()),
            "{m}: {statics:?}"
        );
        assert!(
            statics.contains(&format!("/world/trajectory/{m}").as_str()),
            "{m}"
        );
    }
    for e in [
        "/map/control_points",
        "/world/control_points",
        "/world/vehicle/body",
        "/disupt/tables",
        "/readme",
        "/sensitivity/kryt1",
        "/sensitivity/kryt2",
        // The recording's name (the viewer's sources panel showed `<unknown>` without it).
        "/__properties",
    ] {
        assert!(statics.contains(&e), "{e}: {statics:?}");
    }

    // The vehicle's mark is the navigated point: not drawn apart.
    assert!(!statics.contains(&"/world/vehicle/mark"), "{statics:?}");

    // Garbage is refused by the same reader (the check is not a rubber stamp).
    let garbage = tmp.path().join("garbage.rrd");
    std::fs::write(&garbage, b"not a recording at all").unwrap();
    let st = Command::new(&py)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/check_rrd.py"))
        .arg(&garbage)
        .output()
        .unwrap();
    assert!(!st.status.success());
}

/// Headless Chromium: `UNZ_CHROMIUM`, else /usr/bin/chromium (scripts/test.sh installs
/// it). Missing fails the test with instructions unless `UNZ_SKIP_BROWSER=1`.
fn chromium() -> Option<PathBuf> {
    if std::env::var("UNZ_SKIP_BROWSER").as_deref() == Ok("1") {
        eprintln!("UNZ_SKIP_BROWSER=1: browser check skipped");
        return None;
    }
    let p = std::env::var_os("UNZ_CHROMIUM")
        .map_or_else(|| PathBuf::from("/usr/bin/chromium"), PathBuf::from);
    assert!(
        p.is_file(),
        "no Chromium at {}: run the tests through scripts/test.sh, or set UNZ_SKIP_BROWSER=1",
        p.display()
    );
    Some(p)
}

/// Screenshots `page` into `png`; returns the page's console messages.
fn screenshot(chromium: &Path, page: &Path, png: &Path, profile: &Path) -> Vec<String> {
    let out = Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--enable-logging=stderr",
            "--v=0",
            "--window-size=1400,1800",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--screenshot={}", png.display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("chromium runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stderr)
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(str::to_owned)
        .collect()
}

/// (width, height, share of pixels that are not near-white).
fn png_ink(path: &Path) -> (u32, u32, f64) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let px = &buf[..info.buffer_size()];
    let ink = px
        .chunks(channels)
        .filter(|p| p.iter().take(3).any(|&c| c < 200))
        .count();
    (
        info.width,
        info.height,
        ink as f64 / (px.len() / channels) as f64,
    )
}

#[test]
fn campaign_report_renders_in_headless_chromium() {
    let tmp = tempfile::tempdir().unwrap();
    let demo = tmp.path().join("demo");
    unz_ok(&["demo", "--out", demo.to_str().unwrap()]);
    let html_path = demo.join("results/campaign.html");
    let html = std::fs::read_to_string(&html_path).unwrap();
    // Static: nothing to fetch at view time.
    for bad in ["<script", "<link", "src=", "url("] {
        assert!(!html.contains(bad), "{bad} in the report");
    }
    assert_eq!(html.matches("<svg").count(), 5, "five plots");
    assert_eq!(html.matches("<tr class=").count(), 3, "one row per run");
    for run in ["sim-0001", "sim-0002-faulty", "sim-0003"] {
        assert!(
            html.contains(&format!("{run}/review/{run}.rrd")),
            "{run}'s recording linked"
        );
    }
    let Some(chromium) = chromium() else { return };
    let png = tmp.path().join("report.png");
    let console = screenshot(&chromium, &html_path, &png, &tmp.path().join("profile"));
    assert!(console.is_empty(), "console messages: {console:?}");
    let (w, h, ink) = png_ink(&png);
    assert_eq!((w, h), (1400, 1800));
    // Plots and a table, not a blank page (a white page has none; see below).
    assert!(
        ink > 0.01,
        "only {:.2} % of the screenshot is drawn",
        ink * 100.0
    );

    // The console check sees errors when there are some.
    let bad = tmp.path().join("bad.html");
    std::fs::write(
        &bad,
        "<html><body><script>console.error('boom')</script></body></html>",
    )
    .unwrap();
    let console = screenshot(
        &chromium,
        &bad,
        &tmp.path().join("bad.png"),
        &tmp.path().join("profile2"),
    );
    assert!(console.iter().any(|l| l.contains("boom")), "{console:?}");
    let (_, _, blank_ink) = png_ink(&tmp.path().join("bad.png"));
    assert!(
        blank_ink < 0.001,
        "a blank page has {:.2} % ink",
        blank_ink * 100.0
    );
}

/// The recording in the pinned rerun-sdk's web viewer (`rerun --serve-web`), opened by
/// headless Chromium on SwiftShader: `scripts/viewer_screenshot.py` waits for the viewer,
/// saves a screenshot and fails on an error in the viewer's console (map tiles, which
/// need the network, excepted).
#[test]
fn the_recording_opens_in_the_web_viewer() {
    let Some(py) = python() else { return };
    let Some(chromium) = chromium() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let demo = tmp.path().join("demo");
    unz_ok(&["demo", "--out", demo.to_str().unwrap()]);
    let rrd = demo.join("results/sim-0001/review/sim-0001.rrd");
    let png = tmp.path().join("viewer.png");
    let out = Command::new(&py)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/viewer_screenshot.py"))
        .arg(&rrd)
        .arg(&png)
        .args(["--settle-s", "3", "--timeout-s", "400"])
        .env("UNZ_CHROMIUM", &chromium)
        .env("RERUN_ANALYTICS", "0")
        .output()
        .unwrap();
    let said =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{said}");
    assert!(said.contains("0 other errors"), "{said}");
    // The whole 10-minute run streamed into the viewer (its `time` range, ns).
    assert!(
        said.contains("recording sim-0001 loaded") && said.contains(r#""max":599990000000"#),
        "{said}"
    );
    let (w, h, ink) = png_ink(&png);
    assert_eq!((w, h), (1600, 1000));
    // Panels, plots and routes drawn, not a blank page (the viewer's theme is light).
    assert!(
        ink > 0.05,
        "only {:.2} % of the screenshot is drawn: {said}",
        ink * 100.0
    );
}
