//! Lockstep learning that replays the same. When the simulator paces on the trainer (lockstep,
//! `pace` > 0 in its chunks), what an update learns from and when its weights drive are fixed by
//! the data, never by when a chunk arrived or how fast anything ran:
//! - training starts at chunk c0, the chunk after which the buffer first holds enough to train;
//! - update k of this process draws from the chunks received before H_k = c0 + k x 50 / rate
//!   (rate: updates per 1000 steps, 50 chunks of 20 steps) and waits until it has them;
//! - the weights published after update k drive from observation step end(H_k - 1) + the lag:
//!   the predictor installs them right before answering that step, and the simulator does not
//!   send it before they are out (`next_install_step`).
//!
//! Without pacing (real time) there is no schedule: updates run as fast as they can and weights
//! are installed on arrival.

use crate::replay::ReplayBuffer;

/// Steps between the end of an update's data and the step its weights drive from: room for the
/// trainer to learn and publish while the simulator runs on (more than one chunk, so the
/// simulator never waits for a chunk it has not finished).
pub const INSTALL_LAG_STEPS: u64 = 100;
const CHUNKS_PER_1000_STEPS: f64 = 1000.0 / mtanet_ipc::REPLAY_STEPS as f64;

#[derive(Debug, Default)]
pub struct Schedule {
    /// c0: chunks received when training could start.
    start: Option<u64>,
    /// Versions published under the schedule, and the install step of the last.
    pub published: u64,
    pub last_install_step: u64,
}

impl Schedule {
    /// After each chunk taken in: the first time the learner is ready marks the start.
    pub fn see(&mut self, received: u64, ready: bool) {
        if self.start.is_none() && ready {
            self.start = Some(received);
        }
    }

    /// H_k, when there is a schedule (pacing on and training started).
    pub fn horizon(&self, k: u64, rate: f32) -> Option<u64> {
        let c0 = self.start?;
        (rate > 0.0).then(|| c0 + (k as f64 * CHUNKS_PER_1000_STEPS / f64::from(rate)) as u64)
    }

    /// Update k may run: its chunks are in (always, without a schedule).
    pub fn may_update(&self, k: u64, rate: f32, received: u64) -> bool {
        self.horizon(k, rate).is_none_or(|h| received >= h)
    }

    /// The step from which the weights of the update with horizon `h` drive.
    pub fn install_step(&self, h: u64, buffer: &ReplayBuffer) -> u64 {
        let end = h
            .checked_sub(1)
            .and_then(|c| buffer.end_step(c))
            .unwrap_or(0);
        end + INSTALL_LAG_STEPS
    }

    /// A lower bound on the install step of the next version, to be published by update
    /// `k_next`; `u64::MAX` once the chunks say there is no pacing (no step waits for
    /// weights). Before the first chunk the pacing is not known: the bound holds either way.
    pub fn next_install_step(&self, k_next: u64, rate: f32, buffer: &ReplayBuffer) -> u64 {
        if rate <= 0.0 && buffer.received() > 0 {
            return u64::MAX;
        }
        let received = buffer.received();
        match self.horizon(k_next, rate) {
            Some(h) if h <= received => self.install_step(h, buffer),
            // Its data is not all in: it ends after the newest chunk.
            _ => self.install_step(received, buffer),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mtanet_ipc::ReplayChunk;

    fn buffer_with(chunks: u64) -> ReplayBuffer {
        let mut b = ReplayBuffer::new(16);
        for i in 0..chunks {
            let mut c: ReplayChunk = bytemuck::Zeroable::zeroed();
            (c.seq, c.first_step, c.len, c.pace) = (i, i * 20, 20, 40.0);
            b.push(&c);
        }
        b
    }

    #[test]
    fn horizons_follow_the_data_and_the_rate_only() {
        let mut s = Schedule::default();
        assert_eq!(s.horizon(0, 40.0), None, "not started");
        assert!(s.may_update(0, 40.0, 0), "no schedule: free to update");
        s.see(5, false);
        s.see(6, true);
        s.see(7, true);
        // 40 updates per 1000 steps: one update per 1.25 chunks.
        let h: Vec<u64> = (0..5).map(|k| s.horizon(k, 40.0).unwrap()).collect();
        assert_eq!(h, [6, 7, 8, 9, 11]);
        assert!(!s.may_update(4, 40.0, 10) && s.may_update(4, 40.0, 11));
        assert_eq!(s.horizon(3, 0.0), None, "no pacing, no schedule");
    }

    #[test]
    fn weights_drive_a_lag_after_their_data_and_the_bound_never_overshoots() {
        let b = buffer_with(10); // chunk i covers steps [20 i, 20 i + 20)
        let mut s = Schedule::default();
        s.see(4, true);
        // Update 5's horizon is 4 + 6 = 10 chunks: its data ends at step 200.
        assert_eq!(s.horizon(5, 40.0), Some(10));
        assert_eq!(s.install_step(10, &b), 200 + INSTALL_LAG_STEPS);
        assert_eq!(s.next_install_step(5, 40.0, &b), 200 + INSTALL_LAG_STEPS);
        // Update 9 needs 15 chunks: not in yet; the bound is what the newest chunk allows.
        let bound = s.next_install_step(9, 40.0, &b);
        assert_eq!(bound, 200 + INSTALL_LAG_STEPS);
        assert!(bound <= 15 * 20 + INSTALL_LAG_STEPS);
        assert_eq!(s.next_install_step(9, 0.0, &b), u64::MAX);
        let empty = ReplayBuffer::new(4);
        assert_eq!(s.next_install_step(0, 0.0, &empty), INSTALL_LAG_STEPS);
    }
}
