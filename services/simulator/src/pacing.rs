//! Lockstep pacing on the trainer: the simulator runs as fast as the predictor answers, which
//! on a fast CPU is many simulated seconds per training update. So once the trainer trains, the
//! simulator waits whenever it is more than `updates_per_1000_steps` ahead of the trainer's
//! updates: a run of S simulated seconds then learns the same on any machine.

use std::time::{Duration, Instant};

use mtanet_ipc::TrainerStatus;
use mtanet_ipc::ports::Receiver;
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::systemd::Watchdog;
pub use mtanet_summaries::simulator::PaceSummary;

/// Steps the simulator may run ahead of the trainer, in updates.
const SLACK_UPDATES: f64 = 1.0;

pub struct Pace {
    rate: f64,
    enabled: bool,
    start: Option<(u64, u64)>,
    latest: Option<TrainerStatus>,
    waited: Duration,
}

impl Pace {
    /// `rate` updates per 1000 steps (0 = off); only lockstep is paced.
    pub fn new(rate: f64, lockstep: bool) -> Self {
        Self {
            rate,
            enabled: lockstep && rate > 0.0,
            start: None,
            latest: None,
            waited: Duration::ZERO,
        }
    }

    /// The rate in force (0 when not pacing).
    pub fn rate(&self) -> f32 {
        if self.enabled { self.rate as f32 } else { 0.0 }
    }

    fn refresh(&mut self, rx: &Receiver<TrainerStatus>) -> anyhow::Result<()> {
        if let Some(s) = rx.latest()? {
            self.latest = Some(s);
        }
        Ok(())
    }

    /// Steps `step` may run after the trainer's progress so far.
    fn allowed(&self) -> Option<f64> {
        let (s0, u0) = self.start?;
        let u = self.latest?.session_updates;
        Some(s0 as f64 + (u.saturating_sub(u0) as f64 + SLACK_UPDATES) * 1000.0 / self.rate)
    }

    /// Blocks before step `step` until the trainer has caught up (or has left, or a signal).
    pub fn wait_for_trainer(
        &mut self,
        rx: &Receiver<TrainerStatus>,
        step: u64,
        shutdown: &Shutdown,
        watchdog: &mut Watchdog,
    ) -> anyhow::Result<()> {
        if !self.enabled {
            return Ok(());
        }
        self.refresh(rx)?;
        let Some(status) = self.latest else {
            return Ok(());
        };
        if status.training == 0 || rx.publishers() == 0 {
            return Ok(()); // not training yet, or gone: nothing to wait for
        }
        match self.start {
            // A restarted trainer counts its updates from 0 again: pace from here.
            Some((_, u0)) if status.session_updates < u0 => {
                self.start = Some((step, status.session_updates))
            }
            None => {
                tracing::info!(
                    step,
                    rate = self.rate,
                    "the trainer trains: pacing the simulation on its updates"
                );
                self.start = Some((step, status.session_updates));
            }
            _ => {}
        }
        self.wait_while(rx, shutdown, watchdog, |p| {
            p.allowed().is_some_and(|a| step as f64 > a)
        })
    }

    /// Blocks on the trainer's status while `behind` holds, the trainer is there and no signal
    /// came; the time counts as waited.
    fn wait_while(
        &mut self,
        rx: &Receiver<TrainerStatus>,
        shutdown: &Shutdown,
        watchdog: &mut Watchdog,
        behind: impl Fn(&Self) -> bool,
    ) -> anyhow::Result<()> {
        let t0 = Instant::now();
        while behind(self) && !shutdown.requested() && rx.publishers() > 0 {
            rx.wait(Duration::from_millis(100))?;
            self.refresh(rx)?;
            watchdog.pet();
        }
        self.waited += t0.elapsed();
        Ok(())
    }

    /// Lockstep learning (the trainer's `schedule.rs`): blocks before step `step` while weights
    /// due at or before it are not out yet, so the predictor has them when it answers it.
    pub fn wait_for_weights(
        &mut self,
        rx: &Receiver<TrainerStatus>,
        step: u64,
        shutdown: &Shutdown,
        watchdog: &mut Watchdog,
    ) -> anyhow::Result<()> {
        if !self.enabled {
            return Ok(());
        }
        self.refresh(rx)?;
        self.wait_while(rx, shutdown, watchdog, |p| {
            p.latest.is_none_or(|s| s.next_install_step <= step)
        })
    }

    pub fn summary(&self, step: u64) -> PaceSummary {
        let mut s = PaceSummary {
            target_updates_per_1000_steps: if self.enabled { self.rate } else { 0.0 },
            wait_seconds: self.waited.as_secs_f64(),
            ..Default::default()
        };
        if let (Some((s0, u0)), Some(latest)) = (self.start, self.latest) {
            s.paced_steps = step.saturating_sub(s0);
            s.trainer_updates = latest.session_updates.saturating_sub(u0);
            if s.paced_steps > 0 {
                s.updates_per_1000_steps = s.trainer_updates as f64 * 1000.0 / s.paced_steps as f64;
            }
        }
        s
    }
}
