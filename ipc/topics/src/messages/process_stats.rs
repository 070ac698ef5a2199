use bytemuck::Zeroable;
use iceoryx2::prelude::ZeroCopySend;

/// What one process says of itself once a second on [`crate::names::STATS`], for `mta status`,
/// `mta top` and tests: one message type for every process, each field with one meaning, named
/// as in the process's exit summary; fields of another role stay at zero (NaN for the floats).
/// Percentiles are since the process started.
#[derive(Debug, Clone, Copy, Default, Zeroable, ZeroCopySend)]
#[type_name("mtanet::ProcessStats/v2")]
#[repr(C)]
pub struct ProcessStats {
    /// `CLOCK_MONOTONIC` ns when published.
    pub stamp_ns: u64,
    /// The process's role, NUL-padded ASCII: "simulator", "predictor", "trainer".
    pub role: [u8; 16],
    pub pid: u32,
    /// Restarts by the supervisor before this process (from `MTANET_RESTARTS`; 0 under systemd).
    pub restarts: u32,
    /// Work done: simulator steps, predictor ticks, trainer updates.
    pub count: u64,
    /// `count` per second over the last interval (NaN in a process's first message).
    pub rate_hz: f32,
    /// Resident memory, kB, and CPU use over the last interval (100 = one core).
    pub cpu_percent: f32,
    pub rss_kb: u64,
    /// Latency of its unit of work, us: the whole step (simulator), the per-tick compute
    /// (predictor), an update (trainer).
    pub p50_us: f32,
    pub p99_us: f32,
    pub p999_us: f32,
    pub max_us: f32,
    /// Simulator: laps completed over all episodes.
    pub laps: u32,
    /// Simulator: steps whose command did not come in time.
    pub missed_commands: u32,
    /// Predictor: the [`crate::CommandSource`] of its last command.
    pub driver: u32,
    /// Predictor: times the fallback took over.
    pub fallbacks: u32,
    /// Predictor: the live model's next-frame error over copy-last (NaN: none yet).
    pub model_over_copy_last: f32,
    /// Predictor: weights put in use, refused (damaged or not fitting), and held back (their
    /// probe failed while the model in hand drove).
    pub weights_installed: u32,
    pub weights_rejected: u32,
    pub weights_held_back: u32,
    /// Predictor: the version of the weights in use (0: none).
    pub model_version: u64,
    /// Trainer: sequences in the replay buffer, and replay chunks lost.
    pub replay_sequences: u32,
    pub chunks_lost: u32,
    /// Trainer: the last update's loss (NaN: none yet).
    pub loss: f32,
    /// Trainer: weights this process published.
    pub weights_published: u32,
    /// Trainer: the update count of the checkpoint it resumed from (0: a fresh start).
    pub resumed_from_update: u64,
}

impl ProcessStats {
    pub fn set_role(&mut self, role: &str) {
        let b = role.as_bytes();
        let n = b.len().min(self.role.len());
        self.role = [0; 16];
        self.role[..n].copy_from_slice(&b[..n]);
    }

    pub fn role(&self) -> &str {
        let n = self
            .role
            .iter()
            .position(|&c| c == 0)
            .unwrap_or(self.role.len());
        core::str::from_utf8(&self.role[..n]).unwrap_or("?")
    }
}
