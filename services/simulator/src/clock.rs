//! When steps happen. Real time: step n is due at start + n x period, on an absolute schedule
//! (a late step does not shift the ones after it); the wait for it is one sleep to that
//! deadline. Lockstep: as soon as the previous step is done.

use std::time::{Duration, Instant};

use mtanet_ipc::latency::LatencyStats;

pub struct Clock {
    start: Instant,
    period: Duration,
    realtime: bool,
    /// How late each step started against its tick.
    pub jitter: LatencyStats,
    /// How far past its tick each step finished (0 when on time).
    pub late: LatencyStats,
}

impl Clock {
    pub fn new(period_s: f64, realtime: bool) -> Self {
        Self {
            start: Instant::now(),
            period: Duration::from_secs_f64(period_s),
            realtime,
            jitter: LatencyStats::new(),
            late: LatencyStats::new(),
        }
    }

    fn due(&self, step: u64) -> Instant {
        self.start + self.period.mul_f64(step as f64)
    }

    /// Step `step` begins now.
    pub fn begin(&mut self, step: u64) -> Instant {
        let now = Instant::now();
        if self.realtime {
            let late = now.saturating_duration_since(self.due(step));
            self.jitter.record_ns(late.as_nanos() as u64);
        }
        now
    }

    /// `done` steps are done: in real time, wait for the next one's tick.
    pub fn wait_for_tick(&mut self, done: u64) {
        if !self.realtime {
            return;
        }
        let next = self.due(done);
        let now = Instant::now();
        self.late
            .record_ns(now.saturating_duration_since(next).as_nanos() as u64);
        std::thread::sleep(next.saturating_duration_since(now));
    }

    pub fn elapsed(&self) -> Duration {
        self.start.elapsed()
    }
}
