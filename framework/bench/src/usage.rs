//! What this process used, from Linux's `/proc/self`: CPU seconds (user + system, every thread) and
//! peak resident memory, whose high-water mark can be reset between runs. Elsewhere both read as zero.

/// Clock ticks per second of `/proc/self/stat` (`sysconf(_SC_CLK_TCK)`, 100 on every Linux SKiD runs on).
const TICKS_PER_SECOND: f64 = 100.0;

/// User plus system CPU time of the whole process so far, seconds.
pub fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // The command name may hold spaces; the fields after its closing parenthesis are space-separated,
    // utime and stime being the 12th and 13th of them.
    let after_name = stat.rsplit_once(')').map_or("", |(_, rest)| rest);
    let fields: Vec<&str> = after_name.split_whitespace().collect();
    let ticks = |index: usize| {
        fields
            .get(index)
            .and_then(|f| f.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) / TICKS_PER_SECOND
}

/// The peak resident set size since the process started or since [`reset_peak_rss`], MiB.
pub fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            status
                .lines()
                .find_map(|line| line.strip_prefix("VmHWM:"))
                .and_then(|value| value.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        })
        .map_or(0.0, |kib| kib / 1024.0)
}

/// Resets the peak resident set size to the current one (Linux 4.0 and later), so the next run's peak
/// is its own.
pub fn reset_peak_rss() {
    if let Err(error) = std::fs::write("/proc/self/clear_refs", "5") {
        eprintln!("could not reset the peak memory reading ({error}); peaks include earlier runs");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readings_are_plausible_on_linux() {
        if !cfg!(target_os = "linux") {
            return;
        }
        // Spin until the kernel has counted a tick of this process (10 ms), for at most 5 s.
        let started = std::time::Instant::now();
        let mut spin = 0_u64;
        while cpu_seconds() <= 0.0 {
            spin = std::hint::black_box(spin.wrapping_add(1));
            assert!(started.elapsed().as_secs() < 5, "no CPU time counted");
        }
        reset_peak_rss();
        assert!(peak_rss_mb() > 1.0);
    }
}
