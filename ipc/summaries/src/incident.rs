//! Real-time misses with when they happened (`CLOCK_MONOTONIC`, shared by a host's processes),
//! so that a soak can set them beside the machine's own pauses: a miss while the machine ran
//! nothing is the machine's, the rest are the stack's.

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IncidentKind {
    /// The simulator had no command within its wait (half a period).
    MissedCommand,
    /// A simulator step's work took longer than a period.
    Overrun,
    /// The predictor's plan for a segment was not there when the segment began.
    LatePlan,
}

/// One miss, from the start of the work that missed to when the miss was known.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Incident {
    pub step: u64,
    pub kind: IncidentKind,
    pub start_ns: u64,
    pub end_ns: u64,
}
