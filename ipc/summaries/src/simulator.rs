//! What the simulator reports at exit (`--summary FILE.json`) and the data it holds: who drove
//! ([`ControlSummary`]), the lateral error, the lockstep pacing.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::incident::Incident;
use crate::latency::LatencySummary;

/// What the simulator reports at exit (`--summary FILE.json`).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Summary {
    pub steps: u64,
    /// Steps driven by a command from the predictor for that very step.
    pub commands_received: u64,
    /// Steps where a predictor was connected but its command did not come within the wait
    /// (`command_timeout_ms`, at most half a period in real time).
    pub missed_commands: u64,
    /// Steps whose command did not come in time but which the plan of the last command
    /// covered: the car followed that plan (not counted in `missed_commands`).
    #[serde(default)]
    pub plan_followed: u64,
    /// Commands that arrived for another step (late answers to earlier steps), dropped.
    pub stale_commands: u64,
    /// Non-finite commands rejected by the world.
    pub rejected_commands: u64,
    /// Steps driven by the teacher because no predictor was connected.
    pub teacher_steps: u64,
    pub replay_chunks_sent: u64,
    /// iceoryx2 nodes of crashed peers this simulator removed (after repeated missed commands).
    pub dead_nodes_cleaned: u64,
    /// Times the car was lost (or drove the wrong way) and was put back at the start.
    pub resets: u64,
    /// Of those, the times it drove the wrong way round.
    pub wrong_way_resets: u64,
    /// Times the car moved on to the next of several tracks (`simulator.also_tracks`). Episodes
    /// are 1 + resets + track_switches.
    #[serde(default)]
    pub track_switches: u64,
    /// Observation published -> its command received, as seen by the simulator.
    pub round_trip: LatencySummary,
    /// Wall time of one step's work (sensors, publishing, waiting for the command, physics);
    /// in real time without the wait for the next tick.
    pub step_time: LatencySummary,
    /// Real time: how far past its 50 Hz tick each step finished (floor 1 us).
    pub tick_late: LatencySummary,
    /// Command published by the predictor -> taken in here (transport and wake-up).
    pub cmd_to_sim: LatencySummary,
    /// Real time: how late each step started against its 50 Hz schedule.
    pub tick_jitter: LatencySummary,
    /// Steps whose work took longer than the control period (their tick was missed).
    pub overruns: u64,
    /// Real time: when each missed command and overrun happened (the first 10,000), so that a
    /// soak can tell the stack's own misses from the machine's pauses.
    #[serde(default)]
    pub incidents: Vec<Incident>,
    /// Histograms (upper bound in us, count), for pictures.
    pub step_time_hist: Vec<[f64; 2]>,
    pub round_trip_hist: Vec<[f64; 2]>,
    pub cmd_to_sim_hist: Vec<[f64; 2]>,
    pub laps: u32,
    pub lateral_error_m: LateralError,
    /// Who drove, and how well (per command source).
    pub control: ControlSummary,
    /// Lockstep pacing on the trainer's updates.
    pub pace: PaceSummary,
    pub sim_seconds: f64,
    pub wall_seconds: f64,
}

/// Who drove, and how well, per command source (the simulator knows every step's source).
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ControlSummary {
    /// Steps driven by each source (`reactive`, `exploration`, `active_inference`, `fallback`,
    /// `teacher`).
    pub steps: BTreeMap<String, u64>,
    /// Mean |lateral error| (m) over the steps of each source that drove.
    pub lateral_mean_m: BTreeMap<String, f64>,
    /// Changes from another source to active inference and back.
    pub switches: u64,
    /// Times the fallback took over (the line lost under active inference).
    pub fallbacks: u64,
    /// Share of the steps driven by exploration segments.
    pub exploration_fraction: f64,
    /// Laps completed while active inference drove every step since the lap before (or since
    /// it took over).
    pub laps_completed_under_active_inference: u32,
    /// Median simulated seconds of a whole lap (from one lap line crossing to the next in one
    /// episode), over every such lap, and over those active inference drove start to end.
    #[serde(default)]
    pub lap_time_s: Option<f64>,
    #[serde(default)]
    pub lap_time_active_inference_s: Option<f64>,
    /// The longest stretch the fallback drove without a break, seconds (0: none).
    #[serde(default)]
    pub longest_fallback_s: f64,
    /// Lateral error and fallbacks by the line's curvature under the sensor bar.
    #[serde(default)]
    pub by_curvature: Vec<CurvatureBin>,
}

/// Where on the line the steps were: |curvature| in `[min, max)` 1/m (curvature of the circle
/// through the line 10 cm either side of the sensor bar's projection).
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct CurvatureBin {
    pub min_curvature: f64,
    /// None: no upper bound.
    pub max_curvature: Option<f64>,
    /// Steps by active inference, and by any other source.
    pub steps_active_inference: u64,
    pub steps_other: u64,
    /// Mean |lateral error| (m) of those steps.
    pub lateral_active_inference_m: Option<f64>,
    pub lateral_other_m: Option<f64>,
    /// Fallbacks that began here.
    pub fallbacks: u64,
}

/// The bins' edges, 1/m: straights and sweeping arcs, the oval's 2.5 1/m bends, corners, and
/// hairpins from 5 and from 7.5 1/m (the square's corners are 10 1/m).
pub const CURVATURE_EDGES: [f64; 6] = [0.0, 1.5, 3.5, 5.0, 7.5, f64::INFINITY];

/// Mean and max of |lateral error| in metres.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq)]
pub struct LateralError {
    pub mean: f64,
    pub max: f64,
}

/// Lockstep pacing on the trainer's updates over the run.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct PaceSummary {
    /// The configured rate (0: not paced).
    pub target_updates_per_1000_steps: f64,
    /// Trainer updates per 1000 steps since pacing began (once the trainer trained).
    pub updates_per_1000_steps: f64,
    /// Steps since pacing began, and the trainer's updates in them.
    pub paced_steps: u64,
    pub trainer_updates: u64,
    /// Wall time spent waiting for the trainer.
    pub wait_seconds: f64,
}
