//! What the operating system says about memory: how much is still available (the default
//! budget of the reference, `trace::reference::default_budget`) and this process's peak
//! (render summaries). Linux only, from `/proc` and cgroup v2; `None` elsewhere.

/// Bytes the system can still hand out: `MemAvailable`, or less where a cgroup v2 limit
/// (a container's, a Slurm job's) leaves this process less.
pub fn available_bytes() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let mut available = kib_field(&meminfo, "MemAvailable:")?;
    let read = |name: &str| {
        std::fs::read_to_string(format!("/sys/fs/cgroup/{name}"))
            .ok()
            .and_then(|s| s.trim().parse::<u64>().ok())
    };
    // "max" (no limit) does not parse.
    if let (Some(max), Some(current)) = (read("memory.max"), read("memory.current")) {
        available = available.min(max.saturating_sub(current));
    }
    Some(available)
}

/// This process's peak resident memory so far (`VmHWM`), in bytes.
pub fn peak_resident_bytes() -> Option<u64> {
    kib_field(
        &std::fs::read_to_string("/proc/self/status").ok()?,
        "VmHWM:",
    )
}

/// A `/proc` line `NAME:   1234 kB`, in bytes.
fn kib_field(text: &str, name: &str) -> Option<u64> {
    let kib = text
        .lines()
        .find_map(|l| l.strip_prefix(name))?
        .trim()
        .strip_suffix("kB")?
        .trim()
        .parse::<u64>()
        .ok()?;
    Some(kib * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proc_fields_are_read_in_bytes() {
        let text = "MemTotal:       24576000 kB\nMemAvailable:    1000 kB\n";
        assert_eq!(kib_field(text, "MemAvailable:"), Some(1_024_000));
        assert_eq!(kib_field(text, "VmHWM:"), None);
        assert_eq!(kib_field("VmHWM: 12 pages\n", "VmHWM:"), None);
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn this_machine_reports_both() {
        let peak = peak_resident_bytes().expect("VmHWM");
        // Touch 64 MiB: the peak must grow past it.
        let block = std::hint::black_box(vec![1u8; 64 << 20]);
        let after = peak_resident_bytes().expect("VmHWM");
        assert!(after >= peak.max(64 << 20), "{peak} -> {after}");
        assert!(available_bytes().expect("MemAvailable") > 0);
        drop(block);
    }
}
