use bytemuck::Zeroable;
use iceoryx2::prelude::ZeroCopySend;

/// What one process says of itself once a second on [`crate::names::STATS`], for `mta status`
/// (and a live view): one message type for every process, with the fields that do not apply to
/// it left at zero (NaN for the floats). Percentiles are since the process started.
#[derive(Debug, Clone, Copy, Default, Zeroable, ZeroCopySend)]
#[type_name("mtanet::ProcessStats/v1")]
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
    /// Simulator: laps; predictor: the [`crate::CommandSource`] of its last command; trainer:
    /// replay sequences held.
    pub laps_or_driver_or_fill: u32,
    /// Simulator: missed commands; predictor: fallbacks; trainer: replay chunks lost.
    pub faults: u32,
    /// Predictor: live model error / copy-last; trainer: last loss; simulator: NaN.
    pub quality: f32,
    pub _pad: u32,
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
