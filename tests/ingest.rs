//! Ingest end to end: simulated clean and damaged runs, the Kingston text log, and
//! third-party readers on the outputs.

use std::path::Path;

use serde_json::Value;
use unz_formats::IngestReport;

use unz::flow::NavigateSummary;

use crate::util::{
    mcap_chunk_compressions, mcap_messages, python, python_json, read_json, test_data, unz_ok,
};

fn report(path: &Path) -> IngestReport {
    read_json(path)
}

#[test]
fn simulated_runs_ingest_and_faults_are_accounted_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let campaign = tmp.path().join("campaign");
    let out = tmp.path().join("out");
    unz_ok(&[
        "simulate",
        "--out",
        campaign.to_str().unwrap(),
        "--seed",
        "40",
        "--duration-s",
        "600",
        "--faults",
    ]);
    for run in ["sim-0040", "sim-0040-faulty"] {
        unz_ok(&[
            "ingest",
            campaign.join(run).to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
    }
    let clean = report(&out.join("sim-0040/ingest/ingest.json"));
    assert_eq!(clean.imu_accepted, 60_000);
    assert_eq!(clean.rejected_total(), 0);
    assert_eq!(
        clean.marks_accepted, 2,
        "a mid-route and a final control point"
    );

    // Key by key, as JSON objects, so a key added or missing on either side fails too.
    let got: Value = read_json(&out.join("sim-0040-faulty/ingest/ingest.json"));
    let want: Value = read_json(&campaign.join("sim-0040-faulty/expected_ingest.json"));
    let (got, want) = (got.as_object().unwrap(), want.as_object().unwrap());
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        want.keys().collect::<Vec<_>>()
    );
    for (k, v) in want {
        assert_eq!(&got[k], v, "key {k}");
    }
    let spec_keys = [
        "records_read",
        "records_accepted",
        "imu_accepted",
        "marks_accepted",
        "rejected",
        "bytes_skipped",
        "truncated_bytes",
        "resync_events",
        "seq_gaps",
        "lost_samples",
        "lost_duration_s",
        "t_non_increasing",
    ];
    // The spec's keys, and the tags the ingest gave their `seq`'s time (each fault's tag
    // went back past the record before: more than half a period off).
    assert_eq!(got.len(), spec_keys.len() + 1);
    assert!(spec_keys.iter().all(|k| got.contains_key(*k)));
    assert_eq!(got["lone_tags_off"], want["t_non_increasing"]);
    assert_eq!(got["rejected"].as_object().unwrap().len(), 4);

    // Regression: derive's counts survive the stage cache. navigate reads the cached
    // derive (a second process), and reports the time tags repaired and the gaps filled:
    // none repaired (the ingest gave each tag that went back its `seq`'s time), and every
    // gap between accepted records (a lost stretch is closed by the next sample).
    let faulty = campaign.join("sim-0040-faulty");
    unz_ok(&[
        "derive",
        faulty.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    unz_ok(&[
        "navigate",
        faulty.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let nav: NavigateSummary = read_json(&out.join("sim-0040-faulty/navigate/navigate.json"));
    let t_back = want["t_non_increasing"].as_u64().unwrap();
    assert!(t_back > 0);
    assert_eq!(nav.repaired_times, 0, "{nav:?}");
    assert!(nav.filled_gaps > 0, "{nav:?}");

    if let Some(py) = python() {
        let info = python_json(
            &py,
            "check_ingest.py",
            &[&out.join("sim-0040-faulty/ingest")],
        );
        let imu_rows = info["imu"]["rows"].as_u64().unwrap();
        assert_eq!(imu_rows, want["imu_accepted"].as_u64().unwrap());
        assert_eq!(info["odometer"]["rows"].as_u64().unwrap(), imu_rows);
        assert_eq!(info["marks"]["rows"].as_u64().unwrap(), 2);
        assert_eq!(
            info["imu"]["columns"],
            serde_json::json!(["t_ns", "seq", "dtheta_rad", "dvel_mps", "status"])
        );
        assert_eq!(info["imu"]["fields"]["dtheta_rad"]["unit"], "rad");
        assert_eq!(info["imu"]["fields"]["dtheta_rad"]["frame"], "body_frd");
        assert_eq!(info["imu"]["fields"]["dvel_mps"]["unit"], "m/s");
        assert_eq!(info["imu"]["fields"]["t_ns"]["unit"], "ns");
        assert_eq!(info["odometer"]["fields"]["distance_m"]["unit"], "m");
        let ch = &info["mcap"]["channels"];
        assert_eq!(ch["/imu"]["count"].as_u64().unwrap(), imu_rows);
        // The odometer is thinned to 10 Hz for viewing (its exact pulses are in
        // odometer.parquet): one message per 0.1 s of the log's span (the tags that went
        // back given their `seq`'s time, in order), but for the tenths the lost samples
        // took whole.
        let (_, batches) = unz_formats::parquet_io::read_batches(
            &out.join("sim-0040-faulty/ingest/odometer.parquet"),
        )
        .unwrap();
        let mut odo = unz_formats::tables::OdometerTable::default();
        batches
            .iter()
            .for_each(|b| odo.extend_from_batch(b).unwrap());
        let (t0, t1) = (
            *odo.t_ns.iter().min().unwrap(),
            *odo.t_ns.iter().max().unwrap(),
        );
        let odo_msgs = ch["/odometer"]["count"].as_u64().unwrap();
        let expect = (t1 - t0) as f64 * 1e-8;
        let lost_tenths = want["lost_duration_s"].as_f64().unwrap() * 10.0;
        assert!(
            odo_msgs as f64 <= expect + 2.0 && odo_msgs as f64 >= expect - 2.0 - lost_tenths,
            "{odo_msgs} odometer messages over {expect} tenths of a second, {lost_tenths} lost"
        );
        assert_eq!(ch["/marks"]["count"].as_u64().unwrap(), 2);
        // ROS 2 messages, every one decoded by the mcap package's own ROS 2 decoder from
        // the schema text we wrote, and equal to the Parquet tables.
        assert_eq!(ch["/imu"]["message_encoding"], "cdr");
        assert_eq!(ch["/imu"]["schema_encoding"], "ros2msg");
        assert_eq!(ch["/imu"]["schema_name"], "unz_msgs/msg/ImuSample");
        assert_eq!(
            ch["/odometer"]["schema_name"],
            "unz_msgs/msg/OdometerSample"
        );
        assert_eq!(ch["/marks"]["schema_name"], "unz_msgs/msg/ControlPointMark");
        assert_eq!(
            info["mcap"]["decoded"].as_u64(),
            Some(imu_rows + odo_msgs + 2)
        );
        let agree = &info["imu_vs_parquet"];
        assert_eq!(agree["seq_equal"], true, "{agree}");
        assert_eq!(agree["status_equal"], true, "{agree}");
        // Rates are the increments over the 100 Hz period in single precision: a relative
        // error of at most 2 ulp of f32 (1.2e-7) after the division.
        assert!(
            (agree["period_s"].as_f64().unwrap() - 0.01).abs() < 1e-9,
            "{agree}"
        );
        assert!(agree["rate_rel_err"].as_f64().unwrap() < 1.2e-7, "{agree}");
        assert!(agree["accel_rel_err"].as_f64().unwrap() < 1.2e-7, "{agree}");
        assert_eq!(info["marks_equal"], true);
        // Rerun's own MCAP importer decodes every message by reflection of its schema.
        let rr = python_json(
            &py,
            "rerun_mcap.py",
            &[&out.join("sim-0040-faulty/ingest/raw.mcap")],
        );
        assert_eq!(rr["/imu"]["rows"].as_u64(), Some(imu_rows), "{rr}");
        assert_eq!(rr["/odometer"]["rows"].as_u64(), Some(odo_msgs), "{rr}");
        let imu_cols = rr["/imu"]["columns"].as_array().unwrap();
        assert!(
            imu_cols.contains(&"unz_msgs.msg.ImuSample:message".into()),
            "{rr}"
        );
        // The damaged log's 3 records whose tag went back have their `seq`'s time: the
        // MCAP's times increase as the clean log's do.
        assert_eq!(info["mcap"]["monotonic"], true);
        let clean_info = python_json(&py, "check_ingest.py", &[&out.join("sim-0040/ingest")]);
        assert_eq!(clean_info["mcap"]["monotonic"], true);
    }
}

#[test]
fn kingston_text_log_ingests_with_aligned_odometer() {
    let tmp = tempfile::tempdir().unwrap();
    let run = test_data("kingston2008-seg1");
    unz_ok(&[
        "ingest",
        run.to_str().unwrap(),
        "--out",
        tmp.path().to_str().unwrap(),
    ]);
    let dir = tmp.path().join("kingston2008-segment1/ingest");
    let rep = report(&dir.join("ingest.json"));
    assert_eq!(rep.imu_accepted, 8_760);
    assert_eq!(rep.rejected_total(), 0);
    let (_, batches) = unz_formats::parquet_io::read_batches(&dir.join("imu.parquet")).unwrap();
    let mut imu = unz_formats::tables::ImuTable::default();
    batches
        .iter()
        .for_each(|b| imu.extend_from_batch(b).unwrap());
    let (_, batches) =
        unz_formats::parquet_io::read_batches(&dir.join("odometer.parquet")).unwrap();
    let mut odo = unz_formats::tables::OdometerTable::default();
    batches
        .iter()
        .for_each(|b| odo.extend_from_batch(b).unwrap());
    assert_eq!(imu.len(), 8_760);
    assert_eq!(odo.len(), 877);
    // Both in the log's time base (GPS seconds of week): the odometer spans the IMU.
    let (i0, i1) = (imu.t_ns[0], *imu.t_ns.last().unwrap());
    let (o0, o1) = (odo.t_ns[0], *odo.t_ns.last().unwrap());
    assert!(
        (o0 - i0).abs() < 1_000_000_000 && (o1 - i1).abs() < 1_000_000_000,
        "imu {i0}..{i1}, odo {o0}..{o1}"
    );
    // ~2.4 km of driving, with OBD-II speed 1.3 % low.
    let d = *odo.distance_m.last().unwrap();
    assert!((2_000.0..3_000.0).contains(&d), "{d}");
    if let Some(py) = python() {
        let info = python_json(&py, "check_ingest.py", &[&dir]);
        assert_eq!(info["imu"]["rows"], 8_760);
        assert_eq!(info["mcap"]["channels"]["/imu"]["count"], 8_760);
        assert_eq!(info["mcap"]["channels"]["/odometer"]["count"], 877);
    }
}

/// Kingston's files saved with a UTF-8 byte-order mark (as a Windows editor or a
/// spreadsheet's export writes them): its first IMU line and first odometer reading were
/// line faults, each lost. Now the run ingests as without the marks, file for file.
#[test]
fn kingston_saved_with_byte_order_marks_ingests_as_without() {
    let tmp = tempfile::tempdir().unwrap();
    let plain = test_data("kingston2008-seg1");
    let marked = tmp.path().join("marked");
    std::fs::create_dir_all(&marked).unwrap();
    for f in ["imu.txt", "odometer.txt", "run.toml"] {
        let text = std::fs::read(plain.join(f)).unwrap();
        std::fs::write(marked.join(f), [&b"\xef\xbb\xbf"[..], &text].concat()).unwrap();
    }
    let ingest = |run: &Path, out: &str| {
        let out = tmp.path().join(out);
        unz_ok(&[
            "ingest",
            run.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        out.join("kingston2008-segment1/ingest")
    };
    let (want, got) = (ingest(&plain, "plain"), ingest(&marked, "marked"));
    assert_eq!(report(&got.join("ingest.json")).rejected_all_files(), 0);
    for f in [
        "imu.parquet",
        "odometer.parquet",
        "ingest.json",
        "ingest_events.json",
    ] {
        let (a, b) = (std::fs::read(want.join(f)), std::fs::read(got.join(f)));
        assert!(a.unwrap() == b.unwrap(), "{f} differs");
    }
}

#[test]
fn raw_mcap_compression_changes_the_size_not_the_messages() {
    use unz::ingest::{IngestOptions, ingest};
    use unz_formats::mcap_io::McapCompression;
    let tmp = tempfile::tempdir().unwrap();
    let campaign = tmp.path().join("campaign");
    unz_ok(&[
        "simulate",
        "--out",
        campaign.to_str().unwrap(),
        "--seed",
        "41",
        "--duration-s",
        "300",
    ]);
    let manifest = unz::runs::load_run(&campaign.join("sim-0041")).unwrap();
    let mut sizes = Vec::new();
    let mut messages = Vec::new();
    for (name, compression) in [
        ("none", McapCompression::None),
        ("zstd", McapCompression::Zstd),
        ("lz4", McapCompression::Lz4),
    ] {
        let dir = tmp.path().join(name);
        let options = IngestOptions {
            mcap: Some(compression),
            odo_lag_prior_s: 0.0,
            imu_axes: Default::default(),
            imu_mounting: None,
            keep_series: false,
            max_gap_s: unz_stages::derive::DeriveParams::default().max_gap_s,
        };
        ingest(&manifest, &dir, options).unwrap();
        let path = dir.join("raw.mcap");
        let chunks = mcap_chunk_compressions(&path);
        assert!(!chunks.is_empty());
        let want = match compression {
            McapCompression::None => "",
            McapCompression::Zstd => "zstd",
            McapCompression::Lz4 => "lz4",
        };
        assert!(chunks.iter().all(|c| c == want), "{name}: {chunks:?}");
        sizes.push(std::fs::metadata(&path).unwrap().len());
        messages.push(mcap_messages(&path));
    }
    // 30 000 IMU samples, the odometer at 10 Hz, the marks.
    let imu = messages[0].iter().filter(|m| m.0 == "/imu").count();
    assert_eq!(imu, 30_000);
    assert!(messages[0] == messages[1], "the same messages with zstd");
    assert!(messages[0] == messages[2], "the same messages with lz4");
    // zstd takes the CDR's constant bytes and slow counters out: well under 3/4; lz4,
    // the repeated bytes, less of them.
    assert!(
        (sizes[1] as f64) < 0.75 * sizes[0] as f64,
        "sizes none/zstd/lz4: {sizes:?}"
    );
    assert!(
        sizes[1] < sizes[2] && (sizes[2] as f64) < 0.9 * sizes[0] as f64,
        "sizes none/zstd/lz4: {sizes:?}"
    );
}

/// The series an ingest keeps for the derive that follows are what its files give back,
/// bit for bit: a binary log over several batches, its damaged copy (records lost, and an
/// odometer failure made, bridged), and the Kingston text log with its odometer file.
#[test]
fn the_series_kept_for_the_derive_are_the_files() {
    use unz::ingest::{IngestOptions, ingest};
    use unz_formats::parquet_io::for_each_batch_of;
    use unz_formats::tables::{ImuTable, OdometerTable};
    let tmp = tempfile::tempdir().unwrap();
    let run = crate::util::simulated_run(tmp.path(), 43, &["--duration-s", "900", "--faults"]);
    let faulty = run.with_file_name("sim-0043-faulty");
    // The damaged copy's odometer fails (flagged) for 15 s while driving: bridged.
    crate::util::hold_count(&faulty.join("sim-0043-faulty.unz"), 40_000, 1500, true);
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let bits3 = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    for run in [run.clone(), faulty, test_data("kingston2008-seg1")] {
        let manifest = unz::runs::load_run(&run).unwrap();
        let dir = tmp.path().join("out").join(&manifest.name);
        let options = IngestOptions {
            mcap: None,
            odo_lag_prior_s: 0.0,
            imu_axes: Default::default(),
            imu_mounting: None,
            keep_series: true,
            max_gap_s: unz_stages::derive::DeriveParams::default().max_gap_s,
        };
        let kept = ingest(&manifest, &dir, options).unwrap().series.unwrap();
        let mut imu = ImuTable::default();
        for_each_batch_of(&dir.join("imu.parquet"), &ImuTable::SERIES_COLUMNS, |b| {
            imu.extend_series_from_batch(b)
        })
        .unwrap();
        let mut odometer = OdometerTable::default();
        for_each_batch_of(
            &dir.join("odometer.parquet"),
            &OdometerTable::SERIES_COLUMNS,
            |b| odometer.extend_series_from_batch(b),
        )
        .unwrap();
        let name = &manifest.name;
        assert!(kept.imu.t_ns.len() > 5_000, "{name}");
        assert_eq!(kept.imu.t_ns, imu.t_ns, "{name}");
        assert_eq!(
            bits3(&kept.imu.dtheta_rad),
            bits3(&imu.dtheta_rad),
            "{name}"
        );
        assert_eq!(bits3(&kept.imu.dvel_mps), bits3(&imu.dvel_mps), "{name}");
        assert_eq!(kept.imu.status, imu.status, "{name}");
        assert!(kept.imu.seq.is_empty(), "{name}");
        assert_eq!(kept.odometer.t_ns, odometer.t_ns, "{name}");
        assert_eq!(
            bits(&kept.odometer.distance_m),
            bits(&odometer.distance_m),
            "{name}"
        );
        if name.starts_with("sim") {
            assert!(kept.imu.t_ns.len() > 1 << 16, "{name}: several batches");
        }
        if name.ends_with("faulty") {
            let report = report(&dir.join("ingest.json"));
            assert!(report.odometer_failures.is_some(), "{name}: {report:?}");
        }
    }
}
