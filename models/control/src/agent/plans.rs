//! The agent's side of planning: taking up the plan made a segment ago (or the rest of the last
//! one when it is late) and submitting the next.

use std::time::{Duration, Instant};

use super::{Agent, AgentModel, Tick};
use crate::drive::Drive;
use crate::planner::Outcome;
use crate::worker::{PlanDone, PlanJob, PlanService};

impl Agent {
    /// The outstanding plan's result. Real time waits at most `real_time` (a late plan is
    /// dropped: the step must go out). Lockstep waits for as long as the plan takes, saying so
    /// every `lockstep_wait_ms`: dropping it would make the run depend on the machine's speed
    /// (on a loaded machine a niced planner thread took over 2 s, and two runs of the same
    /// lockstep experiment differed). `None` when nothing is outstanding or real time gave up.
    pub(super) fn await_plan<P, S>(
        &self,
        plans: &mut P,
        lockstep: bool,
        real_time: Duration,
    ) -> Option<PlanDone>
    where
        P: PlanService<S>,
    {
        if !lockstep {
            return plans.wait(real_time);
        }
        let every = Duration::from_secs_f64(self.cfg.lockstep_wait_ms.max(1.0) / 1000.0);
        let asked = Instant::now();
        while !plans.idle() {
            if let Some(done) = plans.wait(every) {
                return Some(done);
            }
            tracing::warn!(
                segment = self.segment,
                waited_s = asked.elapsed().as_secs_f64(),
                "lockstep: the plan is not done yet; waiting for it (a lockstep plan is never late)"
            );
        }
        None
    }

    /// The plan submitted a segment ago, if it is done in time (`plan_wait_ms` in real time).
    pub(super) fn fresh_plan<P, S>(
        &mut self,
        t: &Tick,
        plans: &mut P,
    ) -> Option<(Outcome, Duration)>
    where
        P: PlanService<S>,
    {
        let wait = Duration::from_secs_f64(self.cfg.plan_wait_ms.max(0.0) / 1000.0);
        let wanted = self.segment - 1;
        let done = self.await_plan(plans, t.lockstep, wait)?;
        match done.outcome {
            Ok(o) if done.segment == wanted => Some((o, done.compute)),
            Ok(_) => None, // a late plan for a segment already past
            Err(e) => {
                self.stats.plan_errors += 1;
                tracing::error!("planning failed: {e:#}");
                None
            }
        }
    }

    /// Drives the plan's first segment now and keeps the rest for late plans.
    pub(super) fn adopt(&mut self, o: &Outcome) {
        self.stats.plans += 1;
        self.planning.record(o);
        self.committed = o.plan[0].wheels();
        self.spare = o.plan[1..].iter().copied().collect();
    }

    /// The plan for the segment starting now: the one submitted a segment ago, or, if it is late
    /// or failed, the rest of the previous plan.
    pub(super) fn take_plan<P, S>(&mut self, t: &Tick, plans: &mut P) -> Option<(Outcome, Duration)>
    where
        P: PlanService<S>,
    {
        match self.fresh_plan(t, plans) {
            Some(p) => {
                self.adopt(&p.0);
                Some(p)
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
    pub(super) fn submit<M, P>(
        &mut self,
        model: &mut M,
        plans: &mut P,
        restart: Option<Drive>,
    ) -> anyhow::Result<()>
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
        let asked = Instant::now();
        let deadline = match model.frame_skip() {
            Some(skip) if !self.lockstep => Some(asked + self.plan_budget(skip)),
            _ => None,
        };
        plans.submit(PlanJob {
            segment: self.segment,
            start: model.snapshot()?,
            committed: self.committed,
            cost,
            restart,
            asked,
            deadline,
        })
    }

    /// Real time: the wall time a plan may take, `plan_budget` of its segment (the rest is
    /// slack for handing it over before the segment starts).
    pub(super) fn plan_budget(&self, frame_skip: usize) -> Duration {
        let segment_s = frame_skip as f64 * f64::from(self.control_period_s);
        Duration::from_secs_f64((self.cfg.plan_budget * segment_s).max(0.0))
    }
}
