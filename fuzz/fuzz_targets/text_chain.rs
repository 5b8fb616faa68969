//! Any text as a KF-GINS log and its odometer (`common/kfgins_run.rs`), with a control
//! point, through every stage as a campaign runs them (ingest to review, the DISUPT
//! methods on whatever the log holds): an error or the run's outputs, never a panic or a
//! hang (libFuzzer's `-timeout`). The stages are called directly, not through the
//! campaign, whose guard would turn a panic into the run's error.
#![no_main]

#[path = "common/every_stage.rs"]
mod every_stage;

#[path = "common/kfgins_run.rs"]
mod kfgins_run;

use libfuzzer_sys::fuzz_target;
use unz::flow::RunCtx;
use unz::runs::load_run;

fuzz_target!(|data: &[u8]| {
    let Some((run, out)) = kfgins_run::write_run(data, true) else {
        return;
    };
    let ctx = RunCtx::new(load_run(&run).unwrap(), out, false);
    let p = &unz::config::for_run(&toml::Table::new(), &ctx.manifest).unwrap();
    let _ = every_stage::run(&ctx, p);
});
