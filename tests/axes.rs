//! The IMU's axes on the vehicle (`[vehicle] imu_axes`), end to end on simulated runs.

use crate::util::{read_json, run_until, simulated_run, stage_fails, vehicle_settings_named};

/// An IMU mounted facing backwards (x back, y left, z down), as `unz simulate
/// --imu-axes BLD` logs it: gravity cannot tell its axes from the body's, the odometer's
/// accelerations do. Without its axes named, the derive fails and names them. Named (the
/// simulator's manifest does), every table from the ingest to the corrected navigation is
/// the forward-mounted IMU's, byte for byte: the turn is exact, so the estimates and
/// their errors against the truth are the same. The previous build took the log's axes
/// for the body's: the route ran backwards.
#[test]
fn an_imu_facing_backwards_is_named_and_turned_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let short = ["--duration-s", "900"];
    let forward = simulated_run(&tmp.path().join("frd"), 41, &short);
    let backward = simulated_run(
        &tmp.path().join("bld"),
        41,
        &[short[0], short[1], "--imu-axes", "BLD"],
    );
    let manifest = std::fs::read_to_string(backward.join("run.toml")).unwrap();
    assert!(manifest.contains("imu_axes = \"BLD\""), "{manifest}");
    let log = |run: &std::path::Path| std::fs::read(run.join("sim-0041.unz")).unwrap();
    assert!(log(&forward) != log(&backward));

    // Without the name.
    let nameless = tmp.path().join("nameless");
    std::fs::create_dir_all(&nameless).unwrap();
    std::fs::copy(backward.join("sim-0041.unz"), nameless.join("sim-0041.unz")).unwrap();
    let stripped: String = (manifest.lines())
        .filter(|l| !l.contains("imu_axes") && !l.contains("[params.vehicle]"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(nameless.join("run.toml"), stripped).unwrap();
    let err = stage_fails("derive", &nameless, &tmp.path().join("nameless-o"));
    assert!(err.contains("imu_axes = \"BLD\""), "{err}");
    assert!(err.contains("x back, y left, z down"), "{err}");

    // Named.
    let (fo, bo) = (tmp.path().join("frd-o"), tmp.path().join("bld-o"));
    run_until(&forward, &fo, "disupt");
    run_until(&backward, &bo, "disupt");
    for file in [
        "ingest/imu.parquet",
        "ingest/raw.mcap",
        "derive/derived.parquet",
        "navigate/nav.parquet",
        "disupt/disupt.json",
        "disupt/corrected_nav.parquet",
    ] {
        let at = |o: &std::path::Path| std::fs::read(o.join("sim-0041").join(file)).unwrap();
        assert!(at(&fo) == at(&bo), "{file}");
    }
    let nav: unz::flow::NavigateSummary = read_json(&bo.join("sim-0041/navigate/navigate.json"));
    let report = nav.imu_axes.unwrap();
    assert_eq!(report.named.to_string(), "BLD");
    // Measured within 3.3° of forward on 38 runs (the verdict rounds to 90°).
    assert!(report.check.forward_turn_deg.abs() < 5.0, "{report:?}");
    assert!(report.check.forward_correlation > 0.8, "{report:?}");
}

/// A binary log from an IMU yawed 20° on its mount (`--odo-boresight-deg 20`: the
/// vehicle's forward is the IMU's x turned 20° clockwise): the derive fails it, naming
/// the mounting the drive shows (the IMU's x about 20° to the left of forward); named
/// so, the ingest turns the counts as scaled and the joint fit's route meets the control
/// points within a metre (the simulated route's own: 0.1–0.5 m).
#[test]
fn an_imu_yawed_on_its_mount_is_measured_and_turned() {
    let tmp = tempfile::tempdir().unwrap();
    let run = simulated_run(
        tmp.path(),
        41,
        &["--duration-s", "900", "--odo-boresight-deg", "20"],
    );
    let out = tmp.path().join("o");
    let err = stage_fails("derive", &run, &out);
    assert!(err.contains("to the left of forward"), "{err}");
    let settings = vehicle_settings_named(&err);
    let yaw: f64 = settings
        .rsplit(", ")
        .next()
        .and_then(|y| y.trim_end_matches("]\n").parse().ok())
        .unwrap_or_else(|| panic!("{settings}"));
    assert!((yaw + 20.0).abs() < 5.0, "{settings}");
    let manifest = std::fs::read_to_string(run.join("run.toml")).unwrap();
    std::fs::write(
        run.join("run.toml"),
        format!("{manifest}\n[params.vehicle]\n{settings}"),
    )
    .unwrap();
    run_until(&run, &out, "disupt");
    let d: unz::disupt_stage::DisuptOut = read_json(&out.join("sim-0041/disupt/disupt.json"));
    assert_eq!(d.corrected_by.as_deref(), Some("joint"), "{:?}", d.skipped);
    let worst = crate::kingston::worst_control_point_m(&d.methods["joint"]);
    assert!(worst < 1.0, "{worst} m");
    // The manifest's azimuth is the unit's (its alignment's, of the IMU's x): the body's
    // initial azimuth is it turned by the mounting, so that its error from the body's true
    // heading (the IMU's less the yaw named) is the manifest's alone, not the mounting's
    // (a level vehicle: the tilts' share is hundredths of a degree).
    let nav: unz::flow::NavigateSummary = read_json(&out.join("sim-0041/navigate/navigate.json"));
    let truth: unz_stages::simulate::TrueSettings = read_json(&run.join("truth.json"));
    let initial = nav.initial;
    // The manifest's six decimals.
    let unit_deg = initial.unit_azimuth_deg.expect("the unit's azimuth turned");
    assert!(
        (unit_deg - truth.manifest_azimuth_deg).abs() < 1e-6,
        "{initial:?}"
    );
    let manifest_error = unit_deg - truth.azimuth_deg;
    let body_error = initial.azimuth_deg - (truth.azimuth_deg - yaw);
    assert!(
        (body_error - manifest_error).abs() < 0.05,
        "{initial:?}: {body_error}° off the body's heading, the manifest {manifest_error}°"
    );
}
