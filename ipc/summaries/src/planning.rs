//! What the plans could afford over a run: iterations, candidates, how many a deadline cut, the
//! cost they reached and what a rollout cost. For reports (`report.json`, `soak.json`, logs).

use serde::{Deserialize, Serialize};

/// Per plan taken up: p50 and minimum of the iterations and candidates it could afford, the
/// share its deadline cut, and the expected free energy of the plans chosen.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PlanningSummary {
    pub plans: u64,
    /// Plans the deadline stopped short of the configured iterations or candidates.
    pub cut: u64,
    pub cut_share: f64,
    /// Plans the deadline stopped before anything was scored (the warm start drove unscored).
    pub unscored: u64,
    pub iterations_p50: f64,
    pub iterations_min: u32,
    /// Candidates per CEM iteration (the fewest of each plan's iterations).
    pub candidates_p50: f64,
    pub candidates_min: u32,
    /// Expected free energy of the plans chosen (lower is better).
    pub cost_p50: f64,
    pub cost_p90: f64,
    /// Measured wall time of a rollout per candidate-segment, microseconds.
    pub rollout_us_per_candidate_segment_p50: f64,
}

impl std::fmt::Display for PlanningSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "n={} iterations p50={} min={} candidates p50={} min={} cut={:.0}% cost p50={:.2}",
            self.plans,
            self.iterations_p50,
            self.iterations_min,
            self.candidates_p50,
            self.candidates_min,
            100.0 * self.cut_share,
            self.cost_p50
        )
    }
}
