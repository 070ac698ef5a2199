//! What the soak reads of the stack's processes while they run: scheduling class, resident
//! memory and open files.

/// A process's scheduling class as `ps` shows it: "FIFO 20", or "OTHER nice 10".
pub(crate) fn scheduling(pid: u32) -> String {
    let pid = pid as libc::pid_t;
    let mut param = libc::sched_param { sched_priority: 0 };
    // SAFETY: reads the policy and priority of another process (its main thread).
    let (policy, ok) = unsafe {
        (
            libc::sched_getscheduler(pid),
            libc::sched_getparam(pid, &mut param) == 0,
        )
    };
    // SAFETY: getpriority(2) on a process id.
    let nice = unsafe { libc::getpriority(libc::PRIO_PROCESS, pid as libc::id_t) };
    match policy {
        libc::SCHED_FIFO if ok => format!("FIFO {}", param.sched_priority),
        libc::SCHED_OTHER => format!("OTHER nice {nice}"),
        libc::SCHED_IDLE => "IDLE".into(),
        p => format!("policy {p}"),
    }
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
