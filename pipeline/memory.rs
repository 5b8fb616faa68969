//! The process's resident memory, for the stages' verbose phase logs.

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
    fn rss_is_positive_and_below_its_peak_on_linux() {
        if cfg!(target_os = "linux") {
            let (now, peak) = rss_mb().expect("/proc/self/status");
            assert!(now > 0.0 && now <= peak, "{now} {peak}");
        }
    }
}
