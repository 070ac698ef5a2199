//! Waiting in a WaitSet for a condition no message announces (a peer connecting): woken by an
//! interval, bounded by a deadline and a signal. The service loops wait here or on a topic's
//! event, never by sleeping in slices.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;

use crate::node::create_waitset;
use crate::shutdown::Shutdown;

/// The longest a termination signal waits to be noticed: a signal interrupts no wait
/// (signal-hook restarts it), so every wait is bounded by this.
pub const SIGNAL_LATENCY: Duration = Duration::from_millis(100);

/// How a wait ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Waited {
    Done,
    Deadline,
    Signal,
}

/// When an [`until`] wait looks again, and when it gives up.
pub struct Wake {
    /// Look this often (at most [`SIGNAL_LATENCY`]).
    pub every: Duration,
    pub deadline: Instant,
}

/// Checks `done` now and after every wake-up until it holds, the deadline passes or a signal
/// arrives; `on_wake` runs at each wake-up (to pet a watchdog).
pub fn until(
    wake: &Wake,
    shutdown: &Shutdown,
    mut on_wake: impl FnMut() -> anyhow::Result<()>,
    mut done: impl FnMut() -> bool,
) -> anyhow::Result<Waited> {
    let waitset = create_waitset()?;
    let _interval = waitset.attach_interval(wake.every.min(SIGNAL_LATENCY))?;
    loop {
        if done() {
            return Ok(Waited::Done);
        }
        if shutdown.requested() {
            return Ok(Waited::Signal);
        }
        let left = wake.deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Ok(Waited::Deadline);
        }
        waitset.wait_and_process_once_with_timeout(|_| CallbackProgression::Continue, left)?;
        on_wake()?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wake(every_ms: u64, deadline_ms: u64) -> Wake {
        Wake {
            every: Duration::from_millis(every_ms),
            deadline: Instant::now() + Duration::from_millis(deadline_ms),
        }
    }

    #[test]
    fn an_interval_wakes_the_wait_until_the_condition_holds() {
        let shutdown = Shutdown::manual();
        let (mut wakes, mut checks) = (0, 0);
        let on_wake = || {
            wakes += 1;
            Ok(())
        };
        let done = || {
            checks += 1;
            checks > 3
        };
        let end = until(&wake(5, 30_000), &shutdown, on_wake, done).unwrap();
        assert_eq!(end, Waited::Done);
        assert_eq!(wakes, 3, "one wake-up per failed check");
    }

    #[test]
    fn a_deadline_ends_a_wait_for_a_condition_that_never_holds() {
        let shutdown = Shutdown::manual();
        let w = wake(1_000, 30);
        let end = until(&w, &shutdown, || Ok(()), || false).unwrap();
        assert_eq!(end, Waited::Deadline);
        assert!(Instant::now() >= w.deadline);
    }

    #[test]
    fn a_requested_shutdown_ends_the_wait() {
        let shutdown = Shutdown::manual();
        shutdown.request();
        let end = until(&wake(10, 30_000), &shutdown, || Ok(()), || false).unwrap();
        assert_eq!(end, Waited::Signal);
    }
}
