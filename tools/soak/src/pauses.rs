//! The machine's own pauses: one SCHED_FIFO 99 thread per CPU that sleeps 2 ms at a time. Nothing
//! in the system holds off a FIFO 99 thread for milliseconds, so a wake-up that late means the
//! CPU ran nothing at all: a virtual machine whose host paused it (seen here: both vCPUs of an
//! idle VM at once, 20-117 ms, several times a minute) or firmware taking the CPU. A soak sets
//! them beside its own misses: a miss during such a pause is the machine's, not the stack's.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use mtanet_ipc::stamp;
use mtanet_summaries::soak::PauseSummary;
use serde::Serialize;

/// Lateness from which a wake-up counts as a pause of the CPU.
const PAUSE_NS: u64 = 3_000_000;
const PERIOD_NS: u64 = 2_000_000;
/// Pauses kept (a run that pauses more is reported by count).
const MAX_KEPT: usize = 100_000;

/// A CPU that ran nothing from `start_ns` to `end_ns` (`CLOCK_MONOTONIC`).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Pause {
    pub cpu: usize,
    pub start_ns: u64,
    pub end_ns: u64,
}

pub struct PauseWatch {
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<bool>>,
    pauses: Arc<Mutex<Vec<Pause>>>,
    started_ns: u64,
}

impl PauseWatch {
    /// Starts a watcher on each of `cpus`.
    pub fn start(cpus: &[usize]) -> anyhow::Result<Self> {
        let stop = Arc::new(AtomicBool::new(false));
        let pauses = Arc::new(Mutex::new(Vec::new()));
        let mut threads = Vec::new();
        for &cpu in cpus {
            let (stop, pauses) = (Arc::clone(&stop), Arc::clone(&pauses));
            threads.push(
                std::thread::Builder::new()
                    .name(format!("pause-watch-{cpu}"))
                    .spawn(move || watch(cpu, &stop, &pauses))?,
            );
        }
        Ok(Self {
            stop,
            threads,
            pauses,
            started_ns: stamp::monotonic_ns(),
        })
    }

    /// Stops the watchers; the pauses seen and their summary.
    pub fn finish(self) -> (Vec<Pause>, PauseSummary) {
        self.stop.store(true, Ordering::Relaxed);
        let measured = self
            .threads
            .into_iter()
            .map(|t| t.join().unwrap_or(false))
            .fold(true, |a, b| a && b);
        let minutes = stamp::elapsed_ns(self.started_ns) as f64 / 60e9;
        let pauses = std::mem::take(&mut *self.pauses.lock().expect("not poisoned"));
        let ms = |p: &Pause| (p.end_ns - p.start_ns) as f64 / 1e6;
        let summary = PauseSummary {
            measured,
            count: pauses.len(),
            per_minute: pauses.len() as f64 / minutes.max(1e-9),
            worst_ms: pauses.iter().map(ms).fold(0.0, f64::max),
            total_ms: pauses.iter().map(ms).sum(),
        };
        (pauses, summary)
    }
}

/// Sleeps to absolute 2 ms ticks on `cpu` at SCHED_FIFO 99, recording every wake-up later than
/// [`PAUSE_NS`]. False if it could not be real-time (then it records nothing).
fn watch(cpu: usize, stop: &AtomicBool, pauses: &Mutex<Vec<Pause>>) -> bool {
    let realtime = mtanet_ipc::sched::pin_thread(cpu) && mtanet_ipc::sched::set_thread_fifo(99);
    if !realtime {
        tracing::warn!(
            cpu,
            "no SCHED_FIFO 99 (needs root or CAP_SYS_NICE): machine pauses are not measured"
        );
        return false;
    }
    let mut due = stamp::monotonic_ns();
    while !stop.load(Ordering::Relaxed) {
        due += PERIOD_NS;
        let ts = rustix::time::Timespec {
            tv_sec: (due / 1_000_000_000) as i64,
            tv_nsec: (due % 1_000_000_000) as _,
        };
        let _ = rustix::thread::clock_nanosleep_absolute(rustix::time::ClockId::Monotonic, &ts);
        let now = stamp::monotonic_ns();
        if now > due + PAUSE_NS {
            let mut kept = pauses.lock().expect("not poisoned");
            if kept.len() < MAX_KEPT {
                kept.push(Pause {
                    cpu,
                    start_ns: due,
                    end_ns: now,
                });
            }
            due = now; // the schedule starts again from here
        }
    }
    true
}

/// True if `[start_ns, end_ns]` overlaps a pause (within `margin_ns`).
pub fn during_a_pause(pauses: &[Pause], start_ns: u64, end_ns: u64, margin_ns: u64) -> bool {
    pauses
        .iter()
        .any(|p| p.start_ns <= end_ns + margin_ns && start_ns <= p.end_ns + margin_ns)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_incident_counts_as_the_machines_only_if_it_overlaps_a_pause() {
        let pauses = [Pause {
            cpu: 0,
            start_ns: 100,
            end_ns: 200,
        }];
        assert!(during_a_pause(&pauses, 150, 160, 0));
        assert!(during_a_pause(&pauses, 50, 100, 0));
        assert!(during_a_pause(&pauses, 205, 300, 10));
        assert!(!during_a_pause(&pauses, 205, 300, 0));
        assert!(!during_a_pause(&[], 0, u64::MAX / 2, 0));
    }
}
