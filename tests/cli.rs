//! Command-line behaviour: help, bad arguments, unreadable inputs.

use crate::util::{unz_ok, unz_output};

#[test]
fn help_lists_the_commands() {
    let help = unz_ok(&["--help"]);
    for cmd in ["simulate", "ingest", "demo", "bench"] {
        assert!(help.contains(cmd), "{help}");
    }
}

#[test]
fn a_missing_run_is_a_clear_error() {
    let out = unz_output(&["ingest", "/nonexistent/run", "--out", "/tmp/x"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/nonexistent/run"), "{err}");
}

#[test]
fn a_broken_manifest_names_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("run.toml"),
        "name = \"r\"\nraw = \"r.unz\"\nformat = \"unz-binary\"\nsurprise = 1\n",
    )
    .unwrap();
    let out = unz_output(&[
        "ingest",
        dir.path().to_str().unwrap(),
        "--out",
        dir.path().join("o").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("line 4") && err.contains("run.toml") && err.contains("surprise"),
        "{err}"
    );
}

#[test]
fn an_unreadable_raw_log_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let m = "name = \"r\"\nraw = \"r.unz\"\nformat = \"unz-binary\"\n[site]\nlatitude_deg = 1.0\nlongitude_deg = 2.0\nheight_m = 3.0\n";
    std::fs::write(dir.path().join("run.toml"), m).unwrap();
    std::fs::write(dir.path().join("r.unz"), b"NOTAUNZFILE").unwrap();
    let out = unz_output(&[
        "ingest",
        dir.path().to_str().unwrap(),
        "--out",
        dir.path().join("o").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("r.unz") && err.contains("header"), "{err}");
    // No half-written output is left under a final name.
    let ingest_dir = dir.path().join("o/r/ingest");
    let finals: Vec<_> = std::fs::read_dir(&ingest_dir)
        .map(|d| d.filter_map(Result::ok).map(|e| e.file_name()).collect())
        .unwrap_or_default();
    assert!(finals.is_empty(), "{finals:?}");
}

#[test]
fn config_show_prints_the_effective_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("unz.toml");
    std::fs::write(&cfg, "[derive.filter]\ncutoff_hz = 0.25\n").unwrap();
    let shown = unz_ok(&["config", "--show", "--config", cfg.to_str().unwrap()]);
    let t: toml::Table = toml::from_str(&shown).unwrap();
    assert_eq!(t["derive"]["filter"]["cutoff_hz"].as_float(), Some(0.25));
    assert!(
        t["kalman"]["r_rad"].as_float().is_some(),
        "defaults are filled in: {shown}"
    );
    assert_eq!(
        t["ingest"]["raw_mcap_compression"].as_str(),
        Some("none"),
        "{shown}"
    );
    assert_eq!(
        t["export"]["mcap_compression"].as_str(),
        Some("lz4"),
        "{shown}"
    );
    std::fs::write(&cfg, "[ingest]\nraw_mcap_compression = \"zstd\"\n").unwrap();
    let shown = unz_ok(&["config", "--show", "--config", cfg.to_str().unwrap()]);
    let t: toml::Table = toml::from_str(&shown).unwrap();
    assert_eq!(t["ingest"]["raw_mcap_compression"].as_str(), Some("zstd"));
    std::fs::write(&cfg, "[ingest]\nraw_mcap_compression = \"lzma\"\n").unwrap();
    let out = unz_output(&["config", "--show", "--config", cfg.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("lzma"));
    std::fs::write(&cfg, "[derive]\nsurprise = 1\n").unwrap();
    let out = unz_output(&["config", "--show", "--config", cfg.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("surprise"));
}
