//! A stage's input files asked into the page cache before its readers take them.
//!
//! A stage reads its inputs one reader at a time per thread, and a page the kernel no
//! longer holds (evicted since the earlier stage wrote it: on this VM, a few seconds of
//! other work are enough for some) stops that reader for a disk read (4–5 ms measured in
//! the disupt stage's load, perf `sched:sched_switch`). Asking for all of them first lets
//! the kernel read them at once, in the background, while the stage starts.

use std::path::PathBuf;

/// Asks the kernel to read `paths` ahead (`posix_fadvise(WILLNEED)`), without waiting.
/// A file that cannot be opened or advised is left to its reader, which reports it.
pub fn read_ahead(paths: &[PathBuf]) {
    for path in paths {
        if let Ok(file) = unz_formats::regular::open_regular(path) {
            let _ = rustix::fs::fadvise(&file, 0, None, rustix::fs::Advice::WillNeed);
        }
    }
}
