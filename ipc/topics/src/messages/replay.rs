use bytemuck::Zeroable;
use iceoryx2::prelude::ZeroCopySend;

use crate::{ACTION_DIM, IMAGE_PIXELS, REPLAY_STEPS};

/// `REPLAY_STEPS` consecutive steps for the trainer, in the dataset convention of the project:
/// `actions[t]` is the wheel command applied from frame t-1 to frame t (the quantity a planner
/// chooses, not the measured wheel speed, which lags it). Consecutive chunks of one episode join
/// into longer sequences. ~7.9 KB, written in place in shared memory by the simulator.
#[derive(Debug, Clone, Copy, Zeroable, bytemuck::Pod, ZeroCopySend)]
#[type_name("mtanet::ReplayChunk/v2")]
#[repr(C)]
pub struct ReplayChunk {
    /// `CLOCK_MONOTONIC` ns when published.
    pub stamp_ns: u64,
    /// Chunk counter of this simulator run (gaps = chunks lost).
    pub seq: u64,
    /// Observation step of `images[0]`.
    pub first_step: u64,
    /// Valid steps (== REPLAY_STEPS except for a final partial chunk).
    pub len: u32,
    /// Episode of all steps (a chunk never spans a reset).
    pub episode: u32,
    pub images: [[f32; IMAGE_PIXELS]; REPLAY_STEPS],
    pub actions: [[f32; ACTION_DIM]; REPLAY_STEPS],
    /// Who decided `actions[t]` (a `CommandSource` as u8), e.g. to count exploratory data.
    pub sources: [u8; REPLAY_STEPS],
    /// Lockstep pacing in force: trainer updates per 1000 steps (0: none, e.g. real time). The
    /// trainer keeps to it from its side too, so the rate holds exactly in both directions.
    pub pace: f32,
}
