//! Helpers shared by the end-to-end tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use unz_formats::raw::{Accepted, FileHeader, ImuRecord, MarkRecord, RawReader, RawWriter};

/// The `unz` binary under test.
pub fn unz() -> Command {
    Command::new(env!("CARGO_BIN_EXE_unz"))
}

/// Runs `unz` with `args`, asserting success; returns stdout.
pub fn unz_ok(args: &[&str]) -> String {
    let out = unz().args(args).output().expect("unz runs");
    assert!(
        out.status.success(),
        "unz {args:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Simulates the run of `seed` (with `options` for `unz simulate`) into `dir/c/`; returns
/// its folder.
pub fn simulated_run(dir: &Path, seed: u32, options: &[&str]) -> PathBuf {
    let campaign = dir.join("c");
    let seed_arg = seed.to_string();
    let mut args = vec![
        "simulate",
        "--out",
        campaign.to_str().unwrap(),
        "--seed",
        &seed_arg,
    ];
    args.extend_from_slice(options);
    unz_ok(&args);
    campaign.join(format!("sim-{seed:04}"))
}

/// The rows of a Parquet file (from its footer).
pub fn parquet_rows(path: &Path) -> i64 {
    use parquet::file::reader::{FileReader, SerializedFileReader};
    let f = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    SerializedFileReader::new(f)
        .unwrap()
        .metadata()
        .file_metadata()
        .num_rows()
}

/// A JSON artifact read back through its one typed definition (the type the pipeline
/// writes it with); a missing or mistyped field fails the test here.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> T {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_slice(&bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Runs `unz` with `args`, returning the whole output.
pub fn unz_output(args: &[&str]) -> Output {
    unz().args(args).output().expect("unz runs")
}

/// A real data set shipped with the tests (`tests/data/<name>`; see its README for the
/// source and licence). No test reads outside the repository.
pub fn test_data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("data")
        .join(name)
}

/// Python with pyarrow, mcap and rerun-sdk: `UNZ_PYTHON` (set by scripts/test.sh) or `python3`.
/// Missing readers fail the test with instructions, unless `UNZ_SKIP_PYTHON=1`.
pub fn python() -> Option<String> {
    if std::env::var("UNZ_SKIP_PYTHON").as_deref() == Ok("1") {
        eprintln!("UNZ_SKIP_PYTHON=1: third-party cross-checks skipped");
        return None;
    }
    let py = std::env::var("UNZ_PYTHON").unwrap_or_else(|_| "python3".into());
    let ok = Command::new(&py)
        .args([
            "-c",
            "import pyarrow, mcap, mcap_ros2, rerun, duckdb, websocket",
        ])
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        ok,
        "{py} lacks pyarrow/mcap/mcap-ros2-support/rerun-sdk/duckdb/websocket-client: run the tests through scripts/test.sh (it installs them), or set UNZ_SKIP_PYTHON=1"
    );
    Some(py)
}

/// Runs a Python script from tests/python and parses its JSON output.
pub fn python_json(py: &str, script: &str, args: &[&Path]) -> serde_json::Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("python")
        .join(script);
    let out = Command::new(py)
        .arg(path)
        .args(args)
        .output()
        .expect("python runs");
    assert!(
        out.status.success(),
        "{script} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("script prints JSON")
}

/// `unz run RUN --out OUT --until STAGE`, asserting success.
pub fn run_until(run: &Path, out: &Path, stage: &str) {
    run_until_with(run, out, stage, &[]);
}

/// [`run_until`] with `extra` arguments (`--config FILE`, say).
pub fn run_until_with(run: &Path, out: &Path, stage: &str, extra: &[&str]) {
    let mut args = vec![
        "run",
        run.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--until",
        stage,
    ];
    args.extend_from_slice(extra);
    unz_ok(&args);
}

/// Runs `unz STAGE RUN --out OUT`, which must fail: its standard error.
pub fn stage_fails(stage: &str, run: &Path, out: &Path) -> String {
    let o = unz_output(&[stage, run.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "unz {stage} succeeded: {err}");
    err
}

/// The offset a failed derive names for the odometer's time tags: "Set [derive]
/// odo_time_offset_s = V (in …".
pub fn named_offset_s(err: &str) -> f64 {
    number_after(err, "Set [derive] odo_time_offset_s = ")
}

/// The number that follows `key` in the message `err`.
pub fn number_after(err: &str, key: &str) -> f64 {
    let at = err
        .find(key)
        .unwrap_or_else(|| panic!("no {key:?} in: {err}"));
    let value = err[at + key.len()..]
        .split_whitespace()
        .next()
        .unwrap_or("");
    value
        .parse()
        .unwrap_or_else(|_| panic!("no number after {key:?} in: {err}"))
}

/// Every file below `root`, relative to it, sorted.
pub fn files_below(root: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(root).unwrap().to_path_buf());
            }
        }
    }
    out.sort();
    out
}

/// A raw log: its header, IMU records, and marks with the IMU record they precede.
#[derive(Clone)]
pub struct Log {
    /// The file header.
    pub header: FileHeader,
    /// IMU records, in order.
    pub imu: Vec<ImuRecord>,
    /// Marks, each with the index of the IMU record it precedes.
    pub marks: Vec<(usize, MarkRecord)>,
}

impl Log {
    /// Adds `mark` before the first IMU record not earlier than it.
    pub fn insert_mark(&mut self, mark: MarkRecord) {
        let at = self.imu.partition_point(|r| r.t_us < mark.t_us);
        let after = self.marks.partition_point(|(k, _)| *k <= at);
        self.marks.insert(after, (at, mark));
    }
}

/// Reads the raw log at `path` (records the reader rejects are left out).
pub fn read_log(path: &Path) -> Log {
    let bytes = std::fs::read(path).unwrap();
    let mut reader = RawReader::new(bytes.as_slice()).unwrap();
    let header = reader.header().clone();
    let (mut imu, mut marks) = (Vec::new(), Vec::new());
    while let Some(rec) = reader.next_record().unwrap() {
        match rec {
            Accepted::Imu(s) => imu.push(s.raw),
            Accepted::Mark(m) => marks.push((imu.len(), m.raw)),
        }
    }
    Log { header, imu, marks }
}

/// Writes `log` to `path`, each mark before the IMU record it precedes.
pub fn write_log(path: &Path, log: &Log) {
    let mut w = RawWriter::new(Vec::new(), &log.header).unwrap();
    let mut marks = log.marks.iter().peekable();
    for (k, r) in log.imu.iter().enumerate() {
        while let Some((_, m)) = marks.next_if(|(at, _)| *at <= k) {
            w.write_mark(m).unwrap();
        }
        w.write_imu(r).unwrap();
    }
    for (_, m) in marks {
        w.write_mark(m).unwrap();
    }
    std::fs::write(path, w.finish().unwrap()).unwrap();
}

/// Holds the odometer's count on samples `[k0, k0 + len)` of the raw log at `raw` (the
/// counts after them short by what was driven meanwhile), flagging them failed if
/// `flagged` (status bit 1); unflagged, the count stops as a broken wheel sensor's does.
pub fn hold_count(raw: &Path, k0: usize, len: usize, flagged: bool) {
    let mut log = read_log(raw);
    let held = log.imu[k0].odo_count;
    let missed = log.imu[k0 + len].odo_count.wrapping_sub(held);
    for (k, x) in log.imu.iter_mut().enumerate().skip(k0) {
        if k < k0 + len {
            x.odo_count = held;
            if flagged {
                x.status |= 2;
            }
        } else {
            x.odo_count = x.odo_count.wrapping_sub(missed);
        }
    }
    write_log(raw, &log);
}

/// The `[vehicle]` settings a failure message `err` names ("set [vehicle] imu_axes =
/// "FDL" and [vehicle] imu_mounting_deg = [a, b, c]"), as TOML lines for a run's
/// `[params.vehicle]`.
pub fn vehicle_settings_named(err: &str) -> String {
    let setting = |key: &str| {
        let at = err.find(&format!("[vehicle] {key} = "))? + "[vehicle] ".len() + key.len() + 3;
        let end = if key == "imu_axes" {
            at + 1 + err[at + 1..].find('"')? + 1
        } else {
            at + err[at..].find(']')? + 1
        };
        Some(format!("{key} = {}\n", &err[at..end]))
    };
    ["imu_axes", "imu_mounting_deg"]
        .iter()
        .filter_map(|k| setting(k))
        .collect()
}

/// Every message of an MCAP file: (topic, log time, data), in file order, read with the
/// mcap crate's own reader (chunk CRCs checked).
pub fn mcap_messages(path: &Path) -> Vec<(String, u64, Vec<u8>)> {
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (m.channel.topic.clone(), m.log_time, m.data.into_owned())
        })
        .collect()
}

/// The chunks' compression names of an MCAP file.
pub fn mcap_chunk_compressions(path: &Path) -> Vec<String> {
    let bytes = std::fs::read(path).unwrap();
    mcap::read::LinearReader::new(&bytes)
        .unwrap()
        .filter_map(|r| match r.unwrap() {
            mcap::records::Record::Chunk { header, .. } => Some(header.compression),
            _ => None,
        })
        .collect()
}
