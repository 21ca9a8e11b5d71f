//! Resident memory from `/proc/self/status` (Linux): the peak and the current size.

/// A `kB` field of `/proc/self/status` (`VmHWM`, `VmRSS`) in bytes; `None` off Linux.
pub fn status_bytes(field: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    let kib: u64 = line
        .trim_start_matches(field)
        .trim_start_matches(':')
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    Some(kib * 1024)
}

/// Peak resident set size of this process so far.
pub fn peak() -> Option<u64> {
    status_bytes("VmHWM")
}

pub fn current() -> Option<u64> {
    status_bytes("VmRSS")
}
