//! End-to-end tests of the `unz` binary. One module per area.

mod cli;
mod disupt;
mod ingest;
mod kingston;
mod util;
