//! What the agent is configured with, what it reads each step and what it reports: its config,
//! the tick, the model's health, the decision and the counters; plus the stand-ins for a missing
//! model or planner.

use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::cost::CostConfig;
use crate::drive::Wheels;
use crate::planner::{MAX_HORIZON, Outcome, PlannerConfig};
use crate::worker::{PlanJob, PlanService};

/// Counters for reports (a plain data type of `mtanet-summaries`).
pub use mtanet_summaries::AgentStats;

/// Who decided a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Driver {
    Reactive,
    /// A random exploration segment while the reactive rule drives.
    Exploration,
    ActiveInference,
    /// The reactive rule after the line was lost under active inference.
    Fallback,
}

impl Driver {
    /// The same as the wire's and the reports' vocabulary.
    pub fn source(self) -> mtanet_summaries::CommandSource {
        use mtanet_summaries::CommandSource as S;
        match self {
            Driver::Reactive => S::Reactive,
            Driver::Exploration => S::Exploration,
            Driver::ActiveInference => S::ActiveInference,
            Driver::Fallback => S::Fallback,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AgentConfig {
    /// Drive by active inference once the model is trusted (otherwise only the reactive rule).
    pub enabled: bool,
    /// Trust the model once its next-frame error is below `trust_ratio` x copy-last...
    pub trust_ratio: f64,
    /// ...after this many model steps since its weights were loaded...
    pub trust_after_steps: u64,
    /// ...and its counterfactual probe (rank correlation) is at least this (-1: not needed).
    /// While the model in hand drives, newer weights must pass it too or they wait
    /// ([`crate::Agent::admits`]).
    pub min_probe: f64,
    /// Stop trusting it when its error has stayed above `distrust_ratio` x copy-last for
    /// `distrust_after_steps` model steps (the ratio swings when the car slows down: copying
    /// the last frame is then nearly right).
    pub distrust_ratio: f64,
    pub distrust_after_steps: u64,
    /// Under active inference, hand over to the reactive fallback when the line has been lost
    /// this long (no line sensor on and no line in the near half of the camera's view),
    /// seconds...
    pub fallback_after_s: f32,
    /// ...and take over again once the line has been found again for this long (and the middle
    /// sensor is on it).
    pub resume_after_s: f32,
    /// The fallback first drives back to where the line was last in sight (sensors or camera)
    /// if that was at most this long ago, seconds (0: only the reactive rule's search; `recovery.rs`).
    pub retrace_s: f32,
    /// Centred frames needed before the preference is used, and the newest kept.
    pub preference_frames: usize,
    pub preference_capacity: usize,
    /// Seconds only the middle line sensor must have been on before a frame counts as centred.
    pub preference_steady_s: f32,
    /// Real time: the share of its segment a plan may take, counted from when it is asked for
    /// (the planner stops improving it then; see `planner.rs`). The rest of the segment is
    /// slack for a busy machine to hand the plan over before it is needed.
    pub plan_budget: f64,
    /// Real time: how long the first step of a segment waits for its plan before it counts as
    /// late (the previous plan's next segment is used).
    pub plan_wait_ms: f64,
    /// Lockstep waits for every plan however long it takes (a dropped plan would make the run
    /// depend on the machine's speed), and logs a warning each time this much has passed.
    pub lockstep_wait_ms: f64,
    pub cost: CostConfig,
    pub planner: PlannerConfig,
    pub reflex: crate::reflex::ReflexConfig,
}

impl Default for AgentConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            trust_ratio: 0.8,
            trust_after_steps: 25,
            min_probe: 0.7,
            distrust_ratio: 1.5,
            distrust_after_steps: 50,
            fallback_after_s: 0.5,
            resume_after_s: 0.5,
            retrace_s: 3.0,
            preference_frames: 300,
            preference_capacity: 2000,
            preference_steady_s: 0.0,
            plan_budget: 0.6,
            plan_wait_ms: 2.0,
            lockstep_wait_ms: 2000.0,
            cost: CostConfig::default(),
            planner: PlannerConfig::default(),
            reflex: Default::default(),
        }
    }
}

impl AgentConfig {
    /// Refuses values that cannot work, naming the key.
    pub fn validate(&self) -> anyhow::Result<()> {
        anyhow::ensure!(
            self.plan_budget > 0.0 && self.plan_budget <= 1.0,
            "predictor.active_inference.plan_budget must be in (0, 1] (a share of the segment), not {}",
            self.plan_budget
        );
        crate::Planner::new(&self.planner).map(|_| ())
    }
}

/// One control step's input.
#[derive(Debug, Clone, Copy)]
pub struct Tick<'a> {
    /// The frame's control step (the simulator's count).
    pub step: u64,
    pub episode: u32,
    pub frame: &'a [f32],
    pub line: [bool; 3],
    /// The command applied during the step that led to this frame.
    pub applied: Wheels,
    /// The wheel velocities measured at this frame, rad/s (they lag the command).
    pub measured: Wheels,
    /// The simulator waits for every command (no deadline to keep).
    pub lockstep: bool,
}

/// How far the world model can be trusted.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Health {
    /// Recent next-frame error over the copy-last-frame error.
    pub model_over_copy: Option<f64>,
    /// Model steps since its weights were loaded.
    pub model_steps: u64,
    /// Counterfactual probe of the weights in use (rank correlation).
    pub probe: Option<f64>,
}

impl Health {
    /// For a model that is the world itself.
    pub const PERFECT: Health = Health {
        model_over_copy: Some(0.0),
        model_steps: u64::MAX,
        probe: Some(1.0),
    };
}

/// The world model as the agent uses it.
pub trait AgentModel {
    type Snapshot;
    /// Control steps per model step; `None` while there is no model.
    fn frame_skip(&self) -> Option<usize>;
    /// One model step with the frame seen and the segment's mean command.
    fn observe(&mut self, frame: &[f32], action: Wheels) -> anyhow::Result<()>;
    /// A new episode: forget the past.
    fn reset(&mut self);
    /// The state after the latest observation, for a plan to start from.
    fn snapshot(&mut self) -> anyhow::Result<Self::Snapshot>;
    fn health(&self) -> Health;
}

/// No world model yet (the predictor before the first weights): the agent only drives by rule.
pub struct Blind;

impl AgentModel for Blind {
    type Snapshot = ();
    fn frame_skip(&self) -> Option<usize> {
        None
    }
    fn observe(&mut self, _: &[f32], _: Wheels) -> anyhow::Result<()> {
        Ok(())
    }
    fn reset(&mut self) {}
    fn snapshot(&mut self) -> anyhow::Result<()> {
        Ok(())
    }
    fn health(&self) -> Health {
        Health::default()
    }
}

/// Plans nothing (goes with [`Blind`]).
pub struct NoPlans;

impl PlanService<()> for NoPlans {
    fn submit(&mut self, _: PlanJob<()>) -> anyhow::Result<()> {
        anyhow::bail!("no world model to plan with")
    }
    fn wait(&mut self, _: Duration) -> Option<crate::worker::PlanDone> {
        None
    }
    fn idle(&self) -> bool {
        true
    }
}

/// What the agent decided for one step.
#[derive(Debug, Clone, PartialEq)]
pub struct Decision {
    pub wheels: Wheels,
    pub driver: Driver,
    /// The plan taken up at this step, if any (with its compute time).
    pub plan: Option<(Outcome, Duration)>,
    /// What active inference plans to do from this step's segment on (empty otherwise).
    pub ahead: Ahead,
    /// The plan for the segment this step began was not there in time (the rest of the
    /// previous plan drives it).
    pub late_plan: bool,
}

/// The rest of the plan active inference drives by, from the segment of the step decided: the
/// car can follow it while no command comes (a paused predictor).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Ahead {
    /// The step this segment began at.
    pub first_step: u64,
    /// Control steps per segment (the model's frame skip).
    pub segment_steps: u32,
    len: usize,
    segments: [Wheels; MAX_HORIZON],
}

impl Ahead {
    /// Segments from `first_step` on (at most [`MAX_HORIZON`]; more are dropped).
    pub fn new(
        first_step: u64,
        segment_steps: u32,
        segments: impl IntoIterator<Item = Wheels>,
    ) -> Self {
        let mut a = Self {
            first_step,
            segment_steps,
            ..Self::default()
        };
        for w in segments.into_iter().take(MAX_HORIZON) {
            a.segments[a.len] = w;
            a.len += 1;
        }
        a
    }

    pub fn segments(&self) -> &[Wheels] {
        &self.segments[..self.len]
    }
}
