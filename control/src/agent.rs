//! The agent: who drives, step by step. The reactive rule (with exploration) drives until the
//! world model is trusted; then active inference plans through it; if the car loses the line
//! for too long the reactive rule takes over as a fallback until the line is back.
//!
//! Timing. The model steps every `frame_skip` control steps (a *segment*); its action is the
//! mean command applied over the segment, which is exactly the held command when the planner
//! drives. At the first step of segment k the agent observes the frame, takes the plan made for
//! segment k (submitted at the start of segment k - 1) and submits the plan for segment k + 1,
//! starting from the model state rolled forward through the command of segment k (already sent).
//! So planning has a whole segment of wall time and no step waits for it in real time.

use std::collections::VecDeque;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::cost::{Cost, CostConfig};
use crate::drive::{Drive, Wheels, mean_wheels};
use crate::planner::{Outcome, PlannerConfig};
use crate::preference::{FrameShape, PreferenceLearner};
use crate::reactive::{ExplorationConfig, Explorer, Reactive, ReactiveConfig};
use crate::worker::{PlanJob, PlanService};

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
    /// Centred frames needed before the preference is used, and the newest kept.
    pub preference_frames: usize,
    pub preference_capacity: usize,
    /// Seconds only the middle line sensor must have been on before a frame counts as centred.
    pub preference_steady_s: f32,
    /// Real time: how long the first step of a segment waits for its plan before it counts as
    /// late (the previous plan's next segment is used). Lockstep waits up to `lockstep_wait_ms`.
    pub plan_wait_ms: f64,
    pub lockstep_wait_ms: f64,
    pub cost: CostConfig,
    pub planner: PlannerConfig,
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
            preference_frames: 300,
            preference_capacity: 2000,
            preference_steady_s: 0.0,
            plan_wait_ms: 2.0,
            lockstep_wait_ms: 2000.0,
            cost: CostConfig::default(),
            planner: PlannerConfig::default(),
        }
    }
}

/// One control step's input.
#[derive(Debug, Clone, Copy)]
pub struct Tick<'a> {
    pub episode: u32,
    pub frame: &'a [f32],
    pub line: [bool; 3],
    /// The command applied during the step that led to this frame.
    pub applied: Wheels,
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
}

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
    /// Times the line was lost under active inference and the fallback took over.
    pub fallbacks: u64,
    pub plans: u64,
    /// Segments whose plan was not ready in time (the previous plan's next segment drove).
    pub late_plans: u64,
    pub plan_errors: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Reactive,
    ActiveInference,
    Fallback,
}

pub struct Agent {
    cfg: AgentConfig,
    control_period_s: f32,
    reactive: Reactive,
    explorer: Explorer,
    preference: PreferenceLearner,
    cost: Option<Cost>,
    cost_age: u64,
    mode: Mode,
    episode: Option<u32>,
    /// Commands applied since the last model step.
    applied: Vec<Wheels>,
    ticks_in_segment: usize,
    segment: u64,
    committed: Wheels,
    /// The rest of the latest plan, for segments whose own plan is late.
    spare: VecDeque<Drive>,
    lost_ticks: u32,
    /// Steps in a row with the line found (a line sensor on, or the line in the camera's view).
    found_ticks: u32,
    /// Model steps in a row the model has looked worse than `distrust_ratio`.
    distrust_steps: u64,
    /// A segment's model step and plan submission, done after its command went out.
    deferred: Option<Deferred>,
    pub stats: AgentStats,
}

struct Deferred {
    frame: Vec<f32>,
    action: Wheels,
    /// Submit the next plan (with this warm-start restart) after the model step.
    submit: Option<Option<Drive>>,
}

impl Agent {
    pub fn new(
        cfg: &AgentConfig,
        reactive: &ReactiveConfig,
        exploration: &ExplorationConfig,
        shape: FrameShape,
        control_period_s: f32,
    ) -> Self {
        Self {
            cfg: cfg.clone(),
            control_period_s,
            reactive: Reactive::new(reactive),
            explorer: Explorer::new(exploration, control_period_s),
            preference: PreferenceLearner::new(
                shape,
                cfg.preference_capacity,
                (cfg.preference_steady_s / control_period_s).round() as u32,
            ),
            cost: None,
            cost_age: 0,
            mode: Mode::Reactive,
            episode: None,
            applied: Vec::new(),
            ticks_in_segment: 0,
            segment: 0,
            committed: [0.0; 2],
            spare: VecDeque::new(),
            lost_ticks: 0,
            found_ticks: 0,
            distrust_steps: 0,
            deferred: None,
            stats: AgentStats::default(),
        }
    }

    /// The current cost (the preference learnt so far), if any.
    pub fn cost(&self) -> Option<&Cost> {
        self.cost.as_ref()
    }

    pub fn driving_by_active_inference(&self) -> bool {
        self.mode == Mode::ActiveInference
    }

    fn ticks(&self, seconds: f32) -> u32 {
        (seconds / self.control_period_s).round().max(1.0) as u32
    }

    /// Decides the command for this control step.
    /// Decides this step's command and does the step's model work ([`Agent::tick`] then
    /// [`Agent::after`]): for callers that have no command to send in between.
    pub fn step<M, P>(&mut self, t: &Tick, model: &mut M, plans: &mut P) -> anyhow::Result<Decision>
    where
        M: AgentModel,
        P: PlanService<M::Snapshot>,
    {
        let d = self.tick(t, model, plans)?;
        self.after(model, plans)?;
        Ok(d)
    }

    /// Decides the command for this control step, fast: the model step and the next plan's
    /// submission that a segment's first step needs wait for [`Agent::after`], which the caller
    /// runs once the command is out (the command of a segment comes from the plan made a segment
    /// ago, so it does not need them).
    pub fn tick<M, P>(&mut self, t: &Tick, model: &mut M, plans: &mut P) -> anyhow::Result<Decision>
    where
        M: AgentModel,
        P: PlanService<M::Snapshot>,
    {
        // Catch up if the caller skipped `after` for the previous step.
        self.after(model, plans)?;
        if self.episode != Some(t.episode) {
            if self.episode.is_some() {
                self.new_episode(model, plans);
            }
            self.episode = Some(t.episode);
        }
        self.applied.push(t.applied);
        self.preference.observe(t.frame, t.line);
        self.reactive.observe(t.line);
        // Lost: no line sensor on *and* no line in the near half of the camera's view. The bar
        // leaves the line when the car cuts a tight bend while the camera still follows it.
        let lost = t.line == [false; 3] && !self.camera_sees_line(t.frame);
        self.lost_ticks = if lost { self.lost_ticks + 1 } else { 0 };
        self.found_ticks = if lost { 0 } else { self.found_ticks + 1 };

        let skip = model.frame_skip();
        let model_tick = skip.is_some_and(|s| self.ticks_in_segment == 0 || self.ticks_in_segment >= s);
        if model_tick {
            // The first frame of an episode follows the reset's zero command.
            let action = mean_wheels(&self.applied);
            self.applied.clear();
            self.deferred = Some(Deferred {
                frame: t.frame.to_vec(),
                action,
                submit: None,
            });
            self.ticks_in_segment = 0;
            self.segment += 1;
        }
        if skip.is_some() {
            self.ticks_in_segment += 1;
        } else {
            self.applied.clear();
        }

        // Losing the line under active inference hands over to the fallback at once.
        if self.mode == Mode::ActiveInference && self.lost_ticks >= self.ticks(self.cfg.fallback_after_s) {
            tracing::warn!(segment = self.segment, "line lost under active inference: the reactive fallback drives");
            self.mode = Mode::Fallback;
            self.stats.fallbacks += 1;
            self.spare.clear();
        }
        let mut plan = None;
        if model_tick {
            let health = model.health();
            let bad = health.model_over_copy.is_some_and(|r| r > self.cfg.distrust_ratio);
            self.distrust_steps = if bad { self.distrust_steps + 1 } else { 0 };
            match self.mode {
                Mode::ActiveInference if !self.still_trusted(&health) => {
                    tracing::warn!(?health, "world model no longer trusted: the reactive rule drives");
                    self.mode = Mode::Reactive;
                    self.stats.switches_to_reactive += 1;
                    self.spare.clear();
                }
                Mode::ActiveInference => plan = self.take_plan(t, plans),
                Mode::Reactive | Mode::Fallback => {
                    // Take over only with the car on the line (not in the middle of an
                    // exploration segment or a search).
                    let may_resume =
                        self.found_ticks >= self.ticks(self.cfg.resume_after_s) && t.line[1];
                    if may_resume && self.cost.is_some() && self.trusted(&health) {
                        if !plans.idle() {
                            // A plan still out from before the fallback: its segment is past.
                            let wait = self.cfg.lockstep_wait_ms / 1000.0;
                            let _ = plans.wait(Duration::from_secs_f64(wait));
                        }
                        // Hold the rule's command for this segment, so the plan's start is exact.
                        self.committed = self.reactive.act(t.line);
                        tracing::info!(segment = self.segment, ?health, from = ?self.mode, "active inference takes over");
                        self.mode = Mode::ActiveInference;
                        self.stats.switches_to_active_inference += 1;
                        self.spare.clear();
                        self.defer_submit(Some(Drive::from_wheels(self.committed)));
                        return Ok(self.decided(self.committed, Driver::ActiveInference, None));
                    }
                }
            }
            if self.mode == Mode::ActiveInference {
                self.defer_submit(None);
            }
        }
        Ok(match self.mode {
            Mode::ActiveInference => self.decided(self.committed, Driver::ActiveInference, plan),
            Mode::Fallback => {
                let w = self.reactive.act(t.line);
                self.decided(w, Driver::Fallback, None)
            }
            Mode::Reactive => {
                let (w, exploring) = self.explorer.act(self.reactive.act(t.line));
                let d = if exploring { Driver::Exploration } else { Driver::Reactive };
                self.decided(w, d, None)
            }
        })
    }

    fn defer_submit(&mut self, restart: Option<Drive>) {
        if let Some(d) = self.deferred.as_mut() {
            d.submit = Some(restart);
        }
    }

    /// The work of a segment's first step that its command did not wait for: the model step
    /// with the frame and the segment's mean command, the preference refresh, and submitting
    /// the plan for the next segment from the state just reached.
    pub fn after<M, P>(&mut self, model: &mut M, plans: &mut P) -> anyhow::Result<()>
    where
        M: AgentModel,
        P: PlanService<M::Snapshot>,
    {
        let Some(d) = self.deferred.take() else {
            return Ok(());
        };
        model.observe(&d.frame, d.action)?;
        self.refresh_cost();
        if let Some(restart) = d.submit {
            self.submit(model, plans, restart)?;
        }
        Ok(())
    }

    /// True when a row of the near half of the image holds at least half its usual line (by the
    /// learnt preference; without one, only the line sensors count).
    fn camera_sees_line(&self, frame: &[f32]) -> bool {
        let Some(cost) = &self.cost else {
            return false;
        };
        let p = &cost.preferred;
        let feat = crate::preference::LineFeature::of(frame, p.shape, &p.contrast);
        (p.shape.height / 2..p.shape.height).any(|r| feat.mass[r] >= 0.5 * p.mass_mean[r])
    }

    fn decided(&mut self, wheels: Wheels, driver: Driver, plan: Option<(Outcome, Duration)>) -> Decision {
        let s = &mut self.stats;
        match driver {
            Driver::Reactive => s.reactive_steps += 1,
            Driver::Exploration => s.exploration_steps += 1,
            Driver::ActiveInference => s.active_inference_steps += 1,
            Driver::Fallback => s.fallback_steps += 1,
        }
        Decision { wheels, driver, plan }
    }

    fn trusted(&self, h: &Health) -> bool {
        self.cfg.enabled
            && h.model_steps >= self.cfg.trust_after_steps
            && h.model_over_copy.is_some_and(|r| r <= self.cfg.trust_ratio)
            && (self.cfg.min_probe <= -1.0 || h.probe.is_some_and(|p| p >= self.cfg.min_probe))
    }

    fn still_trusted(&self, h: &Health) -> bool {
        self.cfg.enabled
            && self.distrust_steps < self.cfg.distrust_after_steps.max(1)
            && (self.cfg.min_probe <= -1.0 || h.probe.is_none_or(|p| p >= self.cfg.min_probe))
    }

    /// The plan for the segment starting now: the one submitted a segment ago, or, if it is late
    /// or failed, the rest of the previous plan.
    fn take_plan<P, S>(&mut self, t: &Tick, plans: &mut P) -> Option<(Outcome, Duration)>
    where
        P: PlanService<S>,
    {
        let wait_ms = if t.lockstep { self.cfg.lockstep_wait_ms } else { self.cfg.plan_wait_ms };
        let wanted = self.segment - 1;
        let mut fresh = None;
        if let Some(done) = plans.wait(Duration::from_secs_f64(wait_ms.max(0.0) / 1000.0)) {
            match done.outcome {
                Ok(o) if done.segment == wanted => fresh = Some((o, done.compute)),
                Ok(_) => {} // a late plan for a segment already past
                Err(e) => {
                    self.stats.plan_errors += 1;
                    tracing::error!("planning failed: {e:#}");
                }
            }
        }
        match fresh {
            Some((o, compute)) => {
                self.stats.plans += 1;
                self.committed = o.plan[0].wheels();
                self.spare = o.plan[1..].iter().copied().collect();
                Some((o, compute))
            }
            None => {
                self.stats.late_plans += 1;
                if let Some(d) = self.spare.pop_front() {
                    self.committed = d.wheels();
                }
                None
            }
        }
    }

    /// Submits the plan for the segment after this one, if the planner is free.
    fn submit<M, P>(&mut self, model: &mut M, plans: &mut P, restart: Option<Drive>) -> anyhow::Result<()>
    where
        M: AgentModel,
        P: PlanService<M::Snapshot>,
    {
        let Some(cost) = self.cost.clone() else {
            return Ok(());
        };
        if !plans.idle() {
            return Ok(()); // still busy with a late plan: this segment goes without
        }
        plans.submit(PlanJob {
            segment: self.segment,
            start: model.snapshot()?,
            committed: self.committed,
            cost,
            restart,
        })
    }

    fn refresh_cost(&mut self) {
        // The preference changes slowly: re-learn it every 50 model steps, or until first ready.
        self.cost_age += 1;
        if self.cost.is_none() || self.cost_age >= 50 {
            if let Some(p) = self.preference.preferred(self.cfg.preference_frames) {
                self.cost = Some(Cost::new(p, self.cfg.cost.clone()));
                self.cost_age = 0;
            }
        }
    }

    fn new_episode<M, P>(&mut self, model: &mut M, plans: &mut P)
    where
        M: AgentModel,
        P: PlanService<M::Snapshot>,
    {
        self.deferred = None;
        model.reset();
        self.reactive.reset();
        self.applied.clear();
        self.ticks_in_segment = 0;
        self.spare.clear();
        if !plans.idle() {
            let _ = plans.wait(Duration::from_secs_f64(self.cfg.lockstep_wait_ms / 1000.0));
        }
        if self.mode == Mode::ActiveInference {
            // Start planning afresh from the first frame of the new episode.
            self.mode = Mode::Fallback;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::Imagination;
    use crate::preference::tests::line_frame;
    use crate::worker::{Inline, PlanDone};

    /// A model that counts its steps and reports the health it is given.
    struct Toy {
        skip: usize,
        health: Health,
        observed: Vec<Wheels>,
    }

    impl AgentModel for Toy {
        type Snapshot = f32;
        fn frame_skip(&self) -> Option<usize> {
            Some(self.skip)
        }
        fn observe(&mut self, _: &[f32], a: Wheels) -> anyhow::Result<()> {
            self.observed.push(a);
            Ok(())
        }
        fn reset(&mut self) {}
        fn snapshot(&mut self) -> anyhow::Result<f32> {
            Ok(0.0)
        }
        fn health(&self) -> Health {
            self.health
        }
    }

    /// Imagines the line where it is, whatever the plan: every plan sees the same frames.
    struct Still;

    impl Imagination for Still {
        type Start = f32;
        fn start(&mut self, _: f32, _: Wheels) -> anyhow::Result<()> {
            Ok(())
        }
        fn imagine(&mut self, plans: &[Vec<Drive>]) -> anyhow::Result<Vec<Vec<f32>>> {
            Ok(plans.iter().map(|p| p.iter().flat_map(|_| line_frame(6.0, 0.0)).collect()).collect())
        }
    }

    /// A planner that never finishes in time.
    struct Never(bool);

    impl PlanService<f32> for Never {
        fn submit(&mut self, _: PlanJob<f32>) -> anyhow::Result<()> {
            self.0 = true;
            Ok(())
        }
        fn wait(&mut self, _: Duration) -> Option<PlanDone> {
            None
        }
        fn idle(&self) -> bool {
            !self.0
        }
    }

    fn cfg() -> AgentConfig {
        AgentConfig {
            preference_frames: 5,
            trust_after_steps: 2,
            ..Default::default()
        }
    }

    fn agent(cfg: &AgentConfig) -> Agent {
        let off = ExplorationConfig { enabled: false, ..Default::default() };
        Agent::new(cfg, &ReactiveConfig::default(), &off, FrameShape::CAR, 0.02)
    }

    fn tick<'a>(frame: &'a [f32], line: [bool; 3], applied: Wheels) -> Tick<'a> {
        Tick { episode: 0, frame, line, applied, lockstep: true }
    }

    const CENTRED: [bool; 3] = [false, true, false];

    #[test]
    fn drives_by_rule_until_trusted_then_plans_and_holds_each_segment() {
        let frame = line_frame(6.0, 0.0);
        let mut model = Toy { skip: 3, health: Health::default(), observed: Vec::new() };
        let mut plans = Inline::new(crate::Planner::new(&PlannerConfig::default()).unwrap(), Still);
        let mut a = agent(&cfg());
        let mut applied = [0.0; 2];
        for _ in 0..30 {
            let d = a.step(&tick(&frame, CENTRED, applied), &mut model, &mut plans).unwrap();
            assert_eq!(d.driver, Driver::Reactive, "an untrusted model never drives");
            applied = d.wheels;
        }
        assert_eq!(model.observed.len(), 10, "a model step every 3 control steps");
        assert_eq!(model.observed[1], [8.0, 8.0], "the mean command of its segment");
        model.health = Health { model_over_copy: Some(0.3), model_steps: 10, probe: Some(0.9) };
        let mut segments: Vec<Vec<Wheels>> = Vec::new();
        for k in 0..12 {
            let d = a.step(&tick(&frame, CENTRED, applied), &mut model, &mut plans).unwrap();
            assert_eq!(d.driver, Driver::ActiveInference, "step {k}");
            if k % 3 == 0 {
                segments.push(Vec::new());
            }
            segments.last_mut().unwrap().push(d.wheels);
            applied = d.wheels;
        }
        for s in &segments {
            assert!(s.iter().all(|w| *w == s[0]), "a command is held over its segment: {s:?}");
        }
        assert_eq!(a.stats.switches_to_active_inference, 1);
        assert_eq!(a.stats.plans, 3, "each later segment takes up the plan made a segment ago");
        // With the line held in view, only the priors decide: straight on, near the preferred speed.
        let d = Drive::from_wheels(segments[2][0]);
        assert!(d.turn.abs() < 2.0 && d.speed > 5.0, "{d:?}");
    }

    #[test]
    fn losing_the_line_hands_over_to_the_fallback_until_it_is_seen_again() {
        let frame = line_frame(6.0, 0.0);
        let trusted = Health { model_over_copy: Some(0.3), model_steps: 10, probe: Some(0.9) };
        let mut model = Toy { skip: 2, health: trusted, observed: Vec::new() };
        let mut plans = Inline::new(crate::Planner::new(&PlannerConfig::default()).unwrap(), Still);
        let mut a = agent(&cfg());
        for _ in 0..30 {
            a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans).unwrap();
        }
        assert!(a.driving_by_active_inference());
        // The bar off the line while the camera still sees it (cutting a bend): not lost.
        for _ in 0..40 {
            a.step(&tick(&frame, [false; 3], [8.0; 2]), &mut model, &mut plans).unwrap();
        }
        assert!(a.driving_by_active_inference(), "the camera still follows the line");
        // 0.5 s with neither a line sensor on nor a line in view (25 steps), then the fallback.
        let floor = [0.85f32; 96];
        let mut drivers = Vec::new();
        for _ in 0..30 {
            drivers.push(a.step(&tick(&floor, [false; 3], [8.0; 2]), &mut model, &mut plans).unwrap().driver);
        }
        assert_eq!(drivers.iter().filter(|d| **d == Driver::ActiveInference).count(), 24);
        assert_eq!(drivers.last(), Some(&Driver::Fallback));
        assert_eq!(a.stats.fallbacks, 1);
        // Found again for 0.5 s, the middle sensor on it: active inference resumes.
        let mut back = None;
        for k in 0..40 {
            let d = a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans).unwrap();
            if d.driver == Driver::ActiveInference {
                back = Some(k);
                break;
            }
        }
        let k = back.expect("active inference resumes");
        assert!((24..=26).contains(&k), "after ~25 steps with the line found, at a model step: {k}");
        assert_eq!(a.stats.switches_to_active_inference, 2);
    }

    #[test]
    fn a_late_plan_keeps_the_car_going_on_the_last_plan_and_is_counted() {
        let frame = line_frame(6.0, 0.0);
        let trusted = Health { model_over_copy: Some(0.3), model_steps: 10, probe: Some(0.9) };
        let mut model = Toy { skip: 2, health: trusted, observed: Vec::new() };
        let mut a = agent(&cfg());
        let mut never = Never(false);
        let mut last = [0.0; 2];
        for _ in 0..40 {
            let d = a.step(&Tick { lockstep: false, ..tick(&frame, CENTRED, last) }, &mut model, &mut never).unwrap();
            last = d.wheels;
        }
        assert!(a.driving_by_active_inference(), "planning late is no reason to stop");
        assert!(a.stats.late_plans >= 5, "{:?}", a.stats);
        assert_eq!(a.stats.plans, 0);
        assert_eq!(last, [8.0, 8.0], "the command held from the switch");
    }

    #[test]
    fn takes_over_only_with_the_car_on_the_line() {
        let frame = line_frame(6.0, 0.0);
        let trusted = Health { model_over_copy: Some(0.3), model_steps: 10, probe: Some(0.9) };
        let mut model = Toy { skip: 1, health: trusted, observed: Vec::new() };
        let mut plans = Inline::new(crate::Planner::new(&PlannerConfig::default()).unwrap(), Still);
        let mut a = agent(&cfg());
        for _ in 0..10 {
            a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans).unwrap();
        }
        // Trusted and a preference learnt, but the line is gone (an exploration segment).
        let floor = [0.85f32; 96];
        for _ in 0..40 {
            let d = a.step(&tick(&floor, [false; 3], [8.0; 2]), &mut model, &mut plans).unwrap();
            assert_ne!(d.driver, Driver::ActiveInference, "never taking over off the line");
        }
        let mut k = 0;
        while !a.driving_by_active_inference() {
            a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans).unwrap();
            k += 1;
            assert!(k < 30, "takes over once the line has been found for 0.5 s");
        }
        assert_eq!(k, 25);
        assert_eq!(a.stats.fallbacks, 0);
    }

    #[test]
    fn distrust_needs_a_sustained_bad_model_and_probe_gates_trust() {
        let frame = line_frame(6.0, 0.0);
        let low_probe = Health { model_over_copy: Some(0.3), model_steps: 10, probe: Some(0.2) };
        let mut model = Toy { skip: 1, health: low_probe, observed: Vec::new() };
        let mut plans = Inline::new(crate::Planner::new(&PlannerConfig::default()).unwrap(), Still);
        let mut a = agent(&cfg());
        for _ in 0..30 {
            a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans).unwrap();
        }
        assert!(!a.driving_by_active_inference(), "a probe below min_probe is not trusted");
        model.health.probe = Some(0.9);
        a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans).unwrap();
        assert!(a.driving_by_active_inference());
        // A ratio above distrust_ratio for fewer than distrust_after_steps model steps is a swing.
        model.health.model_over_copy = Some(2.0);
        for _ in 0..40 {
            a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans).unwrap();
        }
        assert!(a.driving_by_active_inference());
        for _ in 0..20 {
            a.step(&tick(&frame, CENTRED, [8.0; 2]), &mut model, &mut plans).unwrap();
        }
        assert!(!a.driving_by_active_inference(), "sustained: the rule drives again");
        assert_eq!(a.stats.switches_to_reactive, 1);
    }
}
