//! `[trainer]` section of the stack's config file (with `[trainer.model]` and `[trainer.train]`).

use std::path::PathBuf;

use mtanet_models::{ModelConfig, TrainConfig};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainerConfig {
    /// Replay buffer capacity in chunks (each REPLAY_STEPS steps); the oldest is dropped beyond.
    pub replay_capacity: usize,
    /// Training starts once the buffer holds this many sequences (a batch of near-duplicates
    /// from the first second of driving would only overfit).
    pub min_sequences: usize,
    /// Publish the weights to the predictor every this many accepted updates.
    pub publish_every_updates: u64,
    /// Keep the latest checkpoint here (atomic writes) and resume from it at start; none: no disk.
    pub checkpoint_dir: Option<PathBuf>,
    /// Scheduling niceness of the trainer process: training yields the CPU to the predictor.
    pub nice: i32,
    /// Seconds of wall clock between progress log lines.
    pub log_every_s: f64,
    /// libtorch intra-op threads (1: never starve the predictor of the second core).
    pub torch_threads: i32,
    /// `[trainer.model]`: the network trained online.
    pub model: ModelConfig,
    /// `[trainer.train]`: optimiser and batch settings.
    pub train: TrainConfig,
}

impl Default for TrainerConfig {
    fn default() -> Self {
        Self {
            replay_capacity: 4096,
            min_sequences: 64,
            publish_every_updates: 50,
            checkpoint_dir: None,
            nice: 10,
            log_every_s: 5.0,
            torch_threads: 1,
            model: ModelConfig {
                // Wheel speeds of the line tracer are ~2..14 rad/s around a cruise of 7-8 (teacher
                // recordings: mean 6.6/7.6, std 1.7/1.0): centre and scale them so the action
                // MLP starts in its useful range instead of saturating on raw rad/s.
                action_offset: vec![7.0, 7.0],
                action_scale: vec![2.5, 2.5],
                ..ModelConfig::default()
            },
            train: TrainConfig::default(),
        }
    }
}
