//! Any sequence of UNZ-50 records (`common/unz50_run.rs`) ingested and derived by the
//! pipeline itself: an error or a derive, never a panic or a hang (libFuzzer's
//! `-timeout`).
#![no_main]

#[path = "common/unz50_run.rs"]
mod unz50_run;

use libfuzzer_sys::fuzz_target;
use unz::flow::{RunCtx, ensure_derive};
use unz::runs::load_run;

fuzz_target!(|data: &[u8]| {
    let (run, out) = unz50_run::write_run(data);
    let ctx = RunCtx::new(load_run(&run).unwrap(), out, false);
    let params = unz::config::for_run(&toml::Table::new(), &ctx.manifest).unwrap();
    let _ = ensure_derive(&ctx, &params);
});
