//! The process's CPU time, so that a benchmark can say how busy the cores were beside how
//! long it took.

/// CPU time used so far by the whole process (every thread, user and system), s: the
/// process's CPU-time clock (`CLOCK_PROCESS_CPUTIME_ID`); `None` where there is none.
pub fn process_cpu_s() -> Option<f64> {
    #[cfg(unix)]
    {
        Some(clock_s(rustix::time::ClockId::ProcessCPUTime))
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// The process's CPU time since `start` (an earlier [`process_cpu_s`]), s.
pub fn cpu_s_since(start: Option<f64>) -> Option<f64> {
    process_cpu_s().zip(start).map(|(now, start)| now - start)
}

/// The time of the clock `id`, s.
#[cfg(unix)]
fn clock_s(id: rustix::time::ClockId) -> f64 {
    let t = rustix::time::clock_gettime(id);
    t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
}

/// The cores this process may run on (what the standard library finds; 1 when it cannot
/// tell).
pub fn available_cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// `", CPU 17.80 s (96 % of 2 cores)"` for `cpu_s` of CPU over `wall_s` on `cores`, or
/// nothing without a CPU time.
pub fn cpu_suffix(cpu_s: Option<f64>, wall_s: f64, cores: usize) -> String {
    cpu_s.map_or_else(String::new, |cpu| {
        let busy = 100.0 * cpu / (wall_s * cores.max(1) as f64);
        format!(", CPU {cpu:.2} s ({busy:.0} % of {cores} cores)")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Works on this thread until it has had `cpu_s` of CPU (its own CPU-time clock).
    #[cfg(unix)]
    fn busy_for(cpu_s: f64) -> u64 {
        let now = || clock_s(rustix::time::ClockId::ThreadCPUTime);
        let t0 = now();
        let mut x = 0u64;
        while now() - t0 < cpu_s {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
        x
    }

    #[cfg(unix)]
    #[test]
    fn the_process_clock_counts_every_threads_work() {
        let before = process_cpu_s();
        assert!(before.is_some());
        // Two threads with 0.1 s of CPU each: the process has had at least 0.2 s more
        // (other tests' threads of this process may add theirs).
        std::thread::scope(|s| {
            let other = s.spawn(|| busy_for(0.1));
            busy_for(0.1);
            other.join().unwrap();
        });
        let used = cpu_s_since(before).unwrap();
        assert!(used >= 0.2 - 1e-6, "{used} s");
    }

    #[test]
    fn the_suffix_gives_the_cores_busy_share() {
        assert_eq!(
            cpu_suffix(Some(18.0), 10.0, 2),
            ", CPU 18.00 s (90 % of 2 cores)"
        );
        assert_eq!(cpu_suffix(None, 10.0, 2), "");
    }
}
