//! The same input gives the same files: one run processed twice, into two output
//! folders, compared byte for byte — once by `unz run` in one process (the stages hand
//! the derive on in memory), once stage by stage in a process each (every stage loads
//! its inputs from the cache).

use std::path::{Path, PathBuf};

use crate::util::{files_below as files, simulated_run, unz, unz_ok};

/// The files below `a` and below `b`, asserted the same names and bytes (`what` names the
/// case); the names.
fn same_files(a: &Path, b: &Path, what: &str) -> Vec<PathBuf> {
    let (fa, fb) = (files(a), files(b));
    assert_eq!(fa, fb, "{what}");
    for f in &fa {
        let (x, y) = (
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
        );
        assert!(x == y, "{what}: {} differs between the two", f.display());
    }
    fa
}

#[test]
fn a_run_processed_twice_gives_identical_files() {
    let tmp = tempfile::tempdir().unwrap();
    let run = simulated_run(tmp.path(), 71, &["--duration-s", "600"]);
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    unz_ok(&["run", run.to_str().unwrap(), "--out", a.to_str().unwrap()]);
    for stage in [
        "ingest", "derive", "navigate", "criteria", "disupt", "export", "review",
    ] {
        unz_ok(&[stage, run.to_str().unwrap(), "--out", b.to_str().unwrap()]);
    }
    let fa = same_files(&a.join("sim-0071"), &b.join("sim-0071"), "sim-0071");
    assert!(fa.len() >= 26, "{fa:?}");
    // Every file, the Rerun recording and the review's stage record (which hashes it)
    // included: rerun's time-based ids, its batching and its footer's hash-map orders are
    // made fixed as the recording is written (`viz/src/rrd_sink.rs`).
    assert!(
        fa.iter().any(|f| f == Path::new("review/sim-0071.rrd")),
        "{fa:?}"
    );
}

/// The stage records name a run's own files relative to its folder, and the outputs
/// relative to the output folder: a campaign run again from another working directory,
/// or moved with its output folder, is taken from the cache whole and its files stay
/// byte-identical; and a run given as its `run.toml` from inside its folder is ingested
/// (the manifest's folder is then `.`).
#[test]
fn a_campaign_run_from_elsewhere_or_moved_is_taken_from_the_cache() {
    let tmp = tempfile::tempdir().unwrap();
    let first = tmp.path().join("first");
    std::fs::create_dir_all(first.join("sub")).unwrap();
    unz_ok(&[
        "simulate",
        "--out",
        first.join("c").to_str().unwrap(),
        "--seed",
        "72",
        "--runs",
        "2",
        "--duration-s",
        "300",
    ]);
    let run_in = |cwd: &Path, args: &[&str]| -> String {
        let out = unz().current_dir(cwd).args(args).output().unwrap();
        let (stdout, stderr) = (
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        );
        assert!(
            out.status.success(),
            "unz {args:?} in {cwd:?}:\n{stdout}\n{stderr}"
        );
        stdout
    };
    let summary = run_in(&first, &["run", "c", "--out", "o"]);
    assert!(summary.contains("2 ok (0 fully cached)"), "{summary}");
    let snapshot = |root: &Path| -> Vec<(PathBuf, Vec<u8>)> {
        files(root)
            .into_iter()
            // The summary holds the wall times and the hash memo file identities.
            .filter(|f| f.starts_with("sim-0072") || f.starts_with("sim-0073"))
            .map(|f| {
                let bytes = std::fs::read(root.join(&f)).unwrap();
                (f, bytes)
            })
            .collect()
    };
    let before = snapshot(&first.join("o"));
    assert!(before.len() >= 50, "{:?}", before.len());

    let again = run_in(&first.join("sub"), &["run", "../c", "--out", "../o"]);
    assert!(again.contains("2 ok (2 fully cached)"), "{again}");
    let moved = tmp.path().join("moved");
    std::fs::rename(&first, &moved).unwrap();
    let again = unz_ok(&[
        "run",
        moved.join("c").to_str().unwrap(),
        "--out",
        moved.join("o").to_str().unwrap(),
    ]);
    assert!(again.contains("2 ok (2 fully cached)"), "{again}");
    assert!(before == snapshot(&moved.join("o")), "a file changed");

    // From inside the run folder, by its manifest's bare name: the same ingest, which a
    // later run of the campaign takes from the cache.
    let run = moved.join("c/sim-0072");
    let elsewhere = tmp.path().join("o2");
    run_in(
        &run,
        &["ingest", "run.toml", "--out", elsewhere.to_str().unwrap()],
    );
    let ingest = |root: &Path| std::fs::read(root.join("sim-0072/ingest/ingest_events.json"));
    assert_eq!(
        ingest(&elsewhere).unwrap(),
        ingest(&moved.join("o")).unwrap()
    );
    let stderr = String::from_utf8(
        unz()
            .args([
                "derive",
                run.to_str().unwrap(),
                "--out",
                elsewhere.to_str().unwrap(),
            ])
            .output()
            .unwrap()
            .stderr,
    )
    .unwrap();
    assert!(stderr.contains("ingest: up to date, skipped"), "{stderr}");
}

/// A run processed in a campaign of several (whose runs share the cores: the disupt
/// stage then orders its review passes for the least CPU, in one batch of lanes) gives
/// the files it gives processed alone (its review passes ordered for the shortest time,
/// in two batches), byte for byte: a run whose heights refuse an odometer pitch
/// boresight and one that takes it (its probe pass and the kept track's heights).
#[test]
fn a_run_in_a_campaign_of_several_gives_the_files_it_gives_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let c = tmp.path().join("c");
    unz_ok(&[
        "simulate",
        "--out",
        c.to_str().unwrap(),
        "--seed",
        "75",
        "--runs",
        "2",
        "--duration-s",
        "600",
    ]);
    let (shared, own) = (tmp.path().join("shared"), tmp.path().join("own"));
    let summary = unz_ok(&[
        "run",
        c.to_str().unwrap(),
        "--out",
        shared.to_str().unwrap(),
    ]);
    assert!(summary.contains("2 ok (0 fully cached)"), "{summary}");
    let mut boresights = 0;
    for run in ["sim-0075", "sim-0076"] {
        unz_ok(&[
            "run",
            c.join(run).to_str().unwrap(),
            "--out",
            own.to_str().unwrap(),
        ]);
        let (a, b) = (shared.join(run), own.join(run));
        // The joint fit ran: its review pass is the one the two orders place apart.
        let report: serde_json::Value = crate::util::read_json(&a.join("disupt/disupt.json"));
        assert!(report["methods"]["joint"].is_object(), "{report}");
        boresights += usize::from(report["odo_pitch"]["applied"] == true);
        same_files(&a, &b, run);
    }
    assert_eq!(boresights, 1, "one run of the two takes its boresight");
}
