//! The process's memory: its allocator's arenas, and its resident set for the stages'
//! verbose phase logs.

/// The allocator's settings for a process that works on one run at a time, before its
/// worker threads start: one arena ([`one_malloc_arena`]) that keeps what is freed
/// ([`keep_freed_memory`]).
pub fn one_run_at_a_time() {
    one_malloc_arena();
    keep_freed_memory();
}

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

/// How far glibc's heap grows past each request when it must grow
/// ([`keep_freed_memory`]), bytes. Address space only: its pages are faulted in when
/// first written, as before.
const TOP_PAD_BYTES: i32 = 8 << 20;

/// Asks glibc's allocator to keep what the process frees for its own later use: blocks
/// up to 32 MiB from its heap (not each in a mapping of its own, unmapped when freed),
/// and up to 256 MiB free at the heap's top (not given back to the kernel). For a
/// process that works on one run at a time, before its threads start. Returns whether
/// the settings took (`false` on other C libraries).
///
/// Why: glibc by default maps blocks from 128 KiB up apart (a run's columns, the
/// encoders' buffers) and unmaps them when freed, so the next stage's or pass's blocks
/// are new pages again, each zeroed by the kernel on a page fault. A 40-minute disupt
/// process started two seconds after the one before (as a user starts it) took 206 ms
/// against 214 (medians of 8, alternately), started back to back 173.6 against 177.2
/// (10); a 12-hour `unz run`'s peak is measured in `docs/performance.md` (session 44).
/// glibc's heap in transparent huge pages (`GLIBC_TUNABLES=glibc.malloc.hugetlb=1`,
/// which session 43 set by starting the process again) is not asked for: on this VM a
/// process started after a pause took 277–302 ms with it against 206–216 without (the
/// host takes back the guest's free 2-MiB blocks, and zeroing one costs 512 of its
/// faults); only processes run back to back gain from it (5–6 %), and they can set it.
///
/// The heap also grows 8 MiB at a time (`M_TOP_PAD`, 128 KiB by default): each growth
/// is a `brk` that holds the process's memory map for writing, and every page fault of
/// the other threads meanwhile waits for it. A 40-minute disupt process grew its heap
/// 116 times (its threads blocked in the kernel at 42 of its 133 switches), now 8: 173.1
/// → 169.1 ms (medians of 20, alternately). Steps of 64 MiB were no faster and raised a
/// 12-hour run's peak by 16 MiB (means of 5); steps of 8 MiB left it as it was.
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
                && libc::mallopt(libc::M_TOP_PAD, TOP_PAD_BYTES) == 1
        };
        ok
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
