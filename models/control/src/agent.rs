//! The agent: who drives, step by step. The reactive rule (with exploration) drives until the
//! world model is trusted; then active inference plans through it; if the car loses the line
//! for too long the fallback drives back the way it came and the reactive rule drives until the
//! line is back.
//!
//! Timing. The model steps every `frame_skip` control steps (a *segment*); its action is the
//! mean command applied over the segment, which is exactly the held command when the planner
//! drives. At the first step of segment k the agent observes the frame, takes the plan made for
//! segment k (submitted at the start of segment k - 1) and submits the plan for segment k + 1,
//! starting from the model state rolled forward through the command of segment k (already sent).
//! So planning has a whole segment of wall time and no step waits for it in real time.

use std::collections::VecDeque;
use std::time::Duration;

use crate::cost::Cost;
use crate::drive::{Drive, Wheels, mean_wheels};
use crate::planner::{Outcome, PlanStats};
use crate::preference::{FrameShape, PreferenceLearner};
use crate::reactive::{ExplorationConfig, Explorer, Reactive, ReactiveConfig};
use crate::recovery::Recovery;
use crate::reflex::Reflex;
use crate::worker::PlanService;

mod handover;
mod plans;
mod types;
pub use types::*;

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
    reflex: Reflex,
    recovery: Recovery,
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
    /// A takeover in progress: the first plan was submitted this segment while the rule's
    /// command is held; active inference drives from the next segment if that plan is there.
    arming: bool,
    lost_ticks: u32,
    /// Steps in a row with the line found (a line sensor on, or the line in the camera's view).
    found_ticks: u32,
    /// Model steps in a row the model has looked worse than `distrust_ratio`.
    distrust_steps: u64,
    /// A segment's model step and plan submission, done after its command went out.
    deferred: Option<Deferred>,
    /// The latest tick's: lockstep plans have no deadline.
    lockstep: bool,
    pub stats: AgentStats,
    /// What the plans taken up could afford.
    pub planning: PlanStats,
}

struct Deferred {
    frame: Vec<f32>,
    action: Wheels,
    /// The plan to submit after the model step, if any.
    next: NextPlan,
}

/// Whether a segment's first step submits the plan for the segment after next.
#[derive(Debug, Clone, Copy, PartialEq)]
enum NextPlan {
    /// No plan: the rule drives on.
    None,
    /// The next plan, warm-started from the last one shifted by a segment.
    Continue,
    /// The first plan of a takeover, warm-started from holding this command.
    Restart(Drive),
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
            reflex: Reflex::new(&cfg.reflex, control_period_s),
            recovery: Recovery::new(cfg.retrace_s, reactive.cruise, control_period_s),
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
            arming: false,
            lost_ticks: 0,
            found_ticks: 0,
            distrust_steps: 0,
            deferred: None,
            lockstep: false,
            stats: AgentStats::default(),
            planning: PlanStats::default(),
        }
    }

    /// The current cost (the preference learnt so far), if any.
    pub fn cost(&self) -> Option<&Cost> {
        self.cost.as_ref()
    }

    pub fn driving_by_active_inference(&self) -> bool {
        self.mode == Mode::ActiveInference
    }

    /// Whether weights whose probe is `probe` may replace the model in hand. While the model in
    /// hand drives (active inference or its fallback), weights below `min_probe` are held back
    /// and the ones in hand go on driving: weights learning from the car's own plans lose
    /// probe for minutes at a time (0.80 to 0.57 in 11 minutes on the oval), and the weights
    /// that drive should be ones that passed. The trust ends by the model's own error
    /// (`distrust_ratio`); then any weights may be tried again while the rule drives.
    pub fn admits(&self, probe: Option<f64>) -> bool {
        self.mode == Mode::Reactive || probe.is_none_or(|p| self.passes_probe(p))
    }

    /// The one bar for the probe, for trust and for weights that replace a driving model.
    fn passes_probe(&self, probe: f64) -> bool {
        self.cfg.min_probe <= -1.0 || probe >= self.cfg.min_probe
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
        let model_tick = self.observe(t, model, plans);
        // Losing the line under active inference hands over to the fallback at once.
        if self.mode == Mode::ActiveInference
            && self.lost_ticks >= self.ticks(self.cfg.fallback_after_s)
        {
            tracing::warn!(
                segment = self.segment,
                "line lost under active inference: the reactive fallback drives"
            );
            self.mode = Mode::Fallback;
            self.stats.fallbacks += 1;
            self.spare.clear();
        }
        let late_before = self.stats.late_plans;
        let plan = if model_tick {
            self.choose_driver(t, model, plans)
        } else {
            None
        };
        let mut d = self.command(t, model, plan);
        d.late_plan = self.stats.late_plans > late_before;
        Ok(d)
    }

    /// Takes in what this step senses (a new episode, the preference, whether the line is
    /// lost); true when it begins a model segment, whose model step is deferred to `after`.
    fn observe<M, P>(&mut self, t: &Tick, model: &mut M, plans: &mut P) -> bool
    where
        M: AgentModel,
        P: PlanService<M::Snapshot>,
    {
        if self.episode != Some(t.episode) {
            if self.episode.is_some() {
                self.new_episode(model, plans, t.lockstep);
            }
            self.episode = Some(t.episode);
        }
        self.lockstep = t.lockstep;
        self.applied.push(t.applied);
        self.preference.observe(t.frame, t.line);
        self.reactive.observe(t.line);
        // Lost: no line sensor on *and* no line in the near half of the camera's view. The bar
        // leaves the line when the car cuts a tight bend while the camera still follows it.
        let lost = t.line == [false; 3] && !self.camera_sees_line(t.frame);
        self.recovery.observe(t.step, !lost, t.measured);
        self.lost_ticks = if lost { self.lost_ticks + 1 } else { 0 };
        self.found_ticks = if lost { 0 } else { self.found_ticks + 1 };

        let skip = model.frame_skip();
        let model_tick =
            skip.is_some_and(|s| self.ticks_in_segment == 0 || self.ticks_in_segment >= s);
        if model_tick {
            // The first frame of an episode follows the reset's zero command.
            let action = mean_wheels(&self.applied);
            self.applied.clear();
            self.deferred = Some(Deferred {
                frame: t.frame.to_vec(),
                action,
                next: NextPlan::None,
            });
            self.ticks_in_segment = 0;
            self.segment += 1;
        }
        if skip.is_some() {
            self.ticks_in_segment += 1;
        } else {
            self.applied.clear();
        }
        model_tick
    }

    /// The wheel command of this step, from the driver now in charge.
    fn command<M: AgentModel>(
        &mut self,
        t: &Tick,
        model: &M,
        plan: Option<(Outcome, Duration)>,
    ) -> Decision {
        if self.mode != Mode::ActiveInference {
            // The ramp integrates only what active inference drives.
            self.reflex.reset();
        }
        match self.mode {
            Mode::ActiveInference => {
                let w = self
                    .reflex
                    .apply(self.committed, t.line, self.reactive.last_side());
                let mut d = self.decided(w, Driver::ActiveInference, plan);
                d.ahead = self.ahead(t.step, model.frame_skip());
                d
            }
            // Arming: the rule's command held for the segment the first plan starts from.
            Mode::Fallback if self.arming => self.decided(self.committed, Driver::Fallback, None),
            Mode::Reactive if self.arming => self.decided(self.committed, Driver::Reactive, None),
            Mode::Fallback => {
                let back = self.recovery.retrace(t.line);
                let w = back.unwrap_or_else(|| self.reactive.act(t.line));
                self.decided(w, Driver::Fallback, None)
            }
            // Weights fit for control (a passing probe: a checkpoint, or a model learnt online,
            // by when the preference is long there) wait only for the preference, which learns
            // from centred frames: no exploration segments, which take the car off the line.
            Mode::Reactive if self.cost.is_none() && self.fit_for_control(&model.health()) => {
                let w = self.reactive.act(t.line);
                self.decided(w, Driver::Reactive, None)
            }
            Mode::Reactive => {
                let (w, exploring) = self.explorer.act(self.reactive.act(t.line));
                let d = if exploring {
                    Driver::Exploration
                } else {
                    Driver::Reactive
                };
                self.decided(w, d, None)
            }
        }
    }

    /// The segment under way and the spare segments after it, from the step it began at.
    fn ahead(&self, step: u64, frame_skip: Option<usize>) -> Ahead {
        let Some(skip) = frame_skip else {
            return Ahead::default();
        };
        // `observe` counted this step already.
        let begun = step.saturating_sub(self.ticks_in_segment.saturating_sub(1) as u64);
        let rest = self.spare.iter().map(|d| d.wheels());
        Ahead::new(
            begun,
            skip as u32,
            std::iter::once(self.committed).chain(rest),
        )
    }

    fn defer_submit(&mut self, next: NextPlan) {
        if let Some(d) = self.deferred.as_mut() {
            d.next = next;
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
        match d.next {
            NextPlan::None => {}
            NextPlan::Continue => self.submit(model, plans, None)?,
            NextPlan::Restart(from) => self.submit(model, plans, Some(from))?,
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

    fn decided(
        &mut self,
        wheels: Wheels,
        driver: Driver,
        plan: Option<(Outcome, Duration)>,
    ) -> Decision {
        let s = &mut self.stats;
        match driver {
            Driver::Reactive => s.reactive_steps += 1,
            Driver::Exploration => s.exploration_steps += 1,
            Driver::ActiveInference => s.active_inference_steps += 1,
            Driver::Fallback => s.fallback_steps += 1,
        }
        Decision {
            wheels,
            driver,
            plan,
            ahead: Ahead::default(),
            late_plan: false,
        }
    }

    fn refresh_cost(&mut self) {
        // The preference changes slowly: re-learn it every 50 model steps, or until first ready.
        self.cost_age += 1;
        if self.cost.is_none() || self.cost_age >= 50 {
            if let Some(p) = self.preference.preferred(self.cfg.preference_frames) {
                if self.cost.is_none() {
                    tracing::info!(centred_frames = p.frames, "preference learnt");
                }
                self.cost = Some(Cost::new(p, self.cfg.cost.clone()));
                self.cost_age = 0;
            }
        }
    }

    fn new_episode<M, P>(&mut self, model: &mut M, plans: &mut P, lockstep: bool)
    where
        M: AgentModel,
        P: PlanService<M::Snapshot>,
    {
        self.deferred = None;
        model.reset();
        self.reactive.reset();
        self.reflex.reset();
        self.recovery.reset();
        self.applied.clear();
        self.ticks_in_segment = 0;
        self.spare.clear();
        self.arming = false;
        if !plans.idle() {
            // Lockstep waits for it (reproducible runs); real time only takes it if it is done:
            // blocking here held a 50 Hz step for 24 ms once. A plan still out is taken up and
            // dropped at the next segment (its segment is past), and submitting skips a busy
            // planner.
            let _ = self.await_plan(plans, lockstep, Duration::ZERO);
        }
        if self.mode == Mode::ActiveInference {
            // Start planning afresh from the first frame of the new episode.
            self.mode = Mode::Fallback;
        }
    }
}

#[cfg(test)]
mod tests;
