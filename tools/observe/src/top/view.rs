//! What `mta top` shows: the latest readings, topic rates from counters, and the histories
//! behind the sparklines.

use std::collections::VecDeque;
use std::time::Instant;

use mtanet_ipc::{Command, Observation, TrainerStatus};

use crate::status::Status;

/// Samples kept for the sparklines (one a second).
const HISTORY: usize = 120;

/// A value and when it was seen, for rates from counters.
#[derive(Clone, Copy)]
struct Seen {
    value: u64,
    at: Instant,
}

/// Rate of a counter between two refreshes.
#[derive(Default)]
pub(super) struct Rate {
    last: Option<Seen>,
    pub hz: Option<f64>,
}

impl Rate {
    pub(super) fn update(&mut self, value: Option<u64>, now: Instant) {
        let Some(value) = value else { return };
        if let Some(l) = self.last {
            let dt = now.duration_since(l.at).as_secs_f64();
            if dt > 0.2 {
                // A restarted process counts from 0 again: no negative rate.
                self.hz = Some(value.saturating_sub(l.value) as f64 / dt);
                self.last = Some(Seen { value, at: now });
            }
        } else {
            self.last = Some(Seen { value, at: now });
        }
    }
}

/// Everything one frame shows.
#[derive(Default)]
pub struct View {
    pub status: Option<Status>,
    pub observation: Option<Observation>,
    pub command: Option<Command>,
    pub trainer: Option<TrainerStatus>,
    /// Topic rates (Hz): observation, command, replay, weights.
    pub(super) rates: [Rate; 4],
    /// Histories for the sparklines.
    pub(super) step_p99_us: VecDeque<u64>,
    pub(super) predictor_p99_us: VecDeque<u64>,
    pub(super) model_ratio_milli: VecDeque<u64>,
    pub(super) loss_micro: VecDeque<u64>,
    pub(super) started: Option<Instant>,
}

fn push(h: &mut VecDeque<u64>, v: Option<f64>) {
    if h.len() == HISTORY {
        h.pop_front();
    }
    h.push_back(v.filter(|v| v.is_finite() && *v >= 0.0).unwrap_or(0.0) as u64);
}

impl View {
    /// Takes in one refresh's readings.
    pub fn update(
        &mut self,
        status: Status,
        observation: Option<Observation>,
        command: Option<Command>,
        trainer: Option<TrainerStatus>,
    ) {
        let now = Instant::now();
        self.started.get_or_insert(now);
        self.observation = observation.or(self.observation);
        self.command = command.or(self.command);
        self.trainer = trainer.or(self.trainer);
        let [obs, cmd, replay, weights] = &mut self.rates;
        obs.update(observation.map(|o| o.step), now);
        cmd.update(command.map(|c| c.step), now);
        replay.update(trainer.map(|t| t.chunks_received), now);
        weights.update(command.map(|c| c.model_version), now);
        let p99 = |role: &str| status.processes.get(role).map(|p| p.latency.p99_us);
        push(&mut self.step_p99_us, p99("simulator"));
        push(&mut self.predictor_p99_us, p99("predictor"));
        push(
            &mut self.model_ratio_milli,
            self.command.map(|c| f64::from(c.model_error_ratio) * 1e3),
        );
        let loss = status
            .processes
            .get("trainer")
            .and_then(|t| t.detail.get("loss"))
            .and_then(|v| v.as_f64());
        push(&mut self.loss_micro, loss.map(|l| l * 1e6));
        self.status = Some(status);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn rates_come_from_counters_and_survive_a_restart() {
        let mut r = Rate::default();
        let t0 = Instant::now();
        r.update(Some(100), t0);
        assert_eq!(r.hz, None, "one reading has no rate");
        r.update(Some(150), t0 + Duration::from_secs(1));
        assert_eq!(r.hz, Some(50.0));
        r.update(Some(3), t0 + Duration::from_secs(2));
        assert_eq!(
            r.hz,
            Some(0.0),
            "a counter that restarted is not a negative rate"
        );
    }
}
