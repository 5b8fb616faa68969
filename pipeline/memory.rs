//! The process's memory: its allocator's arenas, and its resident set for the stages'
//! verbose phase logs.

/// Asks glibc's allocator for one arena shared by all threads, instead of up to eight per
/// core. Call it first thing in `main`, before any thread starts. Returns whether the
/// setting took (`false` on other C libraries, where there is nothing to set).
///
/// Why: glibc gives a thread its own arena when it finds the main one locked, and keeps
/// what is freed there for that arena's later use. The stages allocate run-length
/// vectors on the worker threads and free them on others, so at 12 h the resident set
/// stood 55–65 MiB above the heap's peak. With one arena it stands about 15–20 MiB lower,
/// and the campaign benchmark (2 threads, several stages allocating at once) runs no
/// slower: the hot loops allocate nothing.
pub fn one_malloc_arena() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: `mallopt` takes no pointers; it sets one parameter of glibc's allocator
        // under the allocator's own lock (mallopt(3)). M_ARENA_MAX only caps how many
        // arenas glibc creates from then on, so calling it from any thread is sound.
        #[allow(unsafe_code)]
        let ok = unsafe { libc::mallopt(libc::M_ARENA_MAX, 1) };
        ok == 1
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

/// Resident set size now and its peak so far, MB (Linux's `/proc/self/status`; `None`
/// elsewhere or when unreadable).
pub fn rss_mb() -> Option<(f64, f64)> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let kb = |key: &str| -> Option<f64> {
        let line = status.lines().find(|l| l.starts_with(key))?;
        line[key.len()..]
            .trim()
            .trim_end_matches("kB")
            .trim()
            .parse()
            .ok()
    };
    Some((kb("VmRSS:")? / 1024.0, kb("VmHWM:")? / 1024.0))
}

/// `" (RSS 123 MB, peak 456 MB)"`, or nothing where [`rss_mb`] has no answer.
pub fn rss_suffix() -> String {
    rss_mb().map_or_else(String::new, |(now, peak)| {
        format!(" (RSS {now:.0} MB, peak {peak:.0} MB)")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glibc_takes_the_one_arena_setting() {
        assert_eq!(
            one_malloc_arena(),
            cfg!(all(target_os = "linux", target_env = "gnu"))
        );
    }

    #[test]
    fn rss_is_positive_and_below_its_peak_on_linux() {
        if cfg!(target_os = "linux") {
            let (now, peak) = rss_mb().expect("/proc/self/status");
            assert!(now > 0.0 && now <= peak, "{now} {peak}");
        }
    }
}
