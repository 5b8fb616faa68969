//! Every stage of a run, ingest to review, as a campaign runs them (the DISUPT methods on
//! whatever the log holds), called directly: the campaign's guard would turn a panic
//! into the run's error.

use unz::disupt_stage::{Method, ensure_disupt};
use unz::flow::{
    Overrides, Params, RunCtx, ensure_criteria, ensure_derive, ensure_ingest_before_derive,
    ensure_navigate,
};

/// Runs every stage of `ctx` with `p`; the first stage's error ends it.
pub fn run(ctx: &RunCtx, p: &Params) -> anyhow::Result<()> {
    let none = Overrides::default();
    ensure_ingest_before_derive(ctx, p)?;
    ensure_derive(ctx, p)?;
    ensure_navigate(ctx, p, &none)?;
    ensure_criteria(ctx, p, &none)?;
    ensure_disupt(ctx, p, Method::All)?;
    unz::export::ensure_export(ctx, p)?;
    unz::review::ensure_review(ctx, p)?;
    Ok(())
}
