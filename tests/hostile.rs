//! Hostile archives and output folders: non-physical scales and parameters are refused
//! with the file and the reason, no output escapes the output folder, and two processes
//! do not share one. Every case is one run of a small campaign whose other run goes on.

use std::path::{Path, PathBuf};

use unz::flow::NavigateSummary;
use unz_formats::IngestReport;

use crate::util::{
    files_below, hold_count, parquet_rows, read_json, read_log, unz, unz_output, write_log,
};

/// A campaign of two simulated 200 s runs; returns the campaign folder.
fn campaign(dir: &Path) -> PathBuf {
    simulated_campaign(&dir.join("c"), 80, 2, 200.0)
}

/// Simulates `runs` runs of `duration_s` from `seed` into `camp`; returns it.
fn simulated_campaign(camp: &Path, seed: u32, runs: u32, duration_s: f64) -> PathBuf {
    let o = unz_output(&[
        "simulate",
        "--out",
        camp.to_str().unwrap(),
        "--seed",
        &seed.to_string(),
        "--runs",
        &runs.to_string(),
        "--duration-s",
        &duration_s.to_string(),
    ]);
    assert!(o.status.success());
    camp.to_path_buf()
}

/// Runs the campaign until `until`; returns (exit code, stdout).
fn run(camp: &Path, out: &Path, until: &str) -> (Option<i32>, String) {
    let o = unz_output(&[
        "run",
        camp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--until",
        until,
    ]);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr),
    )
}

/// The row of run `name` in the runs' table of `out/campaign.md`.
fn campaign_row(out: &Path, name: &str) -> String {
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    summary
        .lines()
        .find(|l| l.starts_with(&format!("| {name} ")))
        .unwrap_or_else(|| panic!("no row of {name}: {summary}"))
        .to_owned()
}

fn patch_f64(path: &Path, offset: usize, v: f64) {
    let mut b = std::fs::read(path).unwrap();
    b[offset..offset + 8].copy_from_slice(&v.to_le_bytes());
    std::fs::write(path, b).unwrap();
}

fn append(path: &Path, text: &str) {
    let mut s = std::fs::read_to_string(path).unwrap();
    s += text;
    std::fs::write(path, s).unwrap();
}

/// Header scales of 1e300 (they navigated to Inf and NaN under an "ok" status), a
/// manifest scale of 1e300, a disupt bound of 1e300 and a site at the pole: each fails its
/// run with the file and the reason; the other run of the campaign finishes.
#[test]
fn non_physical_scales_and_parameters_fail_their_run_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let (good, bad) = (camp.join("sim-0080"), camp.join("sim-0081"));
    let original_log = std::fs::read(bad.join("sim-0081.unz")).unwrap();
    let original_manifest = std::fs::read_to_string(bad.join("run.toml")).unwrap();
    type Case<'a> = (&'a str, Box<dyn Fn() + 'a>, &'a [&'a str]);
    let cases: [Case; 6] = [
        (
            "header odo_lsb_m",
            Box::new(|| patch_f64(&bad.join("sim-0081.unz"), 40, 1e300)),
            &["sim-0081.unz", "odo_lsb_m"],
        ),
        (
            "header dtheta_lsb_rad",
            Box::new(|| patch_f64(&bad.join("sim-0081.unz"), 24, 1e300)),
            &["sim-0081.unz", "dtheta_lsb_rad"],
        ),
        (
            "header dvel_lsb_mps",
            Box::new(|| patch_f64(&bad.join("sim-0081.unz"), 32, f64::NAN)),
            &["sim-0081.unz", "dvel_lsb_mps"],
        ),
        (
            "manifest scale",
            Box::new(|| {
                append(
                    &bad.join("run.toml"),
                    "\n[odometer]\nscale_m_per_pulse = 1e300\n",
                )
            }),
            &["run.toml", "scale_m_per_pulse"],
        ),
        (
            "disupt bound",
            Box::new(|| {
                append(
                    &bad.join("run.toml"),
                    "\n[params.disupt]\nazimuth_bound_deg = 1e300\n",
                )
            }),
            &["run.toml", "disupt.azimuth_bound_deg"],
        ),
        (
            "site at the pole",
            Box::new(|| {
                let text = std::fs::read_to_string(bad.join("run.toml")).unwrap();
                let start = text.find("latitude_deg = ").unwrap();
                let end = start + text[start..].find('\n').unwrap();
                let patched = format!("{}latitude_deg = 90.0{}", &text[..start], &text[end..]);
                std::fs::write(bad.join("run.toml"), patched).unwrap();
            }),
            &["run.toml", "latitude_deg"],
        ),
    ];
    for (i, (what, damage, names)) in cases.iter().enumerate() {
        std::fs::write(bad.join("sim-0081.unz"), &original_log).unwrap();
        std::fs::write(bad.join("run.toml"), &original_manifest).unwrap();
        damage();
        let out = tmp.path().join(format!("o{i}"));
        let (code, text) = run(&camp, &out, "disupt");
        assert_eq!(code, Some(1), "{what}: {text}");
        assert!(text.contains("FAILED sim-0081"), "{what}: {text}");
        for n in *names {
            assert!(text.contains(n), "{what}: no {n} in\n{text}");
        }
        assert!(out.join("campaign.md").is_file(), "{what}");
        assert!(
            out.join("sim-0080/disupt/disupt.json").is_file(),
            "{what}: the other run goes on"
        );
        assert!(good.is_dir());
    }
}

/// A run may not be named like the summary files; a symbolic link planted inside the
/// output folder is refused; a second process on the same output folder is refused with
/// the holder's pid.
#[test]
fn output_folder_is_ours_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let manifest = camp.join("sim-0081/run.toml");
    let text = std::fs::read_to_string(&manifest).unwrap();
    std::fs::write(
        &manifest,
        text.replace("name = \"sim-0081\"", "name = \"campaign.parquet\""),
    )
    .unwrap();
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "ingest");
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("campaign.parquet") && text.contains("not a plain run name"),
        "{text}"
    );
    assert!(
        out.join("campaign.parquet").is_file(),
        "the summary is still written"
    );

    // A symlink planted as a stage folder: refused, nothing written where it points.
    let elsewhere = tmp.path().join("elsewhere");
    std::fs::create_dir_all(&elsewhere).unwrap();
    std::fs::create_dir_all(out.join("sim-0080")).unwrap();
    std::fs::remove_dir_all(out.join("sim-0080")).unwrap();
    std::fs::create_dir_all(out.join("sim-0080")).unwrap();
    std::os::unix::fs::symlink(&elsewhere, out.join("sim-0080/ingest")).unwrap();
    let (code, text) = run(&camp, &out, "ingest");
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("is a symbolic link"), "{text}");
    assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0);

    // Two processes on one output folder: the second is refused at once.
    let out2 = tmp.path().join("o2");
    let mut first = unz()
        .args([
            "run",
            camp.to_str().unwrap(),
            "--out",
            out2.to_str().unwrap(),
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Wait until the first holds the lock (it writes its pid into the lock file).
    let lock = out2.join("unz.lock");
    let t0 = std::time::Instant::now();
    while std::fs::read_to_string(&lock).map_or(true, |s| s.trim().is_empty()) {
        assert!(t0.elapsed().as_secs() < 30, "the first run never locked");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let second = unz_output(&[
        "run",
        camp.to_str().unwrap(),
        "--out",
        out2.to_str().unwrap(),
    ]);
    first.wait().unwrap();
    let err = String::from_utf8_lossy(&second.stderr);
    assert!(!second.status.success(), "{err}");
    assert!(
        err.contains(&format!("in use by pid {}", first.id())),
        "{err}"
    );
}

/// The byte offset a failure message `text` names right after `before`, in the raw log
/// `log` (`… byte offset N of LOG)`).
fn offset_named(text: &str, before: &str, log: &str) -> usize {
    (text.split(before).nth(1))
        .and_then(|rest| rest.split(&format!(" of {log})")).next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no offset after {before:?}: {text}"))
}

/// An IMU record's field `len` bytes long `from` its frame's start, of the frame at byte
/// `at` of the raw log `log` (its frame checked): `seq` at 4, `t_us` at 8, the status at
/// 44.
fn imu_field(log: &[u8], at: usize, from: usize, len: usize) -> u64 {
    assert_eq!(
        log[at..at + 4],
        [0xA5, 0x5A, 0x01, 42],
        "no IMU frame at {at}"
    );
    (log[at + from..at + from + len].iter().rev()).fold(0, |v, &b| v << 8 | u64::from(b))
}

/// Rewrites the raw log `log` record by record, IMU records through `edit`.
fn rewrite_imu(log: &Path, edit: &dyn Fn(&mut unz_formats::raw::ImuRecord)) {
    use unz_formats::raw::{Accepted, RawReader, RawWriter};

    let bytes = std::fs::read(log).unwrap();
    let mut reader = RawReader::new(bytes.as_slice()).unwrap();
    let mut writer = RawWriter::new(Vec::new(), reader.header()).unwrap();
    while let Some(rec) = reader.next_record().unwrap() {
        match rec {
            Accepted::Imu(s) => {
                let mut r = s.raw;
                edit(&mut r);
                writer.write_imu(&r).unwrap();
            }
            Accepted::Mark(m) => writer.write_mark(&m.raw).unwrap(),
        }
    }
    std::fs::write(log, writer.finish().unwrap()).unwrap();
}

/// All time tags constant: counted by the reader as time not increasing, and the run fails
/// in derive with that reason instead of ending "ok" with no motion.
#[test]
fn a_log_whose_time_does_not_advance_fails_its_run() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    rewrite_imu(&camp.join("sim-0081/sim-0081.unz"), &|r| r.t_us = 10_000);
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "derive");
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("FAILED sim-0081") && text.contains("time tags do not increase"),
        "{text}"
    );
    // Located in the raw log: the ingest's first such fault (the second IMU record, after
    // the header and the first record).
    let events: unz_formats::IngestEvents =
        read_json(&out.join("sim-0081/ingest/ingest_events.json"));
    let first = (events.events.iter())
        .find(|e| e.kind == unz_formats::raw::FaultKind::TimeNotIncreasing)
        .unwrap();
    assert!(first.offset > 0, "{first:?}");
    assert!(
        text.contains(&format!(
            "the first at sample 1, byte offset {} of sim-0081.unz",
            first.offset
        )),
        "{text}"
    );
    assert!(out.join("sim-0080/derive/derived.parquet").is_file());

    // A text log's are located by their line: 200 of Kingston's tags (2 %) made the one
    // before them.
    let run = kingston_with_imu(&tmp.path().join("k"), |lines| {
        let t = lines[2999].split_whitespace().next().unwrap().to_owned();
        for line in &mut lines[3000..3200] {
            let rest = line.split_once(' ').unwrap().1.to_owned();
            *line = format!("{t} {rest}");
        }
    });
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("ko"));
    assert!(
        err.contains("200 of 8760 IMU time tags do not increase")
            && err.contains("(the first at sample 3000, line 3001 of imu.txt)"),
        "{err}"
    );
}

/// One record whose time tag leapt forward alone, its CRC valid (a glitch in the
/// recorder's clock): by 1 s, by 2^40 µs (beyond an i64 of nanoseconds once scaled) and to
/// u64::MAX. The ingest gives it its `seq`'s time (one lone tag off), and DISUPT finds
/// what it finds in the undamaged run. Before the derive repaired such a tag (one
/// repaired time); before that, every later tag went back from the leap (half a run's
/// tags "repaired", and the run failed), and the odometer's reading there hid every
/// later one (the distance held from it: 1 169 m off at a 10-minute run's control point).
///
/// The log's first or last record apart from the rest: the first's tag leapt 1 s or 20 s
/// forward (a glitch at its start, inside the stretch whose tags give the ingest its
/// period: the derive places it beside the second, one repaired time), the last 10 s
/// after the rest (a record a logger wrote as it closed: the ingest's lone tag off).
/// DISUPT finds the same. Before, a first tag that leapt had every tag up to its time
/// repaired one interval on from it (the whole log shifted by the leap), and a lone
/// record across a gap at the end failed the run on the gap. (A first record before a
/// gap: the Kingston test `kingston_a_lone_first_or_last_line_is_placed_beside_the_rest`.)
#[test]
fn a_record_whose_tag_leapt_forward_alone_is_given_its_time() {
    use unz::disupt_stage::DisuptOut;
    use unz_formats::raw::{Accepted, RawReader};

    let tmp = tempfile::tempdir().unwrap();
    let camp = simulated_campaign(&tmp.path().join("c"), 80, 1, 200.0);
    let log = camp.join("sim-0080/sim-0080.unz");
    let undamaged = std::fs::read(&log).unwrap();
    let mut seqs = Vec::new();
    let mut reader = RawReader::new(undamaged.as_slice()).unwrap();
    while let Some(rec) = reader.next_record().unwrap() {
        if let Accepted::Imu(s) = rec {
            seqs.push(s.raw.seq);
        }
    }
    let (first, last) = (seqs[0], *seqs.last().unwrap());
    let clean_out = tmp.path().join("clean");
    let (code, text) = run(&camp, &clean_out, "disupt");
    assert_eq!(code, Some(0), "{text}");
    let clean: DisuptOut = read_json(&clean_out.join("sim-0080/disupt/disupt.json"));
    assert!(clean.methods.len() >= 3, "{:?}", clean.skipped);
    /// Which record, and its time tag moved, µs.
    type Edit = (u32, fn(u64) -> u64);
    let edits: [(&str, Edit); 6] = [
        ("a leap of 1 s", (12_000, |t| t + 1_000_000)),
        ("a leap of 2^40 µs", (12_000, |t| t + (1 << 40))),
        ("a leap to u64::MAX", (12_000, |_| u64::MAX)),
        ("the first leapt 1 s", (first, |t| t + 1_000_000)),
        ("the first leapt 20 s", (first, |t| t + 20_000_000)),
        ("the last 10 s after", (last, |t| t + 10_000_000)),
    ];
    for (i, (what, (seq, to))) in edits.into_iter().enumerate() {
        std::fs::write(&log, &undamaged).unwrap();
        rewrite_imu(&log, &|r| {
            if r.seq == seq {
                r.t_us = to(r.t_us);
            }
        });
        let out = tmp.path().join(format!("o{i}"));
        let (code, text) = run(&camp, &out, "disupt");
        assert_eq!(code, Some(0), "{what}: {text}");
        let nav: NavigateSummary = read_json(&out.join("sim-0080/navigate/navigate.json"));
        let report: IngestReport = read_json(&out.join("sim-0080/ingest/ingest.json"));
        let (lone, repaired) = if seq == first { (0, 1) } else { (1, 0) };
        assert_eq!(
            (report.lone_tags_off, report.clock_steps, nav.repaired_times),
            (lone, 0, repaired),
            "{what}: {report:?}"
        );
        let damaged: DisuptOut = read_json(&out.join("sim-0080/disupt/disupt.json"));
        assert_same_fit(&clean, &damaged, what);
    }
}

/// A block a recorder sent again after itself (10 s of a binary log's records, their
/// `seq` and `t_us` as first sent), and Kingston's text log with 10 s of lines repeated
/// so, or its two halves joined over 100 s they share: the repeats are duplicates
/// (`rejected.duplicate_seq`, each text line listed with the line it repeats), the time
/// base goes on as logged, and `disupt.json` is the undamaged run's byte for byte.
/// Before, the block went back in time and was kept: its samples were repaired one
/// interval on, the log grew by the block's length, and the binary run's odometer, a text
/// log's control points and its speed file were that much off its clock (Kingston: "the
/// odometer file's time tags run 10.4 s early", 100.4 s for the halves).
#[test]
fn a_block_sent_again_or_logs_joined_over_their_overlap_are_duplicates() {
    use unz_formats::raw::{Accepted, RawReader, RawWriter};

    let tmp = tempfile::tempdir().unwrap();
    let disupt_json = |folder: &Path, out: &str| {
        let out = tmp.path().join(out);
        let (code, text) = run(folder, &out, "disupt");
        assert_eq!(code, Some(0), "{text}");
        let stage = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().path())
            .find(|p| p.join("disupt/disupt.json").exists())
            .unwrap();
        let report: IngestReport = read_json(&stage.join("ingest/ingest.json"));
        let events: unz_formats::IngestEvents = read_json(&stage.join("ingest/ingest_events.json"));
        let json = std::fs::read(stage.join("disupt/disupt.json")).unwrap();
        (json, report, events)
    };

    let camp = simulated_campaign(&tmp.path().join("c"), 80, 1, 200.0);
    let run = camp.join("sim-0080");
    let (clean, _, _) = disupt_json(&run, "clean");
    let log = run.join("sim-0080.unz");
    let bytes = std::fs::read(&log).unwrap();
    let mut reader = RawReader::new(bytes.as_slice()).unwrap();
    let mut writer = RawWriter::new(Vec::new(), reader.header()).unwrap();
    let mut block = Vec::new();
    while let Some(rec) = reader.next_record().unwrap() {
        match rec {
            Accepted::Imu(s) => {
                writer.write_imu(&s.raw).unwrap();
                if (12_000..13_000).contains(&s.raw.seq) {
                    block.push(s.raw);
                }
                if s.raw.seq == 12_999 {
                    block.iter().for_each(|r| writer.write_imu(r).unwrap());
                }
            }
            Accepted::Mark(m) => writer.write_mark(&m.raw).unwrap(),
        }
    }
    std::fs::write(&log, writer.finish().unwrap()).unwrap();
    let (resent, report, _) = disupt_json(&run, "resent");
    assert_eq!(report.rejected.duplicate_seq, 1000, "{report:?}");
    assert_eq!(
        (report.t_non_increasing, report.seq_gaps),
        (0, 0),
        "{report:?}"
    );
    assert!(
        resent == clean,
        "disupt.json differs from the undamaged run's"
    );

    let shipped = kingston_with_imu(&tmp.path().join("k"), |_| {});
    let (want, _, _) = disupt_json(&shipped, "k-o");
    /// The IMU log's lines edited.
    type Edit = fn(&mut Vec<String>);
    let edits: [(&str, Edit, u64); 2] = [
        (
            "10 s sent again",
            |l| {
                let block = l[5000..5100].to_vec();
                l.splice(5100..5100, block);
            },
            100,
        ),
        (
            "halves joined over 100 s",
            |l| {
                let overlap = l[5000..6000].to_vec();
                l.splice(6000..6000, overlap);
            },
            1000,
        ),
    ];
    for (what, edit, repeats) in edits {
        let run = kingston_with_imu(&tmp.path().join(what), edit);
        let (got, report, events) = disupt_json(&run, &format!("{what}-o"));
        assert_eq!(report.rejected.duplicate_seq, repeats, "{what}: {report:?}");
        // Each repeat listed (the text file's lines are 1-based).
        assert_eq!(events.events_total, repeats, "{what}");
        let first = &events.line_faults[0];
        let (line, of) = if repeats == 100 {
            (5101, 5001)
        } else {
            (6001, 5001)
        };
        assert_eq!(first.line, line, "{what}: {first:?}");
        assert!(
            first
                .reason
                .starts_with(&format!("repeats line {of} (its time tag and values)")),
            "{what}: {first:?}"
        );
        assert_eq!(report.t_non_increasing, 0, "{what}: {report:?}");
        assert!(
            got == want,
            "{what}: disupt.json differs from the shipped run's"
        );
    }
}

/// A campaign in `tmp` of one 200-s simulated run (seed 80), and the `disupt.json` its
/// undamaged log gives.
fn clean_200_s_run(tmp: &Path) -> (PathBuf, Vec<u8>) {
    let camp = simulated_campaign(&tmp.join("c"), 80, 1, 200.0);
    let clean_out = tmp.join("clean");
    let (code, text) = run(&camp, &clean_out, "disupt");
    assert_eq!(code, Some(0), "{text}");
    let clean = std::fs::read(clean_out.join("sim-0080/disupt/disupt.json")).unwrap();
    (camp, clean)
}

/// The log at `log` with its recorder's clock set twice while it logged, `seq` running
/// on: its tags moved `ahead_us` from record 6 000 (60 s) and `then_us` from record
/// 14 000 (140 s), its marks with the records about them.
fn set_clock_twice(log: &Path, ahead_us: i64, then_us: i64) {
    let moved = |t: u64, by: i64| t.checked_add_signed(by).unwrap();
    let k = std::cell::Cell::new(0_usize);
    rewrite_imu(log, &|r| {
        match k.get() {
            6_000..14_000 => r.t_us = moved(r.t_us, ahead_us),
            14_000.. => r.t_us = moved(r.t_us, then_us),
            _ => {}
        }
        k.set(k.get() + 1);
    });
    let mut stepped = read_log(log);
    for (at, m) in &mut stepped.marks {
        match *at {
            6_001..=14_000 => m.t_us = moved(m.t_us, ahead_us),
            14_001.. => m.t_us = moved(m.t_us, then_us),
            _ => {}
        }
    }
    write_log(log, &stepped);
}

/// A recorder whose clock was set twice while it logged, `seq` running on: 2 s forward at
/// 60 s, then 3 s back at 140 s (the tags after it 1 s behind the log's start), the
/// control point's mark after both. The ingest takes both leaps out of the time base (each
/// listed at its record), the summary says so, and `disupt.json` is the undamaged run's
/// byte for byte. Before, the leap forward read as a 2.01-s gap and failed the run's
/// derive (`max_gap_s`); a 1-s leap was filled with 99 samples of held rates, and every
/// mark after it was a second off the samples.
#[test]
fn a_clock_set_while_logging_is_taken_out_of_the_time_base() {
    use unz_formats::raw::FaultKind;

    let tmp = tempfile::tempdir().unwrap();
    let (camp, clean) = clean_200_s_run(tmp.path());
    let log = camp.join("sim-0080/sim-0080.unz");
    let marks = read_log(&log).marks;
    assert!(marks.iter().any(|(at, _)| *at > 14_000), "{marks:?}");
    set_clock_twice(&log, 2_000_000, -1_000_000);

    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "disupt");
    assert_eq!(code, Some(0), "{text}");
    let report: IngestReport = read_json(&out.join("sim-0080/ingest/ingest.json"));
    assert_eq!(
        (report.clock_steps, report.lone_tags_off, report.seq_gaps),
        (2, 0, 0),
        "{report:?}"
    );
    assert!((report.clock_shift_s - 1.0).abs() < 1e-9, "{report:?}");
    let events: unz_formats::IngestEvents =
        read_json(&out.join("sim-0080/ingest/ingest_events.json"));
    let leaps: Vec<_> = (events.events.iter())
        .filter(|e| matches!(e.kind, FaultKind::ClockAhead | FaultKind::ClockBack))
        .map(|e| (e.kind, e.amount))
        .collect();
    assert_eq!(
        leaps,
        [
            (FaultKind::ClockAhead, 2_000_000),
            (FaultKind::ClockBack, 3_000_000)
        ]
    );
    let bytes = std::fs::read(&log).unwrap();
    let first = unz_formats::raw::HEADER_LEN;
    for e in events
        .events
        .iter()
        .filter(|e| e.kind == FaultKind::ClockAhead)
    {
        let seq = imu_field(&bytes, e.offset as usize, 4, 4) - imu_field(&bytes, first, 4, 4);
        assert_eq!(seq, 6_000, "{e:?}");
    }
    assert!(
        campaign_row(&out, "sim-0080").contains(
            "the recorder's clock leapt twice while its seq ran on, taken out of the time \
             base (the tags after the last moved by +1.000000 s)"
        ),
        "{}",
        campaign_row(&out, "sim-0080")
    );
    let got = std::fs::read(out.join("sim-0080/disupt/disupt.json")).unwrap();
    assert!(got == clean, "disupt.json differs from the undamaged run's");
}

/// The joint fit and OEPI of `damaged` are `clean`'s, well posed on the 200-s run of
/// [`a_record_whose_tag_leapt_forward_alone_is_given_its_time`]: the same fit to a
/// microdegree and a millimetre. OWPI, whose fit leaves this short run hundreds of metres
/// off, is as ill-conditioned as that says: it ran, and its numbers are not compared.
fn assert_same_fit(
    clean: &unz::disupt_stage::DisuptOut,
    damaged: &unz::disupt_stage::DisuptOut,
    what: &str,
) {
    assert_eq!(
        damaged.methods.keys().collect::<Vec<_>>(),
        clean.methods.keys().collect::<Vec<_>>(),
        "{what}"
    );
    for name in ["joint", "oepi"] {
        let (want, got) = (&clean.methods[name].outcome, &damaged.methods[name].outcome);
        assert!(
            (got.x.azimuth_deg - want.x.azimuth_deg).abs() < 1e-6
                && (got.dx_m - want.dx_m).abs() < 1e-3
                && (got.dy_m - want.dy_m).abs() < 1e-3,
            "{name}, {what}: azimuth {} for {}, ΔX {} for {}, ΔY {} for {}",
            got.x.azimuth_deg,
            want.x.azimuth_deg,
            got.dx_m,
            want.dx_m,
            got.dy_m,
            want.dy_m
        );
    }
}

/// A log that gives no IMU sample fails its ingest naming the log and why: a text log's
/// lines rejected and the first's reason (here decimal commas), a binary log's records
/// read and bytes skipped. It failed in the derive, after an ingest of empty tables, with
/// "the raw log has no IMU record".
#[test]
fn a_log_without_an_imu_sample_fails_its_ingest_saying_why() {
    let tmp = tempfile::tempdir().unwrap();
    let kingston = kingston_with_imu(&tmp.path().join("k"), |lines| {
        for line in lines.iter_mut() {
            *line = line.replace('.', ",");
        }
    });
    let err = crate::util::stage_fails("derive", &kingston, &tmp.path().join("ko"));
    assert!(
        err.contains(
            "stage ingest failed: imu.txt has no IMU sample (lines rejected: 8760; the first, \
             line 1: more than 8 columns, expected 7 or 8 (decimal commas?"
        ) && err.contains("ingest_events.json lists the first faults"),
        "{err}"
    );

    let camp = campaign(tmp.path());
    let log = camp.join("sim-0081/sim-0081.unz");
    let mut bytes = std::fs::read(&log).unwrap();
    let header = unz_formats::raw::HEADER_LEN;
    let n = bytes.len() - header;
    bytes[header..].fill(0);
    std::fs::write(&log, bytes).unwrap();
    let (code, text) = run(&camp, &tmp.path().join("o"), "derive");
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains(&format!(
            "sim-0081.unz has no IMU record after its header: 0 records read, 0 rejected, {n} \
             bytes skipped while resynchronising"
        )),
        "{text}"
    );
    assert!(!text.contains("FAILED sim-0080"), "{text}");
}

/// A text log's run whose odometer gives no reading fails its ingest saying why: its
/// odometer file saved as UTF-16, or no odometer at all (7 columns and no file). Both
/// said "no 8th column and no odometer file", the first wrongly.
#[test]
fn an_odometer_without_a_reading_fails_its_ingest_saying_why() {
    let tmp = tempfile::tempdir().unwrap();
    let kingston = kingston_with_imu(&tmp.path().join("k"), |_| {});
    let speeds = std::fs::read_to_string(kingston.join("odometer.txt")).unwrap();
    let utf16: Vec<u8> = (std::iter::once('\u{feff}').chain(speeds.chars()))
        .flat_map(|c| c.encode_utf16(&mut [0; 2]).to_vec())
        .flat_map(u16::to_le_bytes)
        .collect();
    std::fs::write(kingston.join("odometer.txt"), utf16).unwrap();
    let err = crate::util::stage_fails("ingest", &kingston, &tmp.path().join("ko"));
    assert!(
        err.contains(
            "the odometer file odometer.txt gave no reading (the first line rejected, line 1: \
             UTF-16 text (its byte-order mark): the file must be UTF-8 or ASCII)"
        ),
        "{err}"
    );

    let manifest = std::fs::read_to_string(kingston.join("run.toml")).unwrap();
    let without = manifest.replace("file = \"odometer.txt\"\nkind = \"speed_mps\"\n", "");
    assert_ne!(without, manifest);
    std::fs::write(kingston.join("run.toml"), without).unwrap();
    let err = crate::util::stage_fails("ingest", &kingston, &tmp.path().join("ko2"));
    assert!(
        err.contains(
            "the run has no odometer data: imu.txt has no 8th column (the speed) and the \
             manifest names no [odometer] file"
        ),
        "{err}"
    );
}

/// A binary log holding more than 100 000 control-point marks (a damaged one: a crew
/// presses the key once a point) fails its run, naming the log and the next mark's byte
/// offset, and the other run goes on. A million marks in a row took the ingest to 310 MB,
/// held in order among the samples; more would have taken any memory.
#[test]
fn a_log_of_more_marks_than_a_run_makes_fails_its_run() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let raw = camp.join("sim-0081/sim-0081.unz");
    let mut log = read_log(&raw);
    assert!(
        log.marks.iter().all(|(k, _)| *k > 3000),
        "{}",
        log.marks.len()
    );
    let mark = unz_formats::raw::MarkRecord {
        t_us: log.imu[3000].t_us,
        point_id: 99,
    };
    log.marks
        .splice(0..0, std::iter::repeat_n((3000, mark), 100_001));
    crate::util::write_log(&raw, &log);
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "ingest");
    assert_eq!(code, Some(1), "{text}");
    // The header, 3000 IMU records of 48 bytes, then 100 000 marks of 18.
    assert!(
        text.contains(
            "sim-0081.unz holds more than 100000 control-point marks, the next at byte offset \
             1944128"
        ),
        "{text}"
    );
    assert!(!text.contains("FAILED sim-0080"), "{text}");
    assert!(crate::util::files_below(&out.join("sim-0081")).is_empty());
}

/// A copy of the Kingston segment in `run` (its manifest and odometer file), its IMU log's
/// lines edited by `edit`; returns `run`.
fn kingston_with_imu(run: &Path, edit: impl FnOnce(&mut Vec<String>)) -> PathBuf {
    let data = crate::util::test_data("kingston2008-seg1");
    std::fs::create_dir_all(run).unwrap();
    for f in ["run.toml", "odometer.txt"] {
        std::fs::copy(data.join(f), run.join(f)).unwrap();
    }
    let imu = std::fs::read_to_string(data.join("imu.txt")).unwrap();
    let mut lines: Vec<String> = imu.lines().map(String::from).collect();
    edit(&mut lines);
    std::fs::write(run.join("imu.txt"), lines.join("\n") + "\n").unwrap();
    run.to_path_buf()
}

/// Kingston with a line apart from the rest, as loggers write them: the IMU log's first
/// line 10 s ahead of the rest (its tag leapt) or 10 s before it (a stale line flushed as
/// the logger began), its last 10 s after it (one written as it closed); the speed file's
/// line at 152 862 s (13 m/s) or its first 50 s ahead of the lines about it. An IMU line
/// is placed beside the next (one repaired time), and `disupt.json` is the shipped run's,
/// byte for byte; a speed line is rejected naming its leap, and `disupt.json` is that of
/// the file without the line. Before, the IMU's first tag shifted the whole log by 10 s
/// (the odometer named 10.4 s early), a lone line across a gap failed the run on the gap,
/// and the speed file kept the line that leapt and rejected the 49 or 50 after it, the
/// odometer bridged over them. The ingest reports a line apart across an interval
/// longer than the derive's `max_gap_s` (2 s) as apart, and its interval is no lost
/// samples (before, the 10.1 s were 100 samples lost in `ingest.json`).
#[test]
fn kingston_a_lone_first_or_last_line_is_placed_beside_the_rest() {
    let tmp = tempfile::tempdir().unwrap();
    let disupt_json = |run: &Path, name: &str| {
        let out = tmp.path().join(format!("o-{name}"));
        crate::util::run_until(run, &out, "disupt");
        let stage = out.join("kingston2008-segment1");
        let nav: NavigateSummary = read_json(&stage.join("navigate/navigate.json"));
        let events: unz_formats::IngestEvents = read_json(&stage.join("ingest/ingest_events.json"));
        let json = std::fs::read(stage.join("disupt/disupt.json")).unwrap();
        (json, nav.repaired_times, events.odometer_file_faults)
    };
    let ingest_report = |name: &str| -> unz_formats::IngestReport {
        let stage = tmp.path().join(format!("o-{name}/kingston2008-segment1"));
        read_json(&stage.join("ingest/ingest.json"))
    };
    let shipped = kingston_with_imu(&tmp.path().join("k"), |_| {});
    let (want, repaired, _) = disupt_json(&shipped, "shipped");
    assert_eq!(repaired, 0);
    let clean = ingest_report("shipped");
    assert_eq!((clean.seq_gaps, clean.lost_samples), (0, 0));
    /// A line's time tag moved by `by` s.
    fn moved(line: &str, by: f64) -> String {
        let (t, rest) = line.split_once(' ').unwrap();
        format!("{:.3} {rest}", t.parse::<f64>().unwrap() + by)
    }
    /// The IMU log's lines edited.
    type Edit = fn(&mut Vec<String>);
    let imu_edits: [(&str, Edit); 3] = [
        ("first-ahead", |l| l[0] = moved(&l[0], 10.0)),
        ("first-before", |l| l[0] = moved(&l[0], -10.0)),
        ("last-after", |l| {
            let last = l.len() - 1;
            l[last] = moved(&l[last], 10.0);
        }),
    ];
    for (name, edit) in imu_edits {
        let run = kingston_with_imu(&tmp.path().join(name), edit);
        let (got, repaired, _) = disupt_json(&run, name);
        assert_eq!(repaired, 1, "{name}");
        assert!(
            got == want,
            "{name}: disupt.json differs from the shipped run's"
        );
        // The 10 s and the 0.1-s period between the lines, to the tags' 1 ms.
        let r = ingest_report(name);
        assert_eq!((r.seq_gaps, r.lost_samples), (0, 0), "{name}");
        let (first, last) = match name {
            "first-before" => (Some(10.1), None),
            "last-after" => (None, Some(10.1)),
            // Its tag ahead of the second's: a tag going back, no gap.
            _ => (None, None),
        };
        let near = |got: Option<f64>, want: Option<f64>| match (got, want) {
            (Some(g), Some(w)) => (g - w).abs() < 1e-3,
            (g, w) => g.is_none() && w.is_none(),
        };
        assert!(near(r.first_line_apart_s, first), "{name}: {r:?}");
        assert!(near(r.last_line_apart_s, last), "{name}: {r:?}");
    }

    let speeds = std::fs::read_to_string(shipped.join("odometer.txt")).unwrap();
    let speeds: Vec<&str> = speeds.lines().collect();
    for (name, k) in [("speed-720", 719), ("speed-first", 0)] {
        assert!(
            k == 0 || speeds[k].starts_with("152862 13."),
            "{}",
            speeds[k]
        );
        let with = |lines: Vec<String>| {
            let run =
                kingston_with_imu(&tmp.path().join(format!("{name}-{}", lines.len())), |_| {});
            std::fs::write(run.join("odometer.txt"), lines.join("\n") + "\n").unwrap();
            run
        };
        let mut leapt: Vec<String> = speeds.iter().map(|l| l.to_string()).collect();
        leapt[k] = moved(&leapt[k], 50.0);
        let mut without = leapt.clone();
        without.remove(k);
        let (got, _, faults) = disupt_json(&with(leapt), name);
        assert_eq!(faults.len(), 1, "{name}: {faults:?}");
        assert_eq!(faults[0].line, k as u64 + 1, "{name}: {faults:?}");
        assert!(
            faults[0].reason.contains("leaps ahead of the lines"),
            "{name}: {faults:?}"
        );
        let (want, _, none) = disupt_json(&with(without), &format!("{name}-without"));
        assert!(none.is_empty(), "{none:?}");
        assert!(
            got == want,
            "{name}: disupt.json differs from the file without the line"
        );
    }
}

/// Makes a FIFO (named pipe) at `path`, as an archive tool may restore one.
#[cfg(unix)]
fn make_fifo(path: &Path) {
    let mode = rustix::fs::Mode::RUSR | rustix::fs::Mode::WUSR;
    rustix::fs::mknodat(rustix::fs::CWD, path, rustix::fs::FileType::Fifo, mode, 0).unwrap();
}

/// A raw log that is a FIFO (an archive may restore one): opening it for reading waited
/// for a writer, and the whole campaign with it. Now that run fails at once, naming the
/// file and its kind, and the other run goes on. Run under a deadline, so a regression
/// fails instead of hanging the tests.
#[cfg(unix)]
#[test]
fn a_raw_log_that_is_a_fifo_fails_its_run_and_stops_nothing_else() {
    use std::io::Read;
    use std::process::Stdio;
    use std::time::{Duration, Instant};

    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let log = camp.join("sim-0081/sim-0081.unz");
    std::fs::remove_file(&log).unwrap();
    make_fifo(&log);
    let out = tmp.path().join("o");
    let mut child = unz()
        .args([
            "run",
            camp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .args(["--until", "derive"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(120);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if Instant::now() > deadline {
            child.kill().unwrap();
            panic!("unz run still waits on the FIFO after 120 s");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut text = String::new();
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut text)
        .unwrap();
    assert_eq!(status.code(), Some(1), "{text}");
    assert!(
        text.contains("FAILED sim-0081") && text.contains("not a regular file but a FIFO"),
        "{text}"
    );
    assert!(text.contains("sim-0081.unz"), "{text}");
    assert!(out.join("sim-0080/derive/derived.parquet").is_file());
}

/// A campaign's `run.toml` that is a symbolic link (not followed: it could name a
/// manifest anywhere) or a FIFO was passed over without a word; now each is named with
/// why, and the other runs go on.
#[cfg(unix)]
#[test]
fn a_manifest_that_is_not_a_regular_file_is_skipped_and_said() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let linked = camp.join("sim-0081/run.toml");
    std::fs::rename(&linked, camp.join("sim-0081/manifest.toml")).unwrap();
    std::os::unix::fs::symlink("manifest.toml", &linked).unwrap();
    let fifo = camp.join("elsewhere/run.toml");
    std::fs::create_dir_all(fifo.parent().unwrap()).unwrap();
    make_fifo(&fifo);
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "ingest");
    assert_eq!(code, Some(0), "{text}");
    assert!(
        text.contains(&format!(
            "skipped {}: a symbolic link, not followed",
            linked.display()
        )),
        "{text}"
    );
    assert!(
        text.contains(&format!("skipped {}: not a regular file", fifo.display())),
        "{text}"
    );
    assert!(text.contains("1 run: 1 ok"), "{text}");
    assert!(out.join("sim-0080/ingest/imu.parquet").is_file());
}

/// The odometer-failure status bit: set on every sample, the run fails and says so; set on
/// a few, they are counted in navigate.json and the run goes on.
#[test]
fn odometer_failure_flags_are_honoured() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    rewrite_imu(&camp.join("sim-0080/sim-0080.unz"), &|r| {
        if (1000..1100).contains(&r.seq) {
            r.status |= 2;
        }
    });
    // Flagged from its 401st record on (the log's IMU records alone are before its
    // marks: 48 bytes each after the header's 128).
    let k = std::cell::Cell::new(0_u32);
    rewrite_imu(&camp.join("sim-0081/sim-0081.unz"), &|r| {
        if k.get() >= 400 {
            r.status |= 2;
        }
        k.set(k.get() + 1);
    });
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "navigate");
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("FAILED sim-0081")
            && text.contains(
                "odometer is flagged failed (status bit 1) on 19600 of 20000 samples (the first \
                 at sample 400, byte offset 19328 of sim-0081.unz)"
            ),
        "{text}"
    );
    let log = std::fs::read(camp.join("sim-0081/sim-0081.unz")).unwrap();
    let status = |at: usize| imu_field(&log, at, 44, 2);
    assert_eq!((status(19_328 - 48) & 2, status(19_328) & 2), (0, 2));
    let nav: NavigateSummary = read_json(&out.join("sim-0080/navigate/navigate.json"));
    assert_eq!(nav.odometer_failure_samples, 100, "{nav:?}");
}

/// A tmpfs mounted for one test, unmounted (lazily) when dropped.
struct Mount(PathBuf);

impl Mount {
    /// Mounts a tmpfs with `options` at `dir`; `None` where this process may not mount
    /// (not root, or a container without the capability).
    fn tmpfs(dir: &Path, options: &str) -> Option<Self> {
        std::fs::create_dir_all(dir).unwrap();
        let ok = std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", options, "tmpfs", dir.to_str().unwrap()])
            .stderr(std::process::Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        ok.then(|| Self(dir.to_path_buf()))
    }

    fn remount(&self, options: &str) {
        let s = std::process::Command::new("mount")
            .args([
                "-o",
                &format!("remount,{options}"),
                self.0.to_str().unwrap(),
            ])
            .status()
            .unwrap();
        assert!(s.success());
    }
}

impl Drop for Mount {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount")
            .args(["-l", self.0.to_str().unwrap()])
            .status();
    }
}

/// Every file below `dir`, as full paths.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    files_below(dir).into_iter().map(|f| dir.join(f)).collect()
}

/// A read-only output folder and a disk that fills up during the review: each error says
/// the operating system's reason with the path (the Rerun SDK's writer used to say only
/// "File-writer thread shut down prematurely"), and no temporary file stays behind.
/// Needs to mount a tmpfs (root, as on CI); elsewhere it says so and checks nothing.
#[test]
fn read_only_and_full_output_folders_are_said_with_the_path() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let ro_dir = tmp.path().join("ro");
    let Some(_ro) = Mount::tmpfs(&ro_dir, "ro,size=1m") else {
        eprintln!("cannot mount a tmpfs here: the check needs root");
        return;
    };
    let out = ro_dir.join("out");
    let (code, text) = run(&camp, &out, "review");
    assert_ne!(code, Some(0), "{text}");
    assert!(
        text.contains("Read-only file system") && text.contains(out.to_str().unwrap()),
        "{text}"
    );

    // Everything up to export fits; then the disk is shrunk to leave less than half a
    // recording.
    let reference = tmp.path().join("reference");
    let (code, text) = run(&camp, &reference, "review");
    assert_eq!(code, Some(0), "{text}");
    let review_bytes: u64 = files_under(&reference)
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "rrd"))
        .map(|p| p.metadata().unwrap().len())
        .max()
        .unwrap();
    let full_dir = tmp.path().join("full");
    let full = Mount::tmpfs(&full_dir, "size=200m").unwrap();
    let out = full_dir.join("out");
    let (code, text) = run(&camp, &out, "export");
    assert_eq!(code, Some(0), "{text}");
    let used: u64 = files_under(&out)
        .iter()
        .map(|p| p.metadata().unwrap().len().div_ceil(4096) * 4096)
        .sum();
    full.remount(&format!("size={}", used + review_bytes / 2 + 64 * 1024));
    let (code, text) = run(&camp, &out, "review");
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("stage review failed: cannot write")
            && text.contains("No space left on device")
            && text.contains(out.to_str().unwrap()),
        "{text}"
    );
    assert!(!text.contains("shut down prematurely"), "{text}");
    let left: Vec<_> = files_under(&out)
        .into_iter()
        .filter(|p| p.to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
}

/// Saturated angle increments (i32::MAX counts: 32 rad in 10 ms): a few are replaced by
/// the previous sample's rates and counted in navigate.json, the route unharmed; many
/// fail the run with the reason.
#[test]
fn saturated_increments_are_replaced_or_fail_their_run() {
    let saturate = |saturated: fn(u32) -> bool| {
        move |r: &mut unz_formats::raw::ImuRecord| {
            if saturated(r.seq) {
                r.dtheta = [i32::MAX, i32::MIN, i32::MAX];
            }
        }
    };
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let clean = tmp.path().join("clean");
    let (code, text) = run(&camp, &clean, "navigate");
    assert_eq!(code, Some(0), "{text}");
    // Five samples in the static start (its rates are the previous sample's to the noise).
    rewrite_imu(
        &camp.join("sim-0080/sim-0080.unz"),
        &saturate(|seq| (1000..1005).contains(&seq)),
    );
    rewrite_imu(
        &camp.join("sim-0081/sim-0081.unz"),
        &saturate(|seq| seq % 10 == 3),
    );
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "navigate");
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("FAILED sim-0081") && text.contains("exceed the IMU's range"),
        "{text}"
    );
    // The first is named with its record's byte offset: the fourth record (the log
    // holds IMU records alone before its marks, 48 bytes each after the header's 128),
    // saturated.
    assert!(
        text.contains("(degrees?) (the first at sample 3, byte offset 272 of sim-0081.unz)"),
        "{text}"
    );
    let log = std::fs::read(camp.join("sim-0081/sim-0081.unz")).unwrap();
    assert_eq!(imu_field(&log, 272, 16, 4), i32::MAX as u64);
    let read =
        |dir: &Path| -> NavigateSummary { read_json(&dir.join("sim-0080/navigate/navigate.json")) };
    let (patched, reference) = (read(&out), read(&clean));
    assert_eq!(patched.out_of_range_samples, 5);
    assert_eq!(reference.out_of_range_samples, 0);
    // Replacing 50 ms of rest by the rates before it moves the end of a 200 s drive by
    // what 50 ms of gyro noise does: far below a metre (a saturated sample kept would
    // have spun the attitude by 32 rad).
    let end = |s: &NavigateSummary| s.control_points.last().map(|c| (c.dx_m, c.dy_m)).unwrap();
    let (a, b) = (end(&patched), end(&reference));
    assert!((a.0 - b.0).hypot(a.1 - b.1) < 0.5, "{a:?} vs {b:?}");
    // The derive stores the five replaced samples' increments alone (the others are the
    // ingest's): navigated in a process of its own, from the cache, the run gives the
    // chain's files byte for byte.
    let derive_dir = out.join("sim-0080/derive");
    let repairs = parquet_rows(&derive_dir.join("imu_repairs.parquet"));
    assert_eq!(repairs, 5);
    let alone = tmp.path().join("alone");
    let run_dir = camp.join("sim-0080");
    for stage in ["derive", "navigate"] {
        let o = unz_output(&[
            stage,
            run_dir.to_str().unwrap(),
            "--out",
            alone.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{o:?}");
    }
    for file in ["navigate/nav.parquet", "navigate/navigate.json"] {
        let read = |o: &Path| std::fs::read(o.join("sim-0080").join(file)).unwrap();
        assert!(read(&out) == read(&alone), "{file} differs");
    }
}

/// Moves the first control point of the manifest `run_toml` by `north_m` and `east_m`.
fn move_control_point(run_toml: &Path, north_m: f64, east_m: f64) {
    let mut m: toml::Table = std::fs::read_to_string(run_toml).unwrap().parse().unwrap();
    let cp = m["control_point"].as_array_mut().unwrap()[0]
        .as_table_mut()
        .unwrap();
    let lat_deg = cp["latitude_deg"].as_float().unwrap();
    let lon_deg = cp["longitude_deg"].as_float().unwrap();
    let r_m = 6_371_000.0;
    cp["latitude_deg"] = (lat_deg + (north_m / r_m).to_degrees()).into();
    cp["longitude_deg"] =
        (lon_deg + (east_m / (r_m * lat_deg.to_radians().cos())).to_degrees()).into();
    std::fs::write(run_toml, toml::to_string(&m).unwrap()).unwrap();
}

/// A control point no setting reaches (5 000 km from a start the vehicle left 750 m
/// before) fails its run with the point and the manifest, where the joint fit used to
/// follow it to an odometer scale of thousands and report 0 m under "ok". One within
/// reach but 1 km off its surveyed place (a wrong point id, say): OEPI and OWPI stay in
/// their bounds, and the joint fit, which would leave them to reach it, is refused with
/// what it moved; the corrected navigation is OEPI's and the summary says why the joint
/// is missing.
#[test]
fn control_points_the_log_cannot_reach_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    move_control_point(&camp.join("sim-0081/run.toml"), -5.0e6, 0.0);
    move_control_point(&camp.join("sim-0080/run.toml"), 0.0, 1000.0);
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "disupt");
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("FAILED sim-0081")
            && text.contains("sim-0081/run.toml")
            && text.contains("control point 1 is 50")
            && text.contains("no azimuth or odometer scale reaches it"),
        "{text}"
    );
    let d: unz::disupt_stage::DisuptOut = read_json(&out.join("sim-0080/disupt/disupt.json"));
    let why = &d.skipped["joint"];
    assert!(why.contains("the fit left its bounds"), "{why}");
    assert!(!d.methods.contains_key("joint"));
    assert_eq!(d.corrected_by.as_deref(), Some("oepi"));
    // OEPI's azimuth stays within ±15° of its start (the coarse search's, when it moved).
    let oepi = &d.methods["oepi"].outcome.x;
    let start_deg = d.coarse_azimuth_deg.unwrap_or(d.before.x.azimuth_deg);
    let moved_deg = (oepi.azimuth_deg - start_deg + 180.0).rem_euclid(360.0) - 180.0;
    assert!(moved_deg.abs() <= 15.0 + 1e-9, "{moved_deg}");
    let row = campaign_row(&out, "sim-0080");
    assert!(
        row.contains("| ok |") && row.contains("joint not run: the fit left its bounds"),
        "{row}"
    );
}

/// A run whose joint fit is refused (a control point 1 km off) is corrected by OEPI, a
/// route whose track was written while the joint fit ran: run alone (its reviews beside
/// the joint fit, their tracks handed to the file without a copy, then reviewed again
/// for the file written anew) it writes the same files, byte for byte, as in a campaign
/// that shares the cores (its reviews all after the fit).
#[test]
fn a_refused_joint_fit_writes_the_same_tables_alone_as_in_a_campaign() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    move_control_point(&camp.join("sim-0080/run.toml"), 0.0, 1000.0);
    let (shared, alone) = (tmp.path().join("shared"), tmp.path().join("alone"));
    let (code, text) = run(&camp, &shared, "disupt");
    assert_eq!(code, Some(0), "{text}");
    let (code, text) = run(&camp.join("sim-0080"), &alone, "disupt");
    assert_eq!(code, Some(0), "{text}");
    let d: unz::disupt_stage::DisuptOut = read_json(&alone.join("sim-0080/disupt/disupt.json"));
    assert!(d.skipped.contains_key("joint"), "{:?}", d.skipped);
    assert_eq!(d.corrected_by.as_deref(), Some("oepi"));
    for file in [
        "tracks.parquet",
        "corrected_nav.parquet",
        "kryt1_series.parquet",
        "disupt.json",
    ] {
        let bytes = |out: &Path| std::fs::read(out.join("sim-0080/disupt").join(file)).unwrap();
        let (a, b) = (bytes(&shared), bytes(&alone));
        assert!(
            a == b,
            "{file}: {} bytes shared, {} alone",
            a.len(),
            b.len()
        );
    }
    // The three methods' tracks (the initial settings', OWPI's, OEPI's), each of the
    // run's kept samples at 10 Hz: none left empty.
    let rows = parquet_rows(&alone.join("sim-0080/disupt/tracks.parquet"));
    assert!(rows >= 3 * 1_900 && rows % 3 == 0, "{rows}");
}

/// A 30-s hole in a moving run's IMU log (its records lost) fails the run at derive with
/// where the gap is, where holding the rate across it turned the heading by whatever the
/// vehicle was turning at times 3 000; a run that raises `derive.max_gap_s` past it (a
/// pause its crew knows to have been at rest) is bridged as before.
#[test]
fn a_gap_longer_than_the_derive_bridges_fails_its_run() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    // 30 s of records lost (their `seq` and tags gone with them).
    let lose_30_s = |log: &Path| {
        let mut l = read_log(log);
        l.imu.drain(12_000..15_000);
        for (at, _) in &mut l.marks {
            if *at > 12_000 {
                *at = at.saturating_sub(3_000).max(12_000);
            }
        }
        write_log(log, &l);
    };
    lose_30_s(&camp.join("sim-0081/sim-0081.unz"));
    lose_30_s(&camp.join("sim-0080/sim-0080.unz"));
    append(
        &camp.join("sim-0080/run.toml"),
        "\n[params.derive]\nmax_gap_s = 40.0\n",
    );
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "derive");
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("FAILED sim-0081")
            && text.contains("gap of 30.01 s after t = 119.99 s (before sample 12000, byte")
            && text.contains("derive.max_gap_s = 2 s"),
        "{text}"
    );
    assert!(!text.contains("FAILED sim-0080"), "{text}");
    assert!(out.join("sim-0080/derive/derived.parquet").is_file());
    // The sample after the gap is named by its record's byte offset: the frame there is
    // the 15 000th record after the first by its `seq`, 150 s after it.
    let log = std::fs::read(camp.join("sim-0081/sim-0081.unz")).unwrap();
    let at = offset_named(&text, "(before sample 12000, byte offset ", "sim-0081.unz");
    let field = |at: usize, from: usize, len: usize| imu_field(&log, at, from, len);
    let first = unz_formats::raw::HEADER_LEN;
    assert_eq!(field(at, 4, 4) - field(first, 4, 4), 15_000);
    assert_eq!(field(at, 8, 8) - field(first, 8, 8), 150_000_000);

    // A text log's gap is named by its line: 40 lines (4 s) of Kingston's log taken out.
    let run = kingston_with_imu(&tmp.path().join("k"), |lines| {
        lines.drain(7000..7040);
    });
    let err = crate::util::stage_fails("derive", &run, &tmp.path().join("ko"));
    assert!(
        err.contains("gap of 4.10 s after t = ") && err.contains(", line 7001 of imu.txt)"),
        "{err}"
    );
}

/// Many odometer steps no land vehicle makes (a pulse counter jumping by a million counts
/// on every 50th record, 2 % of the steps) are a broken odometer: the run fails in its
/// ingest, naming the first step's record by its byte offset, and the other run goes on.
#[test]
fn an_odometer_of_many_impossible_steps_fails_its_run_at_the_first() {
    use std::cell::Cell;
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let k = Cell::new(0_u32);
    let jumps = Cell::new(0_u32);
    rewrite_imu(&camp.join("sim-0081/sim-0081.unz"), &|r| {
        if k.get() >= 1000 && k.get() % 50 == 7 {
            jumps.set(jumps.get() + 1);
        }
        r.odo_count = (r.odo_count).wrapping_add(1_000_000 * jumps.get());
        k.set(k.get() + 1);
    });
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "derive");
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("FAILED sim-0081")
            && text.contains("380 of 20000 odometer steps are beyond a land vehicle's speed"),
        "{text}"
    );
    assert!(!text.contains("FAILED sim-0080"), "{text}");
    // The first is the 1007th record after the first, named by its byte offset.
    let at = offset_named(&text, "(the first at byte offset ", "sim-0081.unz");
    let log = std::fs::read(camp.join("sim-0081/sim-0081.unz")).unwrap();
    let seq = |at: usize| imu_field(&log, at, 4, 4);
    assert_eq!(seq(at) - seq(unz_formats::raw::HEADER_LEN), 1007);
}

/// Odometer steps no land vehicle makes: a pulse counter jumping by a million counts
/// (12.5 km in 10 ms) in a UNZ log, and a 1e300 m/s line in a KF-GINS speed file. Each
/// ended "ok" with the jump in its route (a distance of 1e300 m in the summary); now the
/// step is replaced by the speed before it and counted (`ingest.json`), the bad line is a
/// line fault, and the route is the one without them.
#[test]
fn odometer_steps_no_land_vehicle_makes_are_replaced_and_counted() {
    use std::cell::Cell;
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let k = Cell::new(0_u32);
    rewrite_imu(&camp.join("sim-0081/sim-0081.unz"), &|r| {
        if k.get() >= 12_000 {
            r.odo_count = r.odo_count.wrapping_add(1_000_000);
        }
        k.set(k.get() + 1);
    });
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "navigate");
    assert_eq!(code, Some(0), "{text}");
    let ingest = |run: &str| read_json::<IngestReport>(&out.join(run).join("ingest/ingest.json"));
    assert_eq!(ingest("sim-0081").odometer_out_of_range, 1);
    assert_eq!(ingest("sim-0080").odometer_out_of_range, 0);
    // Written only when a step was replaced (the spec's keys otherwise).
    let text = std::fs::read_to_string(out.join("sim-0080/ingest/ingest.json")).unwrap();
    assert!(!text.contains("odometer_out_of_range"), "{text}");
    let distance = |run: &str| {
        read_json::<NavigateSummary>(&out.join(run).join("navigate/navigate.json")).distance_m
    };
    // The two runs drive alike (seeds 80 and 81, 200 s); the jump is not in the route.
    assert!(
        distance("sim-0081") < 2.0 * distance("sim-0080"),
        "{}",
        distance("sim-0081")
    );

    let run = tmp.path().join("k");
    std::fs::create_dir_all(&run).unwrap();
    for f in ["imu.txt", "run.toml"] {
        std::fs::copy(
            crate::util::test_data("kingston2008-seg1").join(f),
            run.join(f),
        )
        .unwrap();
    }
    let odometer =
        std::fs::read_to_string(crate::util::test_data("kingston2008-seg1").join("odometer.txt"))
            .unwrap();
    let mut lines: Vec<String> = odometer.lines().map(String::from).collect();
    let t = lines[500].split_whitespace().next().unwrap().to_owned();
    lines[500] = format!("{t} 1e300");
    std::fs::write(run.join("odometer.txt"), lines.join("\n") + "\n").unwrap();
    let out = tmp.path().join("ko");
    crate::util::run_until(&run, &out, "navigate");
    let events: unz_formats::IngestEvents =
        read_json(&out.join("kingston2008-segment1/ingest/ingest_events.json"));
    assert_eq!(events.raw, Path::new("imu.txt"));
    let [fault] = &events.odometer_file_faults[..] else {
        panic!("{events:?}");
    };
    assert_eq!(fault.line, 501);
    assert!(
        fault
            .reason
            .contains("speed 1e300 m/s is beyond a land vehicle's"),
        "{fault:?}"
    );
    // Every line of the odometer file is accounted, the rejected one too.
    let report: IngestReport = read_json(&out.join("kingston2008-segment1/ingest/ingest.json"));
    assert_eq!(
        report.odometer_file,
        Some(unz_formats::OdometerFileReport {
            lines_read: lines.len() as u64,
            lines_accepted: lines.len() as u64 - 1,
            lines_rejected: 1,
            ..Default::default()
        })
    );
    assert!(report.is_consistent(), "{report:?}");
    assert_eq!(report.rejected_all_files(), 1);
    let nav: NavigateSummary = read_json(&out.join("kingston2008-segment1/navigate/navigate.json"));
    // The segment's 2.3 km (README), not 1e300 m.
    let d = nav.distance_m;
    assert!((2000.0..2700.0).contains(&d), "{d}");
}

/// Simulated run `seed` (`options`) navigated as simulated, into `dir/clean`, and with the
/// mark `extra` gives for its log inserted, into `dir/marked`: (the two `navigate.json`s,
/// the mark inserted, the log's last mark).
fn navigated_with_mark(
    dir: &Path,
    seed: u32,
    options: &[&str],
    extra: impl FnOnce(&crate::util::Log) -> unz_formats::raw::MarkRecord,
) -> (
    NavigateSummary,
    NavigateSummary,
    unz_formats::raw::MarkRecord,
    unz_formats::raw::MarkRecord,
) {
    let run = crate::util::simulated_run(dir, seed, options);
    let name = format!("sim-{seed:04}");
    let path = run.join(format!("{name}.unz"));
    let mut log = read_log(&path);
    let (_, last) = *log.marks.last().unwrap();
    let mark = extra(&log);
    let navigate = |out: &str| -> NavigateSummary {
        let out = dir.join(out);
        crate::util::run_until(&run, &out, "criteria");
        read_json(&out.join(&name).join("navigate/navigate.json"))
    };
    let clean = navigate("clean");
    log.insert_mark(mark);
    crate::util::write_log(&path, &log);
    (clean, navigate("marked"), mark, last)
}

/// A control point marked twice: an early press 5 s before the stop, while driving up to
/// it (the first mark was used, placing the point tens of metres up the road). The
/// mark at the stop is used, `navigate.json` says which and why, and the errors at the
/// control points are the log's without the early press, bit for bit.
#[test]
fn of_a_point_marked_twice_the_mark_at_rest_is_used() {
    use unz_formats::raw::MarkRecord;

    let tmp = tempfile::tempdir().unwrap();
    let (clean, twice, early, last_mark) =
        navigated_with_mark(tmp.path(), 90, &["--duration-s", "600"], |log| {
            let (_, last_mark) = *log.marks.last().unwrap();
            // The vehicle stops some time before the point is marked: the early press is
            // 5 s before it stopped (its last pulse), while it drove up.
            let before = log.imu.partition_point(|r| r.t_us < last_mark.t_us);
            let stopped = 1 + log.imu[..before]
                .windows(2)
                .rposition(|w| w[0].odo_count != w[1].odo_count)
                .unwrap();
            MarkRecord {
                t_us: log.imu[stopped].t_us - 5_000_000,
                point_id: last_mark.point_id,
            }
        });
    assert!(clean.repeated_marks.is_empty());
    assert_eq!(twice.repeated_marks.len(), 1, "{:?}", twice.repeated_marks);
    let r = &twice.repeated_marks[0];
    assert_eq!((r.id, r.marks), (last_mark.point_id, 2));
    assert!(
        (r.first_t_s - early.t_us as f64 * 1e-6).abs() < 1e-6,
        "{r:?}"
    );
    assert!(
        (r.used_t_s - last_mark.t_us as f64 * 1e-6).abs() < 1e-6,
        "{r:?}"
    );
    assert!(
        r.at_rest && r.used_speed_mps.is_some_and(|v| v <= 0.1),
        "{r:?}"
    );
    assert_eq!(twice.control_points, clean.control_points);
    let summary = std::fs::read_to_string(tmp.path().join("marked/campaign.md")).unwrap();
    let note = format!(
        "control point {} marked 2 times: the mark at t_s = {:.2} used (the last at rest)",
        last_mark.point_id,
        last_mark.t_us as f64 * 1e-6
    );
    assert!(summary.contains(&note), "{summary}");
    // The first run's note in the campaign summary of `dir`.
    let note_of = |dir: &str| {
        use arrow::array::Array;
        let (_, batches) =
            unz_formats::parquet_io::read_batches(&tmp.path().join(dir).join("campaign.parquet"))
                .unwrap();
        let column = batches[0]
            .column_by_name(unz_formats::schema::CAMPAIGN_NOTE)
            .unwrap()
            .as_any()
            .downcast_ref::<arrow::array::StringArray>()
            .unwrap()
            .clone();
        column.is_valid(0).then(|| column.value(0).to_owned())
    };
    assert_eq!(note_of("marked"), Some(note));
    assert_eq!(
        note_of("clean"),
        None,
        "a run with nothing to note has a null note"
    );
}

/// A point's id pressed at rest at an earlier stop, kilometres of driving before the
/// point (a stop taken for the point, corrected at the point itself): both presses are at
/// rest and far apart along the path, as a point the route comes back to would be, but
/// the navigation puts them hundreds of metres apart, so the earlier is a press the last
/// corrected, not a visit. `navigate.json` says so (`elsewhere_t_s`), and the errors at
/// the control points are the log's without it, bit for bit.
#[test]
fn a_press_at_another_stop_is_not_a_visit() {
    use unz_formats::raw::MarkRecord;

    let tmp = tempfile::tempdir().unwrap();
    let options = ["--duration-s", "1200", "--cp-at-every-stop"];
    let (clean, pressed, wrong, last) = navigated_with_mark(tmp.path(), 91, &options, |log| {
        let (_, first) = log.marks[0];
        let (_, last) = *log.marks.last().unwrap();
        assert!(last.point_id > 2, "{:?}", log.marks);
        // At the first point's stop, 2 s after its mark: the last point's id.
        MarkRecord {
            t_us: first.t_us + 2_000_000,
            point_id: last.point_id,
        }
    });
    let r = &pressed.repeated_marks[0];
    assert_eq!(
        (r.id, r.marks, r.at_rest),
        (last.point_id, 2, true),
        "{r:?}"
    );
    assert!(r.visits_t_s.is_empty(), "{r:?}");
    let t = |us: u64| us as f64 * 1e-6;
    assert_eq!(r.elsewhere_t_s.len(), 1, "{r:?}");
    assert!((r.elsewhere_t_s[0] - t(wrong.t_us)).abs() < 1e-6, "{r:?}");
    assert!((r.used_t_s - t(last.t_us)).abs() < 1e-6, "{r:?}");
    assert_eq!(pressed.control_points, clean.control_points);
    let summary = std::fs::read_to_string(tmp.path().join("marked/campaign.md")).unwrap();
    let note = format!(
        "placed elsewhere by the navigation, not used: t_s = {:.2}",
        t(wrong.t_us)
    );
    assert!(summary.contains(&note), "{summary}");
}

/// A route driven out and back ends on the point at its start, and the crew marked that
/// point during the static start too: the same place, but the navigation starts at the
/// manifest's site, so that mark compares the site with the survey (a site read off a
/// map would make it a point off, and the end's visit left out with it). It is not a
/// visit; `navigate.json` says so (`at_start_t_s`), and the errors at the control points
/// are the log's without it, bit for bit.
#[test]
fn a_mark_during_the_static_start_is_not_a_visit() {
    use unz_formats::raw::MarkRecord;

    let tmp = tempfile::tempdir().unwrap();
    let options = ["--duration-s", "1200", "--out-and-back"];
    let (clean, marked, _, home) = navigated_with_mark(tmp.path(), 92, &options, |log| {
        let (_, home) = *log.marks.last().unwrap();
        MarkRecord {
            t_us: 30_000_000,
            point_id: home.point_id,
        }
    });
    let r = marked
        .repeated_marks
        .iter()
        .find(|r| r.id == home.point_id)
        .unwrap();
    assert_eq!((r.marks, r.at_start_t_s.len()), (2, 1), "{r:?}");
    assert!((r.at_start_t_s[0] - 30.0).abs() < 1e-6, "{r:?}");
    assert!(
        r.visits_t_s.is_empty() && r.elsewhere_t_s.is_empty(),
        "{r:?}"
    );
    assert_eq!(marked.control_points, clean.control_points);
}

/// An odometer the log flags failed (status bit 1) for 15 s while driving, its count held:
/// the ingest bridges it with the inertial along-track speed (a held count lost the
/// distance driven meanwhile, and the summary blamed the control points), and the
/// campaign's summary says so first. A failure longer than the longest bridged (here
/// 150 s of a 30-minute run) holds the distance over it, and the summary says that the
/// route after it is short.
#[test]
fn an_odometer_flagged_failed_while_driving_is_bridged_and_said_in_the_summary() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let raw = camp.join("sim-0080/sim-0080.unz");
    // From 150 s (driving since the 90-s static start) for 1500 samples of 100 Hz.
    hold_count(&raw, 15_000, 1500, true);
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "disupt");
    assert_eq!(code, Some(0), "{text}");
    let nav: NavigateSummary = read_json(&out.join("sim-0080/navigate/navigate.json"));
    assert_eq!(nav.odometer_failure_samples, 1500);
    let ingest: IngestReport = read_json(&out.join("sim-0080/ingest/ingest.json"));
    let f = ingest.odometer_failures.unwrap();
    assert_eq!((f.bridged, f.bridged_samples, f.not_bridged), (1, 1500, 0));
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    let row = |name: &str| {
        summary
            .lines()
            .find(|l| l.starts_with(&format!("| {name} ")))
            .unwrap()
            .to_owned()
    };
    assert!(
        row("sim-0080").contains(
            "| the odometer is flagged failed (status bit 1) on 1500 samples (15.0 s); bridged \
             by the inertial along-track speed: 1 failure (15.0 s, "
        ),
        "{summary}"
    );
    assert!(!row("sim-0080").contains("no distance"), "{summary}");
    assert!(!row("sim-0081").contains("flagged failed"), "{summary}");

    // 150 s flagged in a 30-minute run (a tenth of it would fail the run).
    let camp = simulated_campaign(&tmp.path().join("long"), 82, 1, 1800.0);
    let (k0, len) = (30_000, 15_000);
    hold_count(&camp.join("sim-0082/sim-0082.unz"), k0, len, true);
    let out = tmp.path().join("o-long");
    let (code, text) = run(&camp, &out, "disupt");
    assert_eq!(code, Some(0), "{text}");
    let ingest: IngestReport = read_json(&out.join("sim-0082/ingest/ingest.json"));
    let f = ingest.odometer_failures.unwrap();
    assert_eq!(
        (f.bridged, f.not_bridged, f.not_bridged_samples),
        (0, 1, 15_000)
    );
    // The distance holds over it, and goes on after it.
    let (_, batches) =
        unz_formats::parquet_io::read_batches(&out.join("sim-0082/ingest/odometer.parquet"))
            .unwrap();
    let d: Vec<f64> = batches
        .iter()
        .flat_map(|b| unz_formats::tables::f64_column(b, "distance_m").unwrap())
        .collect();
    let log = read_log(&camp.join("sim-0082/sim-0082.unz"));
    let lsb_m = log.header.odo_lsb_m;
    assert!(d[k0 - 1] > 100.0, "{}", d[k0 - 1]);
    // A flagged sample's count is not read: the first reading after goes on from the
    // last before.
    assert!(d[k0..=k0 + len].iter().all(|&x| x == d[k0 - 1]));
    let counted_m = |k: usize| {
        f64::from(
            log.imu[k]
                .odo_count
                .wrapping_sub(log.imu[k0 + len].odo_count),
        ) * lsb_m
    };
    for (k, x) in d.iter().enumerate().skip(k0 + len) {
        let want = d[k0 + len] + counted_m(k);
        assert!((x - want).abs() < 1e-6, "{k}: {x} against {want}");
    }
    assert!(d[d.len() - 1] > d[k0 - 1] + 1000.0);
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains(
            "the odometer is flagged failed (status bit 1) on 15000 samples (150.0 s); 1 \
             failure (15000 samples) not bridged (longer than 120 s, or without readings \
             around it): the dead reckoning has no distance over them"
        ),
        "{summary}"
    );
}

/// An odometer count that stops while driving without a flag (a broken wheel sensor or
/// cable): a stop from the speed before would have taken metres, so the ingest finds it
/// from the count's last step on and bridges it like a flagged failure, and the summary
/// says so. Stopped for the last 2–3 minutes of a 30-minute run, it is too long to
/// bridge: found, the distance held, and said; stopped for its last third, the run
/// fails, as a run flagged failed over a tenth of it does.
#[test]
fn an_odometer_count_that_stops_while_driving_is_found_without_a_flag() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let raw = camp.join("sim-0080/sim-0080.unz");
    hold_count(&raw, 15_000, 1500, false);
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "disupt");
    assert_eq!(code, Some(0), "{text}");
    let nav: NavigateSummary = read_json(&out.join("sim-0080/navigate/navigate.json"));
    assert_eq!(nav.odometer_failure_samples, 0);
    let ingest: IngestReport = read_json(&out.join("sim-0080/ingest/ingest.json"));
    let f = ingest.odometer_failures.unwrap();
    // From the sample after the last step (15 000) to the last held (16 500).
    assert_eq!((f.bridged, f.bridged_samples, f.not_bridged), (1, 1500, 0));
    assert_eq!((f.stuck, f.stuck_samples), (1, 1500));
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains(
            "| the odometer's distance stood while the vehicle moved, unflagged: 1 \
             time (1500 samples, 15.0 s); bridged by the inertial along-track speed: 1 \
             failure (15.0 s, "
        ),
        "{summary}"
    );
    let other: IngestReport = read_json(&out.join("sim-0081/ingest/ingest.json"));
    assert_eq!(other.odometer_failures, None);

    // Stopped at speed for good, in a 30-minute run: for the last 120–180 s (not bridged,
    // under a tenth of the run), and from 20 minutes on (a third: the run fails).
    let camp = simulated_campaign(&tmp.path().join("long"), 82, 1, 1800.0);
    let raw = camp.join("sim-0082/sim-0082.unz");
    let log = read_log(&raw);
    let n = log.imu.len();
    let at_speed = |from: usize| {
        (from..n - 100)
            .find(|&k| {
                let pulses = log.imu[k + 100]
                    .odo_count
                    .wrapping_sub(log.imu[k].odo_count);
                f64::from(pulses) * log.header.odo_lsb_m > 5.0
            })
            .unwrap()
    };
    let k0 = at_speed(n - 18_000);
    assert!(n - 1 - k0 > 12_000, "{k0}");
    let original = std::fs::read(&raw).unwrap();
    hold_count(&raw, k0, n - 1 - k0, false);
    let out = tmp.path().join("o-long");
    let (code, text) = run(&camp, &out, "disupt");
    assert_eq!(code, Some(0), "{text}");
    let ingest: IngestReport = read_json(&out.join("sim-0082/ingest/ingest.json"));
    let f = ingest.odometer_failures.unwrap();
    let stuck = (n - 1 - k0) as u64;
    assert_eq!(
        (
            f.stuck,
            f.stuck_samples,
            f.bridged,
            f.not_bridged,
            f.not_bridged_samples
        ),
        (1, stuck, 0, 1, stuck)
    );
    let summary = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert!(
        summary.contains(&format!(
            "the odometer's distance stood while the vehicle moved, unflagged: 1 time \
             ({stuck} samples, {:.1} s); 1 failure ({stuck} samples) not bridged (longer than \
             120 s, or without readings around it): the dead reckoning has no distance over \
             them",
            stuck as f64 * 0.01
        )),
        "{summary}"
    );

    std::fs::write(&raw, original).unwrap();
    let k0 = at_speed(120_000);
    hold_count(&raw, k0, n - 1 - k0, false);
    let (code, text) = run(&camp, &tmp.path().join("o-third"), "disupt");
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains(&format!(
            "the odometer's distance stood while the vehicle moved (unflagged) on {} of {n} \
             samples (the first from byte offset ",
            n - 1 - k0
        )),
        "{text}"
    );
    // Named by the record where the count stood: the held one's next.
    let at = offset_named(
        &text,
        "samples (the first from byte offset ",
        "sim-0082.unz",
    );
    let log = std::fs::read(&raw).unwrap();
    let seq = |at: usize| imu_field(&log, at, 4, 4);
    assert_eq!(seq(at) - seq(unz_formats::raw::HEADER_LEN), k0 as u64 + 1);
}

/// A control point whose `t_s` lies outside the log fails the run naming the point, its
/// time as a number a reader can take in (1e300 was printed with 301 digits), and the
/// log's span, which shows a time given from the log's start where the log's clock counts
/// from elsewhere (or the other way round).
#[test]
fn a_control_point_timed_outside_the_log_names_the_logs_span() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    for (run, t_s, said) in [("sim-0080", 1e300, "1e300"), ("sim-0081", -2.5, "-2.5")] {
        let path = camp.join(run).join("run.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let point = format!(
            "\n[[control_point]]\nid = 9\nlatitude_deg = 50.0\nlongitude_deg = 16.0\n\
             height_m = 200.0\nt_s = {t_s:e}\n"
        );
        std::fs::write(&path, text + &point).unwrap();
        let log = read_log(&camp.join(run).join(format!("{run}.unz")));
        let (first, last) = (log.imu.first().unwrap().t_us, log.imu.last().unwrap().t_us);
        let span = format!("{:.2} to {:.2}", first as f64 * 1e-6, last as f64 * 1e-6);
        let out = tmp.path().join(format!("o-{run}"));
        let (code, text) = self::run(&camp.join(run), &out, "navigate");
        assert_eq!(code, Some(1), "{text}");
        let want = format!(
            "control point 9 at t_s = {said} is outside the log, which runs from t_s = {span}"
        );
        assert!(text.contains(&want), "{want}\n{text}");
    }
}

/// A mark whose point id no control point has (a key pressed wrong, or a point left out
/// of the manifest): beside a control point that then matches nothing, the run's error
/// names both, the id typed wrong being the likely fault; beside points that all match
/// (here by their `t_s`), the run goes on and `navigate.json` and the campaign's note say
/// which marks matched no point.
#[test]
fn marks_of_ids_no_control_point_has_are_said() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = campaign(tmp.path());
    let mark_t_s = |run: &str| {
        let log = crate::util::read_log(&camp.join(run).join(format!("{run}.unz")));
        let (_, mark) = *log.marks.last().unwrap();
        assert_eq!(mark.point_id, 1);
        mark.t_us as f64 * 1e-6
    };
    let renumber = |run: &str, t_s: Option<f64>| {
        let path = camp.join(run).join("run.toml");
        let mut m: toml::Table = std::fs::read_to_string(&path).unwrap().parse().unwrap();
        let cp = m["control_point"].as_array_mut().unwrap()[0]
            .as_table_mut()
            .unwrap();
        cp.insert("id".into(), 7.into());
        if let Some(t) = t_s {
            cp.insert("t_s".into(), t.into());
        }
        std::fs::write(&path, toml::to_string(&m).unwrap()).unwrap();
    };
    let (t80, t81) = (mark_t_s("sim-0080"), mark_t_s("sim-0081"));
    renumber("sim-0080", None);
    renumber("sim-0081", Some(t81));
    let out = tmp.path().join("o");
    let (code, text) = run(&camp, &out, "navigate");
    assert_eq!(code, Some(1), "{text}");
    let said = format!(
        "control point 7 matches no mark record and has no t_s; the log has marks of ids no \
         control point has: 1 at t_s = {t80:.2}"
    );
    assert!(
        text.contains("FAILED sim-0080") && text.contains(&said),
        "{text}"
    );
    let nav: NavigateSummary = read_json(&out.join("sim-0081/navigate/navigate.json"));
    let unknown = nav.unknown_marks.unwrap();
    assert_eq!(unknown.total, 1);
    assert_eq!(unknown.first.len(), 1);
    assert_eq!(unknown.first[0].0, 1);
    assert!((unknown.first[0].1 - t81).abs() < 1e-6, "{unknown:?}");
    let row = campaign_row(&out, "sim-0081");
    assert!(
        row.contains("| ok |")
            && row.contains(&format!(
                "marks of ids no control point has: 1 at t_s = {t81:.2}"
            )),
        "{row}"
    );
}

/// A recorder's clock set by a time sync's tens of milliseconds while `seq` ran on (less
/// than the 10 periods a leap had to be): 50 ms forward at 60 s and 30 ms back at 140 s,
/// 95 ms each way, 20 ms forward alone, 40 ms back alone, the marks after each on its
/// clock. Each leap is taken out of the time base (counted, with what they add to the
/// tags after the last), and `disupt.json` is the undamaged run's byte for byte. Before,
/// every leap back failed the run's derive (the 6 000 tags after it, each behind the
/// time repaired before it, "do not increase"), and 20 ms forward scaled one sample's
/// increments three times as if it closed a gap (the joint azimuth 0.00016° off).
#[test]
fn a_clock_set_by_a_time_sync_is_taken_out_of_the_time_base() {
    let tmp = tempfile::tempdir().unwrap();
    let (camp, clean) = clean_200_s_run(tmp.path());
    let log = camp.join("sim-0080/sim-0080.unz");
    let undamaged = std::fs::read(&log).unwrap();
    // µs forward at record 6 000, back at 14 000; the steps; what they add after the last.
    let syncs: [(i64, i64, u64, f64); 4] = [
        (50_000, 30_000, 2, -0.02),
        (95_000, 95_000, 2, 0.0),
        (20_000, 0, 1, -0.02),
        (0, 40_000, 1, 0.04),
    ];
    for (i, (ahead, back, steps, shift_s)) in syncs.into_iter().enumerate() {
        let what = format!("{ahead} µs ahead, {back} µs back");
        std::fs::write(&log, &undamaged).unwrap();
        set_clock_twice(&log, ahead, ahead - back);
        let out = tmp.path().join(format!("o{i}"));
        let (code, text) = run(&camp, &out, "disupt");
        assert_eq!(code, Some(0), "{what}: {text}");
        let report: IngestReport = read_json(&out.join("sim-0080/ingest/ingest.json"));
        assert_eq!(
            (report.clock_steps, report.lone_tags_off, report.seq_gaps),
            (steps, 0, 0),
            "{what}: {report:?}"
        );
        assert!(
            (report.clock_shift_s - shift_s).abs() < 1e-9,
            "{what}: {report:?}"
        );
        let got = std::fs::read(out.join("sim-0080/disupt/disupt.json")).unwrap();
        assert!(
            got == clean,
            "{what}: disupt.json differs from the undamaged run's"
        );
    }
}

/// A recorder whose tags jitter (±2.5 ms about the 10-ms period, pseudo-random) with one
/// tag in 400 late by 8 ms, beyond half a period but within four times the jitter the
/// reader's clock learns (its steps stray by 3.4 ms at their 90th percentile: 13.7 ms),
/// so the tags are kept while `seq` says no sample was lost. The derive fills no gap
/// (navigate.json), and the samples' intervals are the period (the tags' mean step,
/// 9.999 817 ms here against the median's 9.999), so the increments and their rates
/// are the untouched run's to that period's 2·10⁻⁵: the time base jitters (the marks'
/// places and the odometer's reading times), and the run's errors before DISUPT and the
/// joint fit's azimuth are the untouched run's within 1 mm and 10⁻⁵° (0.7 µm and
/// 2.4·10⁻⁷° here). Before, the derive took each late tag's 15.5–20.5-ms interval as a gap
/// and scaled that sample's increments as many times over, and every sample's rates
/// (the accelerometers' and the odometer's speed) were its increments over its tags'
/// jittering interval: the errors before DISUPT moved by 0.5 m, the joint fit left its
/// bounds (drift y −9.4 °/h) and was refused, OEPI's azimuth moved by 0.03° and OWPI's
/// by 150°.
#[test]
fn a_recorder_whose_tags_jitter_past_half_a_period_fills_no_gap() {
    use unz::disupt_stage::DisuptOut;

    let tmp = tempfile::tempdir().unwrap();
    let (camp, clean) = clean_200_s_run(tmp.path());
    let clean: DisuptOut = serde_json::from_slice(&clean).unwrap();
    let log = camp.join("sim-0080/sim-0080.unz");
    let k = std::cell::Cell::new(0_u64);
    rewrite_imu(&log, &|r| {
        let i = k.get();
        // SplitMix64's finaliser: a fixed, evenly spread jitter in ±2 500 µs.
        let mut h = i.wrapping_add(0x9E37_79B9_7F4A_7C15);
        h = (h ^ (h >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h = (h ^ (h >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        h ^= h >> 31;
        let jitter_us = if i % 400 == 200 {
            8_000
        } else {
            (h % 5_001) as i64 - 2_500
        };
        r.t_us = r.t_us.checked_add_signed(jitter_us).unwrap();
        k.set(i + 1);
    });
    let out = tmp.path().join("o");
    let (report, nav) = ingest_and_navigation_of(&camp, &out, "disupt");
    assert_eq!(
        (report.clock_steps, report.lone_tags_off, report.seq_gaps),
        (0, 0, 0),
        "{report:?}"
    );
    assert_eq!(nav.filled_gaps, 0, "{nav:?}");
    let got: DisuptOut = read_json(&out.join("sim-0080/disupt/disupt.json"));
    let (a, b) = (&got.before, &clean.before);
    assert!(
        (a.dx_m - b.dx_m).abs() < 1e-3 && (a.dy_m - b.dy_m).abs() < 1e-3,
        "before: {a:?}\nuntouched: {b:?}"
    );
    let joint = |d: &DisuptOut| {
        let m = d.methods.get("joint");
        let m = m.unwrap_or_else(|| panic!("no joint fit: {:?} {:?}", d.methods.keys(), d.skipped));
        m.outcome.clone()
    };
    let (a, b) = (&joint(&got), &joint(&clean));
    assert!(
        (a.x.azimuth_deg - b.x.azimuth_deg).abs() < 1e-5,
        "joint: {:?}\nuntouched: {:?}",
        a.x,
        b.x
    );
}

/// A recorder restarted mid-run: 50 samples lost in its half-second pause, its `seq`
/// counted again from 0 after it. A counter reset says nothing of the time between, and
/// the unwrapped `seq` counts it as one step: the derive tells the pause by its interval
/// (longer than any two tags the reader's clock keeps one step apart) and fills it by
/// holding the rate, as it fills a text log's gaps.
#[test]
fn a_recorder_restarted_after_a_pause_has_the_pause_filled() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = simulated_campaign(&tmp.path().join("c"), 80, 1, 200.0);
    let path = camp.join("sim-0080/sim-0080.unz");
    let mut log = read_log(&path);
    log.imu.drain(10_000..10_050);
    for (k, r) in log.imu.iter_mut().enumerate().skip(10_000) {
        r.seq = (k - 10_000) as u32;
    }
    for (at, _) in &mut log.marks {
        if *at >= 10_050 {
            *at -= 50;
        }
    }
    write_log(&path, &log);
    let (report, nav) = ingest_and_navigation_of(&camp, &tmp.path().join("o"), "navigate");
    assert_eq!(
        (report.seq_gaps, report.lost_samples, report.clock_steps),
        (1, 0, 0),
        "{report:?}"
    );
    assert_eq!(nav.filled_gaps, 1, "{nav:?}");
}

/// Runs `stage` over the campaign `camp` (its one run, sim-0080) into `out`, which must
/// succeed, and reads the run's ingest report and navigation summary.
fn ingest_and_navigation_of(
    camp: &Path,
    out: &Path,
    stage: &str,
) -> (IngestReport, NavigateSummary) {
    let (code, text) = run(camp, out, stage);
    assert_eq!(code, Some(0), "{text}");
    (
        read_json(&out.join("sim-0080/ingest/ingest.json")),
        read_json(&out.join("sim-0080/navigate/navigate.json")),
    )
}
