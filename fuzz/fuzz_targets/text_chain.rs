//! Any text as a KF-GINS log and its odometer (`common/kfgins_run.rs`), with a control
//! point, through every stage as a campaign runs them (ingest to review, the DISUPT
//! methods on whatever the log holds): an error or the run's outputs, never a panic or a
//! hang (libFuzzer's `-timeout`). The stages are called directly, not through the
//! campaign, whose guard would turn a panic into the run's error.
#![no_main]

#[path = "common/kfgins_run.rs"]
mod kfgins_run;

use libfuzzer_sys::fuzz_target;
use unz::disupt_stage::{Method, ensure_disupt};
use unz::flow::{
    Overrides, RunCtx, ensure_criteria, ensure_derive, ensure_ingest_before_derive, ensure_navigate,
};
use unz::runs::load_run;

fuzz_target!(|data: &[u8]| {
    let Some((run, out)) = kfgins_run::write_run(data, true) else {
        return;
    };
    let ctx = RunCtx::new(load_run(&run).unwrap(), out, false);
    let p = &unz::config::for_run(&toml::Table::new(), &ctx.manifest).unwrap();
    let none = Overrides::default();
    let _ = (|| -> anyhow::Result<()> {
        ensure_ingest_before_derive(&ctx, p)?;
        ensure_derive(&ctx, p)?;
        ensure_navigate(&ctx, p, &none)?;
        ensure_criteria(&ctx, p, &none)?;
        ensure_disupt(&ctx, p, Method::All)?;
        unz::export::ensure_export(&ctx, p)?;
        unz::review::ensure_review(&ctx, p)?;
        Ok(())
    })();
});
