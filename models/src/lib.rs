//! MTA-PredNet (multiple-timescale, action-modulated PredNet) in tch: the model, its training,
//! checkpoints, data sets, analysis and figures.
//!
//! - Predictor: build from a checkpoint (`checkpoint::from_bytes(&bytes)?.build()?`), keep a
//!   [`State`], call [`MtaPredNet::step`] with each frame and the action that led to it, and
//!   [`MtaPredNet::predict_candidates`] to compare K next actions. Run under
//!   `tch::no_grad_guard()` so the state carries no autograd graph.
//! - Trainer: [`Trainer::update`] on `[B, T, H, W]` windows (or [`Trainer::update_from`] to carry
//!   the state across windows), [`Trainer::checkpoint_bytes`] to publish weights.
//! - Offline: `mta train` / `mta synth`, [`analysis::analyse`] for metrics, slowness and figure.
//!
//! libtorch should run with one intra-op thread (`tch::set_num_threads(1)`): on 2 shared cores
//! two threads collapse 5-50x when another process holds a core (docs/measurements.md), and at 8x12 the ops
//! are too small to gain from splitting.

pub mod adam;
pub mod analysis;
pub mod checkpoint;
mod checkpoint_v1;
pub mod config;

pub mod data;
pub mod eval;
pub mod figure;
pub mod layer;
pub mod live;
pub mod model;
pub mod packed_conv;
pub mod reference;
pub mod sequences;
pub mod state;
pub mod synth;
pub mod train;
pub mod units;

pub use config::{ActionWeighting, ConfigError, ErrorLoss, ModelConfig};
pub use model::{ModelError, MtaPredNet, StepWeights};
pub use state::{LayerState, SequenceOutput, State, StepOutput};
pub use train::{TrainConfig, Trainer};

/// libtorch allocates and frees several hundred tensors per model step through malloc; glibc's
/// malloc spent ~15% of a training update in its own bookkeeping and page faults. mimalloc,
/// with its `override` feature, replaces malloc for the whole process (libtorch's calls
/// included) in every binary that links this crate: a training update ~10% faster, a rollout
/// ~8% (docs/measurements.md, "Model throughput").
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;
