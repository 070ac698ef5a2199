//! `[trainer]` section of the stack's config file.

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainerConfig {
    /// Replay buffer capacity in chunks (each REPLAY_STEPS steps); the oldest is dropped beyond.
    pub replay_capacity: usize,
    /// Seconds of wall clock between progress log lines.
    pub log_every_s: f64,
    /// libtorch intra-op threads (1: never starve the predictor of the second core).
    pub torch_threads: i32,
}

impl Default for TrainerConfig {
    fn default() -> Self {
        Self {
            replay_capacity: 4096,
            log_every_s: 5.0,
            torch_threads: 1,
        }
    }
}
