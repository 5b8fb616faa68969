//! Rerun review recordings of the pipeline's runs (issue 6: not written yet).
//!
//! This crate is where the `.rrd` recordings will be built from the cached tables; it
//! links rerun 0.36.3 today so that the workspace pins one arrow version (rerun's) and
//! `cargo tree -i arrow-array` shows a single version.
