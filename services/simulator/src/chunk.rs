//! Replay chunks built in place in shared memory, step by step.

use anyhow::Context;
use mtanet_ipc::ports::{Loaned, Sender};
use mtanet_ipc::{CommandSource, REPLAY_STEPS, ReplayChunk, stamp};
use mtanet_scenes::Sensors;

/// Writes consecutive steps straight into a loaned replay sample in shared memory; sends it when full.
#[derive(Default)]
pub struct ChunkBuilder {
    sample: Option<Loaned<ReplayChunk>>,
    pub sent: u64,
    /// Written into each chunk (see `ReplayChunk::pace`).
    pub pace: f32,
}

impl ChunkBuilder {
    /// Adds a step: its frame and the command (and its source) that led to it. Sends the chunk
    /// once it holds `REPLAY_STEPS` steps.
    pub fn push(
        &mut self,
        replay: &Sender<ReplayChunk>,
        step: u64,
        episode: u32,
        s: &Sensors,
        applied: [f32; 2],
        source: CommandSource,
    ) -> anyhow::Result<()> {
        let sample = match self.sample.as_mut() {
            Some(sample) => sample,
            None => {
                let mut fresh = replay.loan_zeroed().context("loaning a replay chunk")?;
                let c = fresh.payload_mut();
                c.seq = self.sent;
                c.first_step = step;
                c.episode = episode;
                self.sample.insert(fresh)
            }
        };
        let c = sample.payload_mut();
        let i = c.len as usize;
        c.images[i] = s.image;
        c.actions[i] = applied;
        c.sources[i] = source as u8;
        c.len += 1;
        c.pace = self.pace;
        if c.len as usize == REPLAY_STEPS {
            c.stamp_ns = stamp::monotonic_ns();
            let full = self.sample.take().expect("a chunk is being filled");
            replay.send_loaned(full).context("sending a replay chunk")?;
            self.sent += 1;
        }
        Ok(())
    }

    /// Drops a partly filled chunk (its loan returns to the pool unsent).
    pub fn discard(&mut self) {
        self.sample = None;
    }
}
