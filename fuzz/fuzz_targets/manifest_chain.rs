//! Any text as a run's manifest, its site, settings, control points and `[params]`, with
//! an UNZ-50 log (`common/unz50_run.rs`), through every stage as a campaign runs them
//! (ingest to review): an error naming the manifest or the run's outputs, never a panic
//! or a hang (libFuzzer's `-timeout`), and no file read or written outside the run's
//! folder and its output folder.
//!
//! The input up to its first NUL byte is the manifest; the rest, the log's operations.
//! The stages are called directly, not through the campaign, whose guard would turn a
//! panic into the run's error.
#![no_main]

#[path = "common/every_stage.rs"]
mod every_stage;

#[path = "common/unz50_run.rs"]
mod unz50_run;

use libfuzzer_sys::fuzz_target;
use unz::flow::RunCtx;
use unz::runs::load_run;

fuzz_target!(|data: &[u8]| {
    let (manifest, ops) = match data.iter().position(|&b| b == 0) {
        Some(k) => (&data[..k], &data[k + 1..]),
        None => (data, &[][..]),
    };
    let (run, out) = unz50_run::write_run_with(ops, manifest);
    let Ok(m) = load_run(&run) else {
        return;
    };
    // What the manifest names stays in its folder.
    assert!(m.raw.starts_with(&run), "{}", m.raw.display());
    assert!((m.odometer.file.as_ref()).is_none_or(|f| f.starts_with(&run)));
    let ctx = RunCtx::new(m, out.clone(), false);
    let Ok(p) = unz::config::for_run(&toml::Table::new(), &ctx.manifest) else {
        return;
    };
    let _ = every_stage::run(&ctx, &p);
    // Whatever the run's name, its outputs are in the output folder: the scratch folder
    // holds the run's and the output's folders only, and the run's folder what was
    // written into it.
    let scratch = run.parent().unwrap();
    for entry in std::fs::read_dir(scratch).unwrap().flatten() {
        let path = entry.path();
        assert!(path == run || path == out, "{} written", path.display());
    }
    for entry in std::fs::read_dir(&run).unwrap().flatten() {
        let name = entry.file_name();
        assert!(name == "run.unz" || name == "run.toml", "{name:?} written");
    }
});
