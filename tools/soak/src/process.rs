//! What the soak reads of the stack's processes while they run: scheduling class, resident
//! memory and open files.

/// A process's scheduling class as `ps` shows it: "FIFO 20", or "OTHER nice 10".
pub(crate) fn scheduling(pid: u32) -> String {
    mtanet_ipc::sched::class_of(pid)
}

/// VmRSS (kB) and open file descriptors of a process.
pub(crate) fn rss_and_fds(pid: u32) -> (u64, u64) {
    let rss = std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1).and_then(|v| v.parse().ok()))
        })
        .unwrap_or(0);
    let fds = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .map(|d| d.count() as u64)
        .unwrap_or(0);
    (rss, fds)
}
