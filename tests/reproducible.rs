//! The same input gives the same files: one run processed twice, into two output
//! folders, compared byte for byte — once by `unz run` in one process (the stages hand
//! the derive on in memory), once stage by stage in a process each (every stage loads
//! its inputs from the cache).

use std::path::Path;

use crate::util::{files_below as files, simulated_run, unz_ok};

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
    let (fa, fb) = (files(&a.join("sim-0071")), files(&b.join("sim-0071")));
    assert_eq!(fa, fb);
    assert!(fa.len() >= 26, "{fa:?}");
    // Every file, the Rerun recording and the review's stage record (which hashes it)
    // included: rerun's time-based ids, its batching and its footer's hash-map orders are
    // made fixed as the recording is written (`viz/src/rrd_sink.rs`).
    assert!(
        fa.iter().any(|f| f == Path::new("review/sim-0071.rrd")),
        "{fa:?}"
    );
    for f in &fa {
        let (x, y) = (
            std::fs::read(a.join("sim-0071").join(f)).unwrap(),
            std::fs::read(b.join("sim-0071").join(f)).unwrap(),
        );
        assert!(x == y, "{} differs between the two", f.display());
    }
}
