//! What the predictor reports at exit (`--summary FILE.json`).

use serde::{Deserialize, Serialize};

use crate::incident::Incident;
use crate::latency::LatencySummary;
use crate::{AgentStats, PlanningSummary};

/// What the predictor reports at exit.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Summary {
    pub observations: u64,
    pub commands_sent: u64,
    /// Observations not answered because a newer one was already waiting (after a pause of
    /// this process): the simulator had moved past them.
    #[serde(default)]
    pub superseded: u64,
    /// Observations whose step did not follow the previous one (lost or reordered).
    pub step_gaps: u64,
    pub weights_received: u64,
    /// Lockstep weights overwritten on the topic before this process took them (each should
    /// have driven from its own step; 0 in a run that replays).
    #[serde(default)]
    pub weights_lost: u64,
    /// Weights put in use.
    #[serde(default)]
    pub weights_installed: u64,
    /// Weights that failed to decode or did not fit; the previous model stayed in use.
    pub weights_rejected: u64,
    /// Weights whose probe failed while the model in hand drove: that one kept driving.
    #[serde(default)]
    pub weights_held_back: u64,
    pub model_version: u64,
    /// Who drove, switches, fallbacks, plans (late ones included).
    pub control: AgentStats,
    /// What the plans could afford in their time: iterations, candidates, the share cut.
    #[serde(default)]
    pub planning: PlanningSummary,
    /// When each late plan was due (from about when it was asked for), for a soak to set
    /// beside the machine's pauses.
    #[serde(default)]
    pub incidents: Vec<Incident>,
    /// Recent next-frame MSE of the model and of copying the last frame (the bar to beat).
    pub model_mse: Option<f64>,
    pub copy_last_mse: Option<f64>,
    /// Counterfactual probe of the weights in use.
    pub probe: Option<f64>,
    /// Observation published -> taken in by the predictor (transport and wake-up).
    pub obs_to_predictor: LatencySummary,
    /// Observation published -> command decided (transport in + own compute).
    pub observation_age: LatencySummary,
    /// Own compute per step until the command is sent (the model step included, every
    /// `frame_skip` steps, and waiting for a plan).
    pub compute: LatencySummary,
    /// Wall time of each plan taken up (computed on the planner's thread).
    pub plan: LatencySummary,
    /// Work after the command went out: the model step and submitting the next plan.
    pub after_command: LatencySummary,
    /// Histograms (upper bound in us, count) of `compute` and `obs_to_predictor`, for pictures.
    pub compute_hist: Vec<[f64; 2]>,
    pub obs_to_predictor_hist: Vec<[f64; 2]>,
}
