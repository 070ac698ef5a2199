//! Who drives at a segment's start: active inference while the model stays trusted, the hand-over
//! to it (arming with the rule's command held, then a fresh plan), and the trust and distrust
//! that decide it from the model's error and probe.

use std::time::Duration;

use super::{Agent, AgentModel, Health, Mode, NextPlan, Tick};
use crate::drive::Drive;
use crate::planner::Outcome;
use crate::worker::PlanService;

impl Agent {
    /// At a segment's start: who drives on, from the model's health and the line; the plan
    /// in force when active inference drives.
    pub(super) fn choose_driver<M, P>(
        &mut self,
        t: &Tick,
        model: &mut M,
        plans: &mut P,
    ) -> Option<(Outcome, Duration)>
    where
        M: AgentModel,
        P: PlanService<M::Snapshot>,
    {
        let health = model.health();
        self.judge_error(health.model_over_copy);
        let mut plan = None;
        match self.mode {
            Mode::ActiveInference if !self.still_trusted() => {
                tracing::warn!(
                    ?health,
                    "world model no longer trusted: the reactive rule drives"
                );
                self.mode = Mode::Reactive;
                self.stats.switches_to_reactive += 1;
                self.spare.clear();
            }
            Mode::ActiveInference => plan = self.take_plan(t, plans),
            Mode::Reactive | Mode::Fallback if self.arming => {
                // Active inference takes the wheel only with a fresh plan in hand: without
                // one it would hold the rule's last command for whole segments, which can
                // leave the line in a bend.
                self.arming = false;
                if let Some(p) = self.fresh_plan(t, plans) {
                    tracing::info!(segment = self.segment, ?health, from = ?self.mode, "active inference takes over");
                    self.take_over(&p.0);
                    plan = Some(p);
                }
            }
            Mode::Reactive | Mode::Fallback => self.consider_resuming(t, &health, plans),
        }
        if self.mode == Mode::ActiveInference {
            self.defer_submit(NextPlan::Continue);
        }
        plan
    }

    pub(super) fn take_over(&mut self, plan: &Outcome) {
        self.mode = Mode::ActiveInference;
        self.recovery.reset();
        self.stats.switches_to_active_inference += 1;
        let s = &mut self.stats;
        s.first_takeover_step.get_or_insert(
            s.reactive_steps + s.exploration_steps + s.active_inference_steps + s.fallback_steps,
        );
        self.adopt(plan);
    }

    /// Under the rule or the fallback: with the car on the line and the model trusted, hold the
    /// rule's command for this segment and plan the next from it (arming).
    pub(super) fn consider_resuming<P, S>(&mut self, t: &Tick, health: &Health, plans: &mut P)
    where
        P: PlanService<S>,
    {
        // Take over only with the car on the line (not in the middle of an exploration
        // segment or a search).
        let may_resume = self.found_ticks >= self.ticks(self.cfg.resume_after_s) && t.line[1];
        let trusted = self.trusted(health);
        if may_resume && self.mode == Mode::Fallback && !trusted {
            // The line is found again but the model has lost its trust meanwhile: the
            // fallback's job is done, and the rule (exploring while learning) drives until
            // the model earns trust again.
            tracing::info!(
                segment = self.segment,
                ?health,
                "line found again; the world model is not trusted: the reactive rule drives"
            );
            self.mode = Mode::Reactive;
            self.recovery.reset();
        }
        if may_resume && self.cost.is_some() && trusted {
            if !plans.idle() {
                // A plan still out from before the fallback: its segment is past.
                let _ = self.await_plan(plans, t.lockstep, Duration::ZERO);
            }
            // Hold the rule's command for this segment, so the plan's start is exact, and plan
            // the next one from it.
            self.committed = self.reactive.act(t.line);
            self.arming = true;
            self.spare.clear();
            self.defer_submit(NextPlan::Restart(Drive::from_wheels(self.committed)));
        }
    }

    /// Counts the model steps in a row its error stayed above `distrust_ratio`; NaN compares
    /// false with everything, so the test is for "not good", not for "bad". A model predicting NaN
    /// or inf gets no grace: the rule drives from this step on.
    pub(super) fn judge_error(&mut self, ratio: Option<f64>) {
        self.distrust_steps = if ratio.is_some_and(|r| !r.is_finite()) {
            self.cfg.distrust_after_steps.max(1)
        } else if ratio.is_some_and(|r| !(r <= self.cfg.distrust_ratio)) {
            self.distrust_steps + 1
        } else {
            0
        };
    }

    pub(super) fn trusted(&self, h: &Health) -> bool {
        self.fit_for_control(h)
            && h.model_steps >= self.cfg.trust_after_steps
            && h.model_over_copy.is_some_and(|r| r <= self.cfg.trust_ratio)
    }

    /// Weights whose probe passes: fit to plan with, once their error is seen to be low.
    pub(super) fn fit_for_control(&self, h: &Health) -> bool {
        self.cfg.enabled
            && (self.cfg.min_probe <= -1.0 || h.probe.is_some_and(|p| self.passes_probe(p)))
    }

    /// The probe no longer counts here: weights that fail it are not installed while the model
    /// in hand drives ([`Agent::admits`]).
    pub(super) fn still_trusted(&self) -> bool {
        self.cfg.enabled && self.distrust_steps < self.cfg.distrust_after_steps.max(1)
    }
}
