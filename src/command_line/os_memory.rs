//! The process's memory as the operating system sees it (the command
//! line owns the process; the library asks it through `Progress`): free pages handed
//! back, the peak resident size read.

/// Hands the allocator's free pages back to the system: memory freed
/// between phases (a DEM read whole then cut, the plan's passes) lies
/// below what is still held, where the allocator never gives it back by
/// itself, and would count in the run's peak ever after.
pub fn release_free_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free pages of glibc's own heap to
    // the system; it touches no memory the program holds.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Peak resident memory of this process (VmHWM), MiB.
pub fn peak_rss_mib() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}
