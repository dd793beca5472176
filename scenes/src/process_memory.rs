//! The process's resident memory, now and at its peak: what `preprocess` reports and its
//! memory budget admits work under, and what `bench` records.

/// Resident bytes now and the peak so far, from `/proc/self/status` (`VmRSS`, `VmHWM`);
/// `None` where the platform does not say (off Linux).
pub fn resident_bytes() -> (Option<u64>, Option<u64>) {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        let line = status.lines().find(|l| l.starts_with(name))?;
        let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kib * 1024)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(target_os = "linux")]
    #[test]
    fn the_peak_is_at_least_what_is_resident_and_grows_with_a_touched_buffer() {
        let (now, peak) = resident_bytes();
        let (now, peak) = (now.expect("VmRSS"), peak.expect("VmHWM"));
        assert!(now > 0 && peak >= now, "resident {now}, peak {peak}");
        // 64 MiB written page by page is resident until dropped.
        let buffer = vec![1u8; 64 << 20];
        let (with, _) = resident_bytes();
        assert!(
            with.expect("VmRSS") >= now + (48 << 20),
            "resident {now} -> {with:?} with 64 MiB touched"
        );
        assert_eq!(buffer.iter().map(|&b| b as usize).sum::<usize>(), 64 << 20);
    }
}
