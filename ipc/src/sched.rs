//! Scheduling of the stack's processes: whether the 50 Hz path can run real-time here, and a
//! process's niceness.

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

/// Sets the whole process's niceness (raising it needs no privilege, lowering does); false when
/// refused.
pub fn set_process_nice(nice: i32) -> bool {
    // SAFETY: setpriority(2) on this process only.
    unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, nice) == 0 }
}

/// The calling process's niceness.
pub fn process_nice() -> i32 {
    // SAFETY: getpriority(2) on this process only.
    unsafe { libc::getpriority(libc::PRIO_PROCESS, 0) }
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
