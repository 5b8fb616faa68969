//! Campaigns: bad runs never stop the others; re-runs are cached; shards partition runs.

use std::collections::BTreeSet;

use crate::util::unz_output;

fn names(md: &str) -> BTreeSet<String> {
    // The runs' table: up to the first blank line (sections follow it).
    md.lines()
        .take_while(|l| !l.is_empty())
        .skip(2)
        .filter_map(|l| l.split('|').nth(1))
        .map(|s| s.trim().to_owned())
        .collect()
}

#[test]
fn a_campaign_survives_a_corrupt_log_and_a_broken_manifest() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = tmp.path().join("campaign");
    let out = tmp.path().join("out");
    let ok = unz_output(&[
        "simulate",
        "--out",
        camp.to_str().unwrap(),
        "--seed",
        "60",
        "--runs",
        "3",
        "--duration-s",
        "300",
    ]);
    assert!(ok.status.success());
    // A log that is garbage from its first byte, and a manifest with an unknown key.
    std::fs::write(
        camp.join("sim-0061/sim-0061.unz"),
        b"this is not a UNZ log at all",
    )
    .unwrap();
    std::fs::create_dir_all(camp.join("broken")).unwrap();
    std::fs::write(
        camp.join("broken/run.toml"),
        "name = \"broken\"\nraw = \"b.unz\"\nformat = \"unz-binary\"\nbogus = 1\n",
    )
    .unwrap();
    let run = unz_output(&[
        "run",
        camp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--until",
        "criteria",
    ]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert_eq!(run.status.code(), Some(1), "{stdout}");
    assert!(stdout.contains("4 runs: 2 ok"), "{stdout}");
    assert!(
        stdout.contains("FAILED sim-0061")
            && stdout.contains("sim-0061.unz")
            && stdout.contains("header"),
        "{stdout}"
    );
    assert!(
        stdout.contains("FAILED broken") && stdout.contains("line 4") && stdout.contains("bogus"),
        "{stdout}"
    );
    for good in ["sim-0060", "sim-0062"] {
        assert!(out.join(good).join("criteria/criteria.json").is_file());
    }
    let md = std::fs::read_to_string(out.join("campaign.md")).unwrap();
    assert_eq!(
        names(&md),
        ["broken", "sim-0060", "sim-0061", "sim-0062"]
            .map(String::from)
            .into()
    );
    // A second run recomputes nothing.
    let again = unz_output(&[
        "run",
        camp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--until",
        "criteria",
    ]);
    assert!(String::from_utf8_lossy(&again.stdout).contains("2 ok (2 fully cached)"));
    // --from forces that stage and those after it, nothing before.
    let forced = unz_output(&[
        "run",
        camp.join("sim-0060").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--from",
        "navigate",
        "--until",
        "criteria",
    ]);
    let log = String::from_utf8_lossy(&forced.stderr);
    assert!(
        log.contains("sim-0060: ingest: up to date")
            && log.contains("sim-0060: derive: up to date"),
        "{log}"
    );
    assert!(
        log.contains("sim-0060: navigate: done") && log.contains("sim-0060: criteria: done"),
        "{log}"
    );
}

#[test]
fn shards_partition_the_campaign() {
    let tmp = tempfile::tempdir().unwrap();
    let camp = tmp.path().join("campaign");
    assert!(
        unz_output(&[
            "simulate",
            "--out",
            camp.to_str().unwrap(),
            "--seed",
            "70",
            "--runs",
            "7",
            "--duration-s",
            "200"
        ])
        .status
        .success()
    );
    let mut union = BTreeSet::new();
    let mut total = 0;
    for i in 0..3 {
        let out = tmp.path().join(format!("out{i}"));
        let r = unz_output(&[
            "run",
            camp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--until",
            "ingest",
            "--shard",
            &format!("{i}/3"),
        ]);
        assert!(r.status.success() || !out.join("campaign.md").exists());
        if let Ok(md) = std::fs::read_to_string(out.join("campaign.md")) {
            let n = names(&md);
            total += n.len();
            union.extend(n);
        }
    }
    assert_eq!(total, 7, "no run twice");
    assert_eq!(union.len(), 7, "every run once");
    // The shard summaries merge into one with every run.
    let outs: Vec<String> = (0..3)
        .map(|i| tmp.path().join(format!("out{i}")))
        .filter(|p| p.join("campaign.parquet").exists())
        .map(|p| p.display().to_string())
        .collect();
    let merged = tmp.path().join("all.parquet");
    let mut args = vec!["campaign", "merge"];
    args.extend(outs.iter().map(String::as_str));
    args.extend(["--into", merged.to_str().unwrap()]);
    let m = unz_output(&args);
    assert!(m.status.success(), "{}", String::from_utf8_lossy(&m.stderr));
    let (_, batches) = unz_formats::parquet_io::read_batches(&merged).unwrap();
    assert_eq!(batches.iter().map(|b| b.num_rows()).sum::<usize>(), 7);
    // Ingested only: nothing to pool, and no settings.
    let pooled = std::fs::read_to_string(tmp.path().join("all.md")).unwrap();
    assert!(
        pooled.contains("nothing: no run's reports show"),
        "{pooled}"
    );
    assert!(!tmp.path().join("all-settings.toml").exists());
    // The README's DuckDB query over the shards' summaries runs as documented.
    if let Some(py) = crate::util::python() {
        let readme =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
        let start = readme.find("```sql\n").expect("README has a SQL example") + 7;
        let sql = &readme[start..start + readme[start..].find("```").unwrap()];
        let glob = tmp.path().join("out*").join("campaign.parquet");
        let sql = sql.replace(
            "/scratch/unz/shard-*/campaign.parquet",
            glob.to_str().unwrap(),
        );
        let file = tmp.path().join("query.sql");
        std::fs::write(&file, sql).unwrap();
        let res = crate::util::python_json(&py, "run_duckdb.py", &[&file]);
        assert_eq!(res["rows"].as_array().unwrap().len(), 7, "{res}");
        assert_eq!(res["columns"][3], "before_m");
    }
    // Merging a shard twice is refused.
    let mut twice = vec![
        "campaign",
        "merge",
        outs[0].as_str(),
        outs[0].as_str(),
        "--into",
    ];
    let other = tmp.path().join("twice.parquet");
    twice.push(other.to_str().unwrap());
    assert!(!unz_output(&twice).status.success());
}

/// Flips one byte in the middle of `path`, in place: same file, same size.
fn flip_middle_byte(path: &std::path::Path) {
    use std::io::{Read, Seek, SeekFrom, Write};
    let mut f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)
        .unwrap();
    let mid = f.metadata().unwrap().len() / 2;
    let mut b = [0u8; 1];
    f.seek(SeekFrom::Start(mid)).unwrap();
    f.read_exact(&mut b).unwrap();
    f.seek(SeekFrom::Start(mid)).unwrap();
    f.write_all(&[!b[0]]).unwrap();
}

#[test]
fn files_changed_in_place_after_a_cached_run_are_read_again() {
    let tmp = tempfile::tempdir().unwrap();
    let run = crate::util::simulated_run(tmp.path(), 64, &["--duration-s", "300"]);
    let out = tmp.path().join("out");
    let until_derive = || {
        let o = unz_output(&[
            "run",
            run.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--until",
            "derive",
        ]);
        assert!(o.status.success(), "{o:?}");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    until_derive();
    // The next process knows every file's hash: the derive's output among them.
    let memo = std::fs::read_to_string(out.join("unz.hashes")).unwrap();
    let derived = out.join("sim-0064/derive/derived.parquet");
    assert!(memo.contains(derived.to_str().unwrap()), "{memo}");
    assert!(until_derive().contains("sim-0064: derive: up to date"));

    // An output changed in place (same inode and size) is found out and made again.
    flip_middle_byte(&derived);
    let log = until_derive();
    assert!(
        log.contains("sim-0064: ingest: up to date") && log.contains("sim-0064: derive: done"),
        "{log}"
    );
    // An archived log changed in place: the ingest runs again.
    flip_middle_byte(&run.join("sim-0064.unz"));
    assert!(until_derive().contains("sim-0064: ingest: done"));
    let log = until_derive();
    assert!(
        log.contains("sim-0064: ingest: up to date")
            && log.contains("sim-0064: derive: up to date"),
        "{log}"
    );
}
