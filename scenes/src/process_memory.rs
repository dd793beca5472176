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
        // 128 MiB written page by page is resident until dropped, whatever the tests running
        // beside this one free meanwhile (a reading in KiB, not bytes, would be 1024 × less).
        let buffer = vec![1u8; 128 << 20];
        let (with, peak_with) = resident_bytes();
        let (with, peak_with) = (with.expect("VmRSS"), peak_with.expect("VmHWM"));
        assert!(with >= 128 << 20, "resident {with} with 128 MiB touched");
        assert!(
            peak_with >= with.max(peak),
            "peak {peak} -> {peak_with}, resident {with}"
        );
        assert_eq!(buffer.iter().map(|&b| b as usize).sum::<usize>(), 128 << 20);
    }
}
