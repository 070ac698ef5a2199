//! The stats topic: every process publishes one [`ProcessStats`] a second about itself (rate,
//! latency, memory, CPU, its role's figures), so `mta status` and a live view read the running
//! stack from shared memory, never from its logs.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;

use crate::latency::LatencySummary;
use crate::ports::{PortError, Sender, TopicShape};
use crate::{ProcessStats, names, stamp};

/// Every process publishes; several viewers may subscribe. History 1: a viewer that starts
/// gets each process's newest message with its next publish.
pub const SHAPE: TopicShape = TopicShape {
    buffer: 8,
    history: 1,
    max_subscribers: 8,
    max_publishers: 8,
    deep_buffer: 8,
};

/// Set by the supervisor (`mta up`) in a restarted process's environment.
pub const RESTARTS_ENV: &str = "MTANET_RESTARTS";

/// Publishes this process's stats at most once per `every`.
pub struct StatsPublisher {
    sender: Sender<ProcessStats>,
    role: &'static str,
    restarts: u32,
    every: Duration,
    last: Instant,
    /// None until the first publish (a resumed trainer's count does not start at 0).
    last_count: Option<u64>,
    last_cpu_s: f64,
}

impl StatsPublisher {
    pub fn open(node: &Node<ipc::Service>, role: &'static str) -> Result<Self, PortError> {
        let restarts = std::env::var(RESTARTS_ENV)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(0);
        Ok(Self {
            sender: Sender::open(node, names::STATS, SHAPE)?,
            role,
            restarts,
            every: Duration::from_secs(1),
            last: Instant::now(),
            last_count: None,
            last_cpu_s: cpu_seconds(),
        })
    }

    /// When a second has passed: publishes with `count` (steps, ticks or updates so far), the
    /// latency of its unit of work and `fill` for the role's own fields. Cheap otherwise.
    pub fn tick(
        &mut self,
        count: u64,
        latency: impl FnOnce() -> LatencySummary,
        fill: impl FnOnce(&mut ProcessStats),
    ) -> Result<bool, PortError> {
        if self.last.elapsed() < self.every {
            return Ok(false);
        }
        self.publish(count, latency, fill)?;
        Ok(true)
    }

    /// Publishes now, due or not: the last word of a process whose work is done.
    pub fn publish(
        &mut self,
        count: u64,
        latency: impl FnOnce() -> LatencySummary,
        fill: impl FnOnce(&mut ProcessStats),
    ) -> Result<(), PortError> {
        let dt = self.last.elapsed().max(Duration::from_micros(1));
        let cpu = cpu_seconds();
        let l = latency();
        let (role, restarts) = (self.role, self.restarts);
        let rate = self.last_count.map_or(f64::NAN, |c| {
            count.saturating_sub(c) as f64 / dt.as_secs_f64()
        });
        let cpu_percent = 100.0 * (cpu - self.last_cpu_s) / dt.as_secs_f64();
        self.sender.send_with(|s| {
            s.stamp_ns = stamp::monotonic_ns();
            s.set_role(role);
            s.pid = std::process::id();
            s.restarts = restarts;
            s.count = count;
            s.rate_hz = rate as f32;
            s.cpu_percent = cpu_percent as f32;
            s.rss_kb = rss_kb();
            (s.p50_us, s.p99_us, s.p999_us, s.max_us) = (
                l.p50_us as f32,
                l.p99_us as f32,
                l.p999_us as f32,
                l.max_us as f32,
            );
            (s.model_over_copy_last, s.loss) = (f32::NAN, f32::NAN);
            fill(s);
        })?;
        (self.last, self.last_count, self.last_cpu_s) = (Instant::now(), Some(count), cpu);
        Ok(())
    }
}

/// User + system CPU time of this process, seconds (`/proc/self/stat`; 0 elsewhere).
fn cpu_seconds() -> f64 {
    let Ok(s) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the parenthesised name: state is the 3rd field, utime the 14th, stime the 15th.
    let rest = s.rsplit_once(')').map_or("", |r| r.1);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = [11, 12]
        .iter()
        .filter_map(|&i| f.get(i)?.parse::<f64>().ok())
        .sum();
    let hz = rustix::param::clock_ticks_per_second().max(1) as f64;
    ticks / hz
}

/// Resident set size, kB (`/proc/self/statm`; 0 elsewhere).
fn rss_kb() -> u64 {
    let pages = std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1)?.parse::<u64>().ok())
        .unwrap_or(0);
    pages * rustix::param::page_size() as u64 / 1024
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_its_own_cpu_and_memory() {
        let t0 = cpu_seconds();
        let mut x = 0u64;
        let start = Instant::now();
        while start.elapsed() < Duration::from_millis(200) {
            x = x.wrapping_add(std::hint::black_box(1));
        }
        assert!(x > 0);
        let used = cpu_seconds() - t0;
        assert!(used > 0.05, "200 ms of spinning showed {used} s of CPU");
        assert!(rss_kb() > 100, "rss {} kB", rss_kb());
    }
}

/// A count for a u32 field of [`ProcessStats`] (saturating: a status is never wrapped).
pub fn saturate(n: u64) -> u32 {
    n.min(u64::from(u32::MAX)) as u32
}
