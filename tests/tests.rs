//! End-to-end tests of the `unz` binary. One module per area.

mod axes;
mod campaign;
mod cli;
mod damaged;
mod disupt;
mod estimation;
mod hostile;
mod ingest;
mod kill;
mod kingston;
mod reproducible;
mod review;
mod util;
