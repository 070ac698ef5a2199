//! MTA-PredNet (multiple-timescale, action-modulated PredNet) in tch: the model, its training,
//! checkpoints, data sets and the layers' timescales.
//!
//! - Predictor: build from a checkpoint (`checkpoint::from_bytes(&bytes)?.build()?`), keep a
//!   [`State`], call [`MtaPredNet::step`] with each frame and the action that led to it, and
//!   [`MtaPredNet::predict_candidates`] to compare K next actions. Run under
//!   `tch::no_grad_guard()` so the state carries no autograd graph.
//! - Trainer: [`Trainer::update`] on `[B, T, H, W]` windows (or [`Trainer::update_from`] to carry
//!   the state across windows), [`Trainer::checkpoint_bytes`] to publish weights.
//! - Offline: `mta train` / `mta synth`, [`analysis::timescales`] for the layers' timescales
//!   (the figure strip and the held-out report are `mtanet-offline`'s).
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
pub mod layer;
pub mod live;
pub mod model;
pub mod packed_conv;
pub mod reference;
pub mod sequences;
pub mod state;
pub mod synth;
pub mod timescale;
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

/// mimalloc's option `mi_option_purge_delay`: milliseconds before freed memory goes back to the
/// OS (1000 by default in the v3 the crate builds), -1 never. Its index in `mi_option_e`
/// (`mimalloc.h`; a test checks the default at this index).
const MI_OPTION_PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

/// Keeps freed memory in the process instead of handing it back to the OS. A training update
/// or a plan allocates and frees the same tensors over and over: with mimalloc's default the
/// trainer made ~140 `madvise` calls and ~800 page faults a second and the predictor ~1,200
/// faults, kernel work during which, on the VMs here, a real-time task woken on the same core
/// waited up to 13-22 ms (docs/measurements.md, "The loop stall"). RSS then stays at its
/// high-water mark, which a steady workload reaches within minutes. Call it first in `main`.
pub fn retain_freed_memory() {
    // SAFETY: sets a process-wide allocator option; safe to call at any time.
    unsafe { libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, -1) };
}

#[cfg(test)]
mod allocator_tests {
    use super::*;

    #[test]
    fn freed_memory_is_retained_once_asked() {
        // SAFETY: reads an allocator option.
        let get = || unsafe { libmimalloc_sys::mi_option_get(MI_OPTION_PURGE_DELAY) };
        assert_eq!(
            get(),
            1000,
            "the index names mimalloc's purge delay (default 1000 ms)"
        );
        retain_freed_memory();
        assert_eq!(get(), -1);
    }
}
