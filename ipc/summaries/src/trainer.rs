//! What the trainer reports at exit (`--summary FILE.json`).

use serde::{Deserialize, Serialize};

use crate::latency::LatencySummary;

/// What the trainer reports at exit.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Summary {
    pub chunks_received: u64,
    /// Chunks missing from the sequence numbers (overwritten before they were read).
    pub chunks_lost: u64,
    pub steps_received: u64,
    /// Share of the steps received that exploration segments drove.
    pub exploration_fraction: f64,
    /// Chunks in the replay buffer at the end.
    pub buffered_sequences: usize,
    /// Updates made by this process (a resumed run's earlier ones not included).
    pub session_updates: u64,
    /// The latest counterfactual probe: training step and rank correlation.
    pub probe_step: Option<u64>,
    pub probe: Option<f64>,
    /// Accepted training updates (including those of a resumed checkpoint).
    pub updates: u64,
    /// Updates refused by the non-finite guard.
    pub updates_refused: u64,
    pub last_loss: Option<f64>,
    pub weights_published: u64,
    /// The update count of the checkpoint this trainer resumed from (0: a fresh start).
    #[serde(default)]
    pub resumed_from_update: u64,
    /// Wall time of one training update.
    pub update_time: LatencySummary,
}
