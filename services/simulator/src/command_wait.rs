//! How long the simulator waits for the predictor's command. The deadline counts only time in
//! which the simulator's own thread could run: that thread is `SCHED_FIFO` above every other
//! thread of the stack, so waking far later than it asked means the CPU ran nothing at all (a
//! host pausing its virtual machine, seen here for 20-117 ms several times a minute). The
//! predictor was frozen with it: once the thread runs again the predictor gets its whole wait
//! anew, rather than a miss counted against it.

use std::time::{Duration, Instant};

/// Lateness of a wake-up from which the thread counts as frozen (a FIFO thread on an idle or
/// busy CPU wakes within tens of microseconds; a normal one beside a CPU hog within a few ms).
pub const FROZEN: Duration = Duration::from_millis(5);

#[derive(Debug, Clone, Copy)]
pub struct CommandDeadline {
    timeout: Duration,
    deadline: Instant,
    /// When the thread expected to be running again at the latest.
    expected: Instant,
    /// Time added back for freezes.
    pub frozen: Duration,
}

impl CommandDeadline {
    pub fn new(now: Instant, timeout: Duration) -> Self {
        Self {
            timeout,
            deadline: now + timeout,
            expected: now,
            frozen: Duration::ZERO,
        }
    }

    /// Time left at `now`; after a freeze since the last [`CommandDeadline::waiting`], the
    /// whole wait again (the freeze may have begun anywhere in the sleep).
    pub fn left(&mut self, now: Instant) -> Duration {
        let late = now.saturating_duration_since(self.expected);
        if late >= FROZEN {
            self.deadline = (self.deadline + late).max(now + self.timeout);
            self.frozen += late;
        }
        self.expected = now;
        self.deadline.saturating_duration_since(now)
    }

    /// The thread is about to sleep up to `slice` from `now`.
    pub fn waiting(&mut self, now: Instant, slice: Duration) {
        self.expected = now + slice;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn a_wait_that_wakes_on_time_runs_out_on_time() {
        let t0 = Instant::now();
        let mut d = CommandDeadline::new(t0, 10 * MS);
        assert_eq!(d.left(t0 + 2 * MS), 8 * MS);
        d.waiting(t0 + 2 * MS, 8 * MS);
        // Woken 1 ms late: the scheduler's, not a freeze.
        assert_eq!(d.left(t0 + 11 * MS), Duration::ZERO);
        assert_eq!(d.frozen, Duration::ZERO);
    }

    #[test]
    fn time_the_thread_was_frozen_is_given_back() {
        let t0 = Instant::now();
        let mut d = CommandDeadline::new(t0, 10 * MS);
        d.waiting(t0, 10 * MS);
        // Asked to wake at 10 ms, ran again at 80: at least 70 ms frozen, and the predictor
        // with it; it gets its 10 ms again.
        assert_eq!(d.left(t0 + 80 * MS), 10 * MS);
        assert_eq!(d.frozen, 70 * MS);
        // A freeze while not sleeping (between two looks) counts too.
        assert_eq!(d.left(t0 + 86 * MS), 10 * MS);
        assert_eq!(d.frozen, 76 * MS);
        d.waiting(t0 + 86 * MS, 10 * MS);
        assert_eq!(d.left(t0 + 96 * MS), Duration::ZERO);
    }
}
