//! The active-inference agent's counters over a run (who drove, switches, fallbacks, plans).

use serde::{Deserialize, Serialize};

/// Counters for reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct AgentStats {
    pub reactive_steps: u64,
    pub exploration_steps: u64,
    pub active_inference_steps: u64,
    pub fallback_steps: u64,
    /// Switches to active inference, and back to the reactive rule because trust was lost.
    pub switches_to_active_inference: u64,
    pub switches_to_reactive: u64,
    /// Control steps decided before active inference first took the wheel.
    pub first_takeover_step: Option<u64>,
    /// Times the line was lost under active inference and the fallback took over.
    pub fallbacks: u64,
    pub plans: u64,
    /// Segments whose plan was not ready in time (the previous plan's next segment drove).
    pub late_plans: u64,
    pub plan_errors: u64,
}
