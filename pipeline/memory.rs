//! The process's memory: its allocator's arenas, and its resident set for the stages'
//! verbose phase logs.

/// Asks glibc's allocator for one arena shared by all threads, instead of up to eight per
/// core, for a process that works on one run at a time. Call it before the process's
/// worker threads start: a thread keeps the arena it first took. Returns whether the
/// setting took (`false` on other C libraries, where there is nothing to set).
///
/// Why: glibc gives a thread its own arena when it finds the main one locked, and keeps
/// what is freed there for that arena's later use. A run's stages allocate run-length
/// vectors on the worker threads and free them on others: one 12-h run's resident set
/// stood 55–65 MiB above its heap's peak, and comes about 20 MiB lower with one arena
/// (4 h: 205 → 179 MiB), at the same speed. Not for campaigns that work on several
/// runs at once: their threads then wait on the one arena's lock (`unz bench campaign`
/// ran about 12 % slower).
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

/// Blocks up to this size come from glibc's heap, not mappings of their own
/// ([`keep_freed_memory`]), bytes.
const MMAP_THRESHOLD_BYTES: i32 = 32 << 20;

/// Free memory at the top of glibc's heap kept rather than given back to the kernel
/// ([`keep_freed_memory`]), bytes.
const TRIM_THRESHOLD_BYTES: i32 = 256 << 20;

/// Asks glibc's allocator to keep what the process frees for its own later use: blocks
/// up to 32 MiB from its heap (not each in a mapping of its own, unmapped when freed),
/// and up to 256 MiB free at the heap's top (not given back to the kernel). For a
/// process whose heap is in huge pages ([`with_huge_pages`]), before its threads start.
/// Returns whether the settings took (`false` on other C libraries).
///
/// Why: the kernel zeroes a whole 2-MiB page on its first touch, so memory given back
/// and taken again is zeroed again; glibc by default maps blocks from 128 KiB up apart
/// (the run's columns, the encoders' buffers) and unmaps them when freed. A 40-minute
/// disupt process took 2 960 page faults, 1 000–1 300 with these settings, and the whole
/// process 166.7 → 161.8 ms (medians of 10, alternately); a 4-hour `unz run` 3.35–3.75
/// → 3.03–3.07 s; a 12-hour one's peak 435 → 445–447 MiB (466–469 MB). With 4-KiB pages
/// they changed nothing measurable (session 41).
pub fn keep_freed_memory() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: `mallopt` takes no pointers; it sets parameters of glibc's allocator
        // under the allocator's own lock (mallopt(3)), which apply to what is allocated
        // and freed from then on.
        #[allow(unsafe_code)]
        let ok = unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1
                && libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES) == 1
        };
        ok
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

/// The environment variable glibc reads its tunables from at start-up.
const GLIBC_TUNABLES: &str = "GLIBC_TUNABLES";

/// glibc's tunable for backing its heap by transparent huge pages (glibc 2.35 on).
const HUGETLB_TUNABLE: &str = "glibc.malloc.hugetlb";

/// Runs this program again, the same arguments and environment, with glibc's allocator
/// told to back its heap by transparent huge pages (`glibc.malloc.hugetlb=1` added to
/// `GLIBC_TUNABLES`, which glibc reads only as a process starts): for a process that
/// works on one run. Returns only when it does not: another C library, the tunable
/// already set (either way: `GLIBC_TUNABLES=glibc.malloc.hugetlb=0` keeps 4-KiB pages),
/// the kernel without transparent huge pages, or the exec failed. Call it first thing,
/// before any thread, lock or file is taken.
///
/// Why: such a process fills vectors of its run's length that it has just allocated (the
/// derive's increments, the passes' series, the tables' column buffers), and every 4-KiB
/// page costs a page fault on first touch. A 40-minute disupt process took 14 200 of
/// them, 3 200 with the tunable, and its `written` lap 181 → 171 ms (medians of 12,
/// alternately; docs/performance.md, session 43); a 12-hour `unz run` keeps its peak
/// (432–437 MiB). Starting again costs about 2 ms. A campaign's process reuses its heap
/// run after run (no gain measured): it is not started again.
pub fn with_huge_pages() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        use std::os::unix::process::CommandExt;
        let tunables = match std::env::var(GLIBC_TUNABLES) {
            Ok(t) if t.contains(HUGETLB_TUNABLE) => return,
            Ok(t) if !t.is_empty() => format!("{t}:{HUGETLB_TUNABLE}=1"),
            Ok(_) | Err(std::env::VarError::NotPresent) => format!("{HUGETLB_TUNABLE}=1"),
            // Not UTF-8: left as it is.
            Err(std::env::VarError::NotUnicode(_)) => return,
        };
        let Ok(exe) = std::env::current_exe() else {
            return;
        };
        if !transparent_huge_pages() {
            return;
        }
        let mut args = std::env::args_os();
        let mut command = std::process::Command::new(exe);
        if let Some(arg0) = args.next() {
            command.arg0(arg0);
        }
        // Only returns on failure; the process then goes on as it is.
        let _ = command.args(args).env(GLIBC_TUNABLES, tunables).exec();
    }
}

/// Whether the kernel backs memory by transparent huge pages when asked
/// (`/sys/kernel/mm/transparent_hugepage/enabled` is `always` or `madvise`).
pub fn transparent_huge_pages() -> bool {
    std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled")
        .is_ok_and(|s| s.contains("[always]") || s.contains("[madvise]"))
}

/// Whether this process's heap is in transparent huge pages ([`with_huge_pages`]): glibc
/// told so by `GLIBC_TUNABLES`, the kernel willing.
pub fn heap_in_huge_pages() -> bool {
    cfg!(all(target_os = "linux", target_env = "gnu"))
        && std::env::var(GLIBC_TUNABLES)
            .is_ok_and(|t| t.split(':').any(|kv| kv == format!("{HUGETLB_TUNABLE}=1")))
        && transparent_huge_pages()
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
    fn glibc_takes_the_settings_that_keep_freed_memory() {
        assert_eq!(
            keep_freed_memory(),
            cfg!(all(target_os = "linux", target_env = "gnu"))
        );
    }

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
