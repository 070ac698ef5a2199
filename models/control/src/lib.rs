//! Active inference for the line tracer, as pure code: no IPC, no simulator, no tensors. The
//! predictor service and the offline drivers (the MuJoCo oracle, the counterfactual probe, the
//! evaluation on other tracks) use the same pieces:
//!
//! - [`preference`]: the preferred observation, learnt from the car's own centred frames, in a
//!   line-position feature of each image row;
//! - [`cost`]: expected free energy of a plan (risk + prior preferences for progress, low effort
//!   and smooth commands);
//! - [`planner`]: CEM over piecewise-constant commands through an [`planner::Imagination`];
//! - [`worker`]: where plans are computed (inline or on a thread);
//! - [`agent`]: who drives each step (reactive rule with exploration, active inference, fallback);
//! - [`reactive`]: the line-sensor rule and the exploration segments;
//! - [`recovery`]: how the fallback finds a lost line (driving back the way it came).

pub mod agent;
pub mod cost;
pub mod drive;
pub mod planner;
pub mod preference;
pub mod reactive;
pub mod recovery;
pub mod reflex;
pub mod worker;

pub use agent::{
    Agent, AgentConfig, AgentModel, AgentStats, Ahead, Blind, Decision, Driver, Health, NoPlans,
    Tick,
};
pub use cost::{Cost, CostConfig, Terms};
pub use drive::{Drive, Wheels};
pub use planner::{
    Imagination, MAX_HORIZON, Outcome, PlanStats, Planner, PlannerConfig, PlanningSummary,
};
pub use preference::{FrameShape, PreferenceLearner, PreferredLine};
pub use reactive::{ExplorationConfig, Explorer, Reactive, ReactiveConfig};
pub use recovery::Recovery;
pub use worker::{Inline, PlanJob, PlanService, Threaded};
