//! Any text as a KF-GINS log and its odometer (`common/kfgins_run.rs`), ingested and
//! derived by the pipeline itself: an error or a derive, never a panic or a hang
//! (libFuzzer's `-timeout`).
#![no_main]

#[path = "common/kfgins_run.rs"]
mod kfgins_run;

use libfuzzer_sys::fuzz_target;
use unz::flow::{RunCtx, ensure_derive};
use unz::runs::load_run;

fuzz_target!(|data: &[u8]| {
    let Some((run, out)) = kfgins_run::write_run(data, false) else {
        return;
    };
    let ctx = RunCtx::new(load_run(&run).unwrap(), out, false);
    let params = unz::config::for_run(&toml::Table::new(), &ctx.manifest).unwrap();
    let _ = ensure_derive(&ctx, &params);
});
