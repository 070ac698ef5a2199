//! `[trainer]` section of the stack's config file (with `[trainer.model]` and `[trainer.train]`).

use std::path::PathBuf;

use mtanet_eval::ProbeConfig;
use mtanet_models::{ModelConfig, TrainConfig};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainerConfig {
    /// Replay buffer capacity in chunks (each REPLAY_STEPS steps); the oldest is dropped beyond.
    pub replay_capacity: usize,
    /// Training starts once the buffer holds this many chunks (a batch of near-duplicates
    /// from the first second of driving would only overfit).
    pub min_sequences: usize,
    /// Model steps per training window (each `model.frame_skip` control steps), cut from
    /// consecutive chunks of one episode.
    pub sequence_steps: usize,
    /// Mirror half the training windows left-right (images flipped, wheels swapped): the car
    /// is symmetric, so a track that turns one way also teaches the other.
    pub mirror: bool,
    /// Run the counterfactual probe every this many updates (0: never; the predictor then
    /// needs `min_probe = -1` to trust the model).
    pub probe_every_updates: u64,
    /// Publish the weights to the predictor every this many accepted updates.
    pub publish_every_updates: u64,
    /// Keep the latest checkpoint here (atomic writes) and resume from it at start; none: no disk.
    pub checkpoint_dir: Option<PathBuf>,
    /// Append one JSON line per update here (loss, gradient norm, update time, replay fill,
    /// chunks lost; `mta plot` draws it); none: no learning curve. `mta up` sets it to the run
    /// folder's `learning.jsonl`.
    pub learning_log: Option<PathBuf>,
    /// Niceness of the trainer process while the 50 Hz path runs on the normal scheduler (no
    /// privilege for SCHED_FIFO): training yields the CPU to the predictor.
    pub nice: i32,
    /// Niceness while the 50 Hz path runs SCHED_FIFO, which preempts the trainer whatever its
    /// niceness: the trainer then need not yield to other programs too (at 10 beside a CPU hog
    /// it learns ten times slower, docs/measurements.md).
    pub nice_beside_fifo: i32,
    /// Seconds of wall clock between progress log lines.
    pub log_every_s: f64,
    /// libtorch intra-op threads (1: never starve the predictor of the second core).
    pub torch_threads: i32,
    /// `[trainer.model]`: the network trained online. Keys a table leaves out keep the
    /// trainer's defaults (below), not the bare `ModelConfig`'s: `tau = [1, 1, 1]` alone must
    /// not also change the frame skip and the action scaling.
    #[serde(deserialize_with = "model_over_defaults")]
    pub model: ModelConfig,
    /// `[trainer.train]`: optimiser and batch settings (missing keys: the trainer's defaults).
    #[serde(deserialize_with = "train_over_defaults")]
    pub train: TrainConfig,
    /// `[trainer.probe]`: states, horizon and commands of the counterfactual probe.
    #[serde(deserialize_with = "probe_over_defaults")]
    pub probe: ProbeConfig,
}

impl Default for TrainerConfig {
    fn default() -> Self {
        Self {
            replay_capacity: 4096,
            min_sequences: 16,
            sequence_steps: 12,
            mirror: true,
            probe_every_updates: 50,
            publish_every_updates: 50,
            checkpoint_dir: None,
            learning_log: None,
            nice: 10,
            nice_beside_fifo: 0,
            log_every_s: 5.0,
            torch_threads: 1,
            model: ModelConfig {
                // Wheel speeds of the line tracer are ~2..14 rad/s around a cruise of 7-8 (teacher
                // recordings: mean 6.6/7.6, std 1.7/1.0): centre and scale them so the action
                // MLP starts in its useful range instead of saturating on raw rad/s.
                // With exploration the commands spread wider (2..19 rad/s): centre on cruise.
                action_offset: vec![8.0, 8.0],
                action_scale: vec![4.0, 4.0],
                // 0.1 s per model step: a command held for a segment visibly moves the view,
                // and a 0.4 s plan is 4 imagined steps, not 20.
                frame_skip: 5,
                ..ModelConfig::default()
            },
            train: TrainConfig {
                // The planner rolls the model out 1 + horizon steps: train it to.
                imagined_steps: 5,
                ..TrainConfig::default()
            },
            probe: ProbeConfig::default(),
        }
    }
}

/// `table` merged over `default` key by key (nested tables too), then typed: what a partial
/// sub-table of `[trainer]` means.
fn over_defaults<'de, D, T>(d: D, default: T) -> Result<T, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Serialize + serde::de::DeserializeOwned,
{
    use serde::de::Error;
    let given = toml::Table::deserialize(d)?;
    let mut merged = toml::Table::try_from(default).map_err(D::Error::custom)?;
    mtanet_summaries::files::merge_tables(&mut merged, &given);
    merged.try_into().map_err(D::Error::custom)
}

fn model_over_defaults<'de, D: serde::Deserializer<'de>>(d: D) -> Result<ModelConfig, D::Error> {
    over_defaults(d, TrainerConfig::default().model)
}

fn train_over_defaults<'de, D: serde::Deserializer<'de>>(d: D) -> Result<TrainConfig, D::Error> {
    over_defaults(d, TrainerConfig::default().train)
}

fn probe_over_defaults<'de, D: serde::Deserializer<'de>>(d: D) -> Result<ProbeConfig, D::Error> {
    over_defaults(d, TrainerConfig::default().probe)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<TrainerConfig, toml::de::Error> {
        toml::from_str(text)
    }

    /// A variant that changes only the taus keeps the trainer's frame skip, action scaling and
    /// imagined steps; a key of its own replaces only itself.
    #[test]
    fn a_partial_model_or_train_table_keeps_the_trainers_other_defaults() {
        let d = TrainerConfig::default();
        let c = parse("[model]\ntau = [1.0, 1.0, 1.0]\n[train]\nbatch_size = 4\n").unwrap();
        assert_eq!(c.model.tau, vec![1.0, 1.0, 1.0]);
        assert_eq!(c.model.frame_skip, d.model.frame_skip);
        assert_eq!(c.model.frame_skip, 5);
        assert_eq!(c.model.action_offset, d.model.action_offset);
        assert_eq!(c.model.action_scale, d.model.action_scale);
        assert_eq!(c.model.channels, d.model.channels);
        assert_eq!(c.train.batch_size, 4);
        assert_eq!(c.train.imagined_steps, d.train.imagined_steps);
        let none = parse("min_sequences = 16\n").unwrap();
        assert_eq!(none.model.frame_skip, 5);
        assert_eq!(none.min_sequences, 16);
    }

    #[test]
    fn an_unknown_key_in_a_sub_table_is_still_an_error_naming_it() {
        let e = parse("[model]\ntaux = [1.0]\n").unwrap_err().to_string();
        assert!(e.contains("taux"), "{e}");
        let e = parse("[model]\ntau = \"slow\"\n").unwrap_err().to_string();
        assert!(e.contains("tau") || e.contains("sequence"), "{e}");
    }
}
