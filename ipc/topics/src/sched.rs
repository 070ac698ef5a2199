//! Scheduling, in one place: the classes and niceness of the stack's processes and threads,
//! the CPUs they may run on, whether the 50 Hz path can run real-time here, and what a process
//! got. Through rustix where it has the call; SCHED_FIFO (`sched_setscheduler` and its getters)
//! only through libc, which rustix does not cover.

use rustix::process::{Pid, getpriority_process, setpriority_process};
use rustix::thread::{CpuSet, sched_getaffinity, sched_setaffinity};

use crate::stack::StackConfig;

/// Whether this user may run threads under SCHED_FIFO (root, CAP_SYS_NICE or `ulimit -r`):
/// tried on a thread of its own that ends at once, so the caller's class is untouched. The
/// processes of one stack share a user and its limits, so this is what the 50 Hz path got.
pub fn fifo_allowed() -> bool {
    std::thread::spawn(|| {
        let param = libc::sched_param { sched_priority: 1 };
        // SAFETY: sched_setscheduler(2) with pid 0 changes the calling thread only, which
        // ends right after.
        unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) == 0 }
    })
    .join()
    .unwrap_or(false)
}

/// Whether the stack's 50 Hz path (every process with a `realtime_priority`) runs SCHED_FIFO:
/// the plan asks for it and this user may have it.
pub fn realtime_path_is_fifo(stack: &StackConfig) -> bool {
    stack.process.iter().any(|p| p.realtime_priority.is_some()) && fifo_allowed()
}

/// Puts the calling thread under SCHED_FIFO at `priority`; false when refused (no privilege).
pub fn set_thread_fifo(priority: i32) -> bool {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: sched_setscheduler(2) with pid 0 changes the calling thread only.
    unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) == 0 }
}

/// Puts the calling thread back on the normal scheduler at `nice` (a thread that inherited
/// SCHED_FIFO and does long work); false when the niceness was refused.
pub fn set_thread_normal(nice: i32) -> bool {
    let normal = libc::sched_param { sched_priority: 0 };
    // SAFETY: sched_setscheduler(2) with pid 0 changes the calling thread only.
    unsafe { libc::sched_setscheduler(0, libc::SCHED_OTHER, &normal) };
    // Linux: a thread's niceness is set through its thread id.
    setpriority_process(Some(rustix::thread::gettid()), nice).is_ok()
}

/// The calling thread's SCHED_FIFO priority, if it runs under SCHED_FIFO.
pub fn thread_fifo_priority() -> Option<i32> {
    let mut param = libc::sched_param { sched_priority: 0 };
    // SAFETY: sched_getscheduler(2) and sched_getparam(2) on the calling thread only.
    let fifo = unsafe {
        libc::sched_getscheduler(0) == libc::SCHED_FIFO && libc::sched_getparam(0, &mut param) == 0
    };
    fifo.then_some(param.sched_priority)
}

/// Pins the calling thread to `cpu`; false when refused.
pub fn pin_thread(cpu: usize) -> bool {
    set_affinity(&[cpu]).is_ok()
}

/// The most CPUs an affinity set can name.
pub const MAX_CPUS: usize = CpuSet::MAX_CPU;

/// Confines the calling thread (and the threads and processes it starts later) to `cpus`.
pub fn set_affinity(cpus: &[usize]) -> std::io::Result<()> {
    let mut set = CpuSet::new();
    for &c in cpus {
        set.set(c);
    }
    sched_setaffinity(None, &set).map_err(Into::into)
}

/// The CPUs the calling thread may run on (`[0]` if that cannot be read).
pub fn allowed_cpus() -> Vec<usize> {
    match sched_getaffinity(None) {
        Ok(set) => (0..MAX_CPUS).filter(|&c| set.is_set(c)).collect(),
        Err(_) => vec![0],
    }
}

/// The CPUs online on this machine, whatever this process may use.
pub fn online_cpus() -> usize {
    // SAFETY: sysconf(3) reads a constant of the system (rustix has no sysconf).
    unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) }.max(1) as usize
}

/// For a child between fork and exec: exactly the class asked for (SCHED_FIFO at
/// `realtime_priority`, else the normal scheduler), never the parent's. Async-signal-safe; a
/// refusal is for the parent to see with [`class_of`].
pub fn set_class_in_child(realtime_priority: Option<i32>) {
    let (policy, p) = match realtime_priority {
        Some(p) => (libc::SCHED_FIFO, p),
        None => (libc::SCHED_OTHER, 0),
    };
    let param = libc::sched_param { sched_priority: p };
    // SAFETY: sched_setscheduler(2) is async-signal-safe and changes only the calling process.
    unsafe { libc::sched_setscheduler(0, policy, &param) };
}

/// Whether process `pid` (its main thread) runs under SCHED_FIFO.
pub fn is_fifo(pid: u32) -> bool {
    // SAFETY: reads another process's policy.
    unsafe { libc::sched_getscheduler(pid as libc::pid_t) == libc::SCHED_FIFO }
}

/// A process's scheduling class as `ps` shows it: "FIFO 20", or "OTHER nice 10".
pub fn class_of(pid: u32) -> String {
    let pid = pid as libc::pid_t;
    let mut param = libc::sched_param { sched_priority: 0 };
    // SAFETY: reads the policy and priority of another process (its main thread).
    let (policy, ok) = unsafe {
        (
            libc::sched_getscheduler(pid),
            libc::sched_getparam(pid, &mut param) == 0,
        )
    };
    let nice = getpriority_process(Pid::from_raw(pid)).unwrap_or(0);
    match policy {
        libc::SCHED_FIFO if ok => format!("FIFO {}", param.sched_priority),
        libc::SCHED_OTHER => format!("OTHER nice {nice}"),
        libc::SCHED_IDLE => "IDLE".into(),
        p => format!("policy {p}"),
    }
}

/// Sets the whole process's niceness (raising it needs no privilege, lowering does); false when
/// refused.
pub fn set_process_nice(nice: i32) -> bool {
    setpriority_process(None, nice).is_ok()
}

/// The calling process's niceness.
pub fn process_nice() -> i32 {
    getpriority_process(None).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probing_fifo_leaves_the_caller_on_the_normal_scheduler() {
        let _ = fifo_allowed();
        // SAFETY: reads the calling thread's policy.
        assert_eq!(unsafe { libc::sched_getscheduler(0) }, libc::SCHED_OTHER);
    }

    #[test]
    fn a_plan_without_a_realtime_process_is_never_fifo() {
        let mut stack = StackConfig::default();
        assert!(stack.process.iter().any(|p| p.realtime_priority.is_some()));
        for p in &mut stack.process {
            p.realtime_priority = None;
        }
        assert!(!realtime_path_is_fifo(&stack));
    }
}
