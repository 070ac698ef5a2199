//! MTA-PredNet (multiple-timescale, action-modulated PredNet) in tch: the model, its training,
//! checkpoints, data sets, analysis and figures.
//!
//! libtorch should run with one intra-op thread (`tch::set_num_threads(1)`): on 2 shared cores
//! two threads collapse 5-50x when another process holds a core (FACTS.md), and at 8x12 the ops
//! are too small to gain from splitting.

pub mod analysis;
pub mod checkpoint;
pub mod config;
pub mod convlstm;
pub mod data;
pub mod eval;
pub mod figure;
pub mod layer;
pub mod model;
pub mod state;
pub mod synth;
pub mod train;

pub use config::{ActionWeighting, ConfigError, ErrorLoss, ModelConfig};
pub use model::{ModelError, MtaPredNet};
pub use state::{LayerState, SequenceOutput, State, StepOutput};
pub use train::{TrainConfig, Trainer};
