//! Real-time misses with when they happened (`CLOCK_MONOTONIC`, shared by a host's processes),
//! so that a soak can set them beside the machine's own pauses: a miss while the machine ran
//! nothing is the machine's, the rest are the stack's.

pub use mtanet_summaries::incident::{Incident, IncidentKind};

/// Incidents kept per run: enough for any run worth reading, bounded for one that goes wrong.
pub const MAX_INCIDENTS: usize = 10_000;

/// Records `kind` for `step`, from `start_ns` to now, while fewer than [`MAX_INCIDENTS`] are kept.
pub fn record(into: &mut Vec<Incident>, step: u64, kind: IncidentKind, start_ns: u64) {
    if into.len() < MAX_INCIDENTS {
        into.push(Incident {
            step,
            kind,
            start_ns,
            end_ns: crate::stamp::monotonic_ns(),
        });
    }
}
