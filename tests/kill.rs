//! A campaign killed with SIGKILL at several points, then re-run, ends with the same files
//! as an uninterrupted run, byte for byte (the Rerun recordings included), and no temporary
//! file left over. The campaign summaries (wall times, what was computed) are not compared.

use std::path::Path;
use std::time::Duration;

use crate::util::{files_below as files, unz, unz_ok};

#[test]
fn kill_9_then_rerun_gives_the_same_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = tmp.path().join("campaign");
    unz_ok(&[
        "simulate",
        "--out",
        camp.to_str().unwrap(),
        "--seed",
        "90",
        "--runs",
        "3",
        "--duration-s",
        "400",
    ]);
    // `unz run CAMPAIGN --out OUT --jobs 1`.
    let run_args = |out: &Path| -> Vec<String> {
        [
            "run",
            camp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--jobs",
            "1",
        ]
        .map(str::to_owned)
        .to_vec()
    };
    let reference = tmp.path().join("reference");
    unz_ok(
        &run_args(&reference)
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );

    let out = tmp.path().join("killed");
    for delay_ms in [150, 400, 900, 1600] {
        let mut child = unz()
            .args(run_args(&out))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(delay_ms));
        child.kill().unwrap(); // SIGKILL
        child.wait().unwrap();
    }
    // What a kill while the campaign summary or the saved hashes are being written leaves
    // (the delays above catch those moments only sometimes).
    std::fs::write(out.join(".campaign.md.Kd9x2Q.tmp"), b"| run |").unwrap();
    std::fs::write(out.join(".unz.hashes.eKdhjq.tmp"), b"{\"version\":1").unwrap();
    unz_ok(
        &run_args(&out)
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );

    let (a, b) = (files(&reference), files(&out));
    let leftovers: Vec<_> = b
        .iter()
        .filter(|p| p.to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    assert_eq!(a, b, "the same files");
    // The campaign summaries hold wall times; the lock file holds the process's pid; the
    // saved hashes name the files' inodes and times.
    for f in a.iter().filter(|f| {
        let name = f.to_string_lossy();
        !name.starts_with("campaign.") && name != "unz.lock" && name != "unz.hashes"
    }) {
        assert!(
            std::fs::read(reference.join(f)).unwrap() == std::fs::read(out.join(f)).unwrap(),
            "{} differs",
            f.display()
        );
    }
}
