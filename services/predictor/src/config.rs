//! `[predictor]` section of the stack's config file.

use mtanet_control::{AgentConfig, ExplorationConfig, ReactiveConfig};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PredictorConfig {
    /// Seconds of wall clock between progress log lines.
    pub log_every_s: f64,
    /// libtorch intra-op threads. One: on these tiny tensors dispatch dominates, and a second
    /// thread collapses throughput when another process holds the other core.
    pub torch_threads: i32,
    /// SCHED_FIFO priority of the planner's thread when the control loop runs real-time
    /// (always below the loop's): plans come before the trainer and every other normal
    /// program, never before a command (docs/measurements.md, "Sharing the CPU"). 0: the
    /// normal scheduler at `helpers_nice`, as without the privilege.
    pub planner_priority: i32,
    /// Niceness of the control loop's helper threads: the weights loader always, the planner on
    /// the normal scheduler (a config may also call it `planner_nice`).
    #[serde(alias = "planner_nice")]
    pub helpers_nice: i32,
    /// `[predictor.reactive]`: the line-sensor rule before the model is trusted, and fallback.
    pub reactive: ReactiveConfig,
    /// `[predictor.exploration]`: random command segments while the reactive rule drives.
    pub exploration: ExplorationConfig,
    /// `[predictor.active_inference]` (with `.cost` and `.planner`): when the model is
    /// trusted, and how plans are made and scored.
    pub active_inference: AgentConfig,
}

impl Default for PredictorConfig {
    fn default() -> Self {
        Self {
            log_every_s: 5.0,
            torch_threads: 1,
            planner_priority: 10,
            helpers_nice: 5,
            reactive: ReactiveConfig::default(),
            exploration: ExplorationConfig::default(),
            active_inference: AgentConfig::default(),
        }
    }
}
