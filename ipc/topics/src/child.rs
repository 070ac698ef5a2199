//! Stopping a child process the way every mtanet process expects to be stopped: one SIGTERM
//! (the process ends its loop, writes its summary and releases its shared memory), then SIGKILL
//! if it has not exited in time. The launcher's supervisor, the soak's ping-pong peer, the
//! experiment's runs and the system tests all stop their children through here.

use std::process::{Child, ExitStatus};
use std::time::{Duration, Instant};

pub use rustix::process::Signal;

/// How often a wait looks at the child again.
const POLL: Duration = Duration::from_millis(10);

/// Sends `sig` to process `pid`; a process already gone is no error. Only for a child of this
/// process that is not yet reaped: its pid cannot have been reused.
pub fn signal(pid: u32, sig: Signal) {
    if let Some(pid) = i32::try_from(pid)
        .ok()
        .and_then(rustix::process::Pid::from_raw)
    {
        let _ = rustix::process::kill_process(pid, sig);
    }
}

/// SIGTERM to `child` (ours, not yet reaped).
pub fn terminate(child: &Child) {
    signal(child.id(), Signal::TERM);
}

/// Waits up to `timeout` for `child` to exit; `None` if it still runs.
pub fn wait_for(child: &mut Child, timeout: Duration) -> Option<ExitStatus> {
    let deadline = Instant::now() + timeout;
    loop {
        if let Ok(Some(status)) = child.try_wait() {
            return Some(status);
        }
        if Instant::now() >= deadline {
            return None;
        }
        std::thread::sleep(POLL);
    }
}

/// SIGTERM, then SIGKILL if `child` has not exited within `timeout`. How it ended; `None`:
/// it had to be killed. The child is reaped either way.
pub fn stop(child: &mut Child, timeout: Duration) -> Option<ExitStatus> {
    stop_with(child, Signal::TERM, timeout)
}

/// [`stop`] with another clean-stop signal (the Zenoh tunnel stops on SIGINT).
pub fn stop_with(child: &mut Child, sig: Signal, timeout: Duration) -> Option<ExitStatus> {
    signal(child.id(), sig);
    let status = wait_for(child, timeout);
    if status.is_none() {
        let _ = child.kill();
        let _ = child.wait();
    }
    status
}

#[cfg(test)]
mod tests {
    use std::io::{BufRead, BufReader};
    use std::os::unix::process::ExitStatusExt;
    use std::process::{Command, Stdio};

    use super::*;

    #[test]
    fn a_child_that_obeys_sigterm_ends_by_it() {
        let mut child = Command::new("sleep").arg("30").spawn().expect("sleep");
        let status = stop(&mut child, Duration::from_secs(10)).expect("ended by SIGTERM");
        assert_eq!(status.signal(), Some(Signal::TERM.as_raw()), "{status:?}");
    }

    #[test]
    fn a_child_that_ignores_sigterm_is_killed_after_the_timeout() {
        // The shell ignores SIGTERM and so does the sleep it becomes (ignored signals are
        // inherited); it says so before the signal is sent.
        let mut child = Command::new("sh")
            .args(["-c", "trap '' TERM; echo ready; exec sleep 30"])
            .stdout(Stdio::piped())
            .spawn()
            .expect("sh");
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("stdout"))
            .read_line(&mut line)
            .expect("read");
        assert_eq!(line.trim(), "ready");
        let t0 = Instant::now();
        assert_eq!(stop(&mut child, Duration::from_millis(300)), None);
        assert!(t0.elapsed() >= Duration::from_millis(300));
        let killed = child.try_wait().expect("reaped").expect("status");
        assert_eq!(killed.signal(), Some(Signal::KILL.as_raw()), "{killed:?}");
    }
}
