//! The trainer's learning curve as read back: one JSON line per accepted update
//! (`learning.jsonl`; the trainer writes it, `mta plot` draws it).

use std::path::Path;

use anyhow::Context;
use serde::{Deserialize, Serialize};

/// One update as the curve records it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CurvePoint {
    /// Training step after this update (a resumed run goes on from its checkpoint's).
    pub step: u64,
    /// Seconds since this trainer process started.
    pub wall_s: f64,
    pub loss: f64,
    /// Global gradient L2 norm before clipping.
    pub grad_norm: f64,
    pub clipped: bool,
    /// Wall time of the update, ms.
    pub update_ms: f64,
    /// Replay sequences held, chunks received and lost so far.
    pub replay_sequences: usize,
    pub chunks_received: u64,
    pub chunks_lost: u64,
    /// Steps received from the simulator so far (the x axis against simulated time).
    pub steps_received: u64,
    /// The latest counterfactual probe, when there is one.
    pub probe: Option<f64>,
}

/// Reads a learning log; a torn last line (the trainer was killed while writing it) and any
/// other unreadable line are skipped and counted, never an error for the lines that are fine.
pub fn read(path: &Path) -> anyhow::Result<(Vec<CurvePoint>, usize)> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading the learning log {}", path.display()))?;
    let mut bad = 0;
    let points = text
        .lines()
        .filter(|l| !l.trim().is_empty())
        .filter_map(|l| serde_json::from_str(l).map_err(|_| bad += 1).ok())
        .collect();
    Ok((points, bad))
}
