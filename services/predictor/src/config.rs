//! `[predictor]` section of the stack's config file.

use serde::{Deserialize, Serialize};

use crate::active_inference::ActiveInferenceConfig;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PredictorConfig {
    /// Forward wheel speed of the reactive rule, rad/s.
    pub cruise: f32,
    /// Wheel speed difference of the reactive rule when a side sensor sees the line, rad/s.
    pub turn: f32,
    /// Seconds of wall clock between progress log lines.
    pub log_every_s: f64,
    /// libtorch intra-op threads. One: on these tiny tensors dispatch dominates, and a second
    /// thread collapses throughput when another process holds the other core (FACTS.md).
    pub torch_threads: i32,
    /// `[predictor.active_inference]`: model-based control once the model is trusted.
    pub active_inference: ActiveInferenceConfig,
}

impl Default for PredictorConfig {
    fn default() -> Self {
        Self {
            cruise: 8.0,
            turn: 6.0,
            log_every_s: 5.0,
            torch_threads: 1,
            active_inference: ActiveInferenceConfig::default(),
        }
    }
}
