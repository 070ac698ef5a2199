//! Per-step timing as percentiles (p50/p99/p99.9/max), never means: tails are what a control
//! loop feels.

use serde::{Deserialize, Serialize};

/// Percentiles of one timed quantity, in microseconds (what a report shows of a
/// `mtanet_ipc::latency::LatencyStats`).
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq)]
pub struct LatencySummary {
    pub count: u64,
    pub p50_us: f64,
    #[serde(default)]
    pub p90_us: f64,
    pub p99_us: f64,
    pub p999_us: f64,
    pub max_us: f64,
}

impl std::fmt::Display for LatencySummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "n={} p50={:.1}us p99={:.1}us p99.9={:.1}us max={:.1}us",
            self.count, self.p50_us, self.p99_us, self.p999_us, self.max_us
        )
    }
}
