use bytemuck::Zeroable;
use iceoryx2::prelude::ZeroCopySend;

/// The trainer's progress, after every update (and when it starts): the lockstep simulator
/// paces itself on `updates` so that learning per simulated second does not depend on the CPU.
#[derive(Debug, Clone, Copy, Default, Zeroable, bytemuck::Pod, ZeroCopySend)]
#[type_name("mtanet::TrainerStatus/v2")]
#[repr(C)]
pub struct TrainerStatus {
    /// `CLOCK_MONOTONIC` ns when published.
    pub stamp_ns: u64,
    /// Training updates done (a resumed trainer counts from its checkpoint).
    pub updates: u64,
    /// Updates done by this trainer process (what pacing counts).
    pub session_updates: u64,
    /// Replay chunks received and lost (sequence gaps) so far.
    pub chunks_received: u64,
    pub chunks_lost: u64,
    /// Sequences in the replay buffer.
    pub sequences: u32,
    /// 1 once the buffer holds enough to train.
    pub training: u32,
    /// Lockstep learning (see `services/trainer/src/schedule.rs`): weights versions published
    /// by this process, the install step of the last one (0: none), and the earliest step at
    /// which the next one can be due (`u64::MAX`: no schedule, weights are installed on arrival).
    /// A lockstep simulator does not send that step before the version is out.
    pub published: u64,
    pub last_install_step: u64,
    pub next_install_step: u64,
}
