//! Receding-horizon planning by the cross-entropy method over piecewise-constant commands, as an
//! anytime algorithm.
//!
//! A plan is `horizon` segments, each a [`Drive`] held for one model step (`frame_skip` control
//! steps). Each call first scores the warm start (the previous plan shifted by one segment) with
//! fixed candidates (straight on, three constant turns each way), so it has a plan in hand; then
//! CEM iterations sample candidates around the warm start, have the imagination roll each batch
//! out, score the imagined frames by expected free energy ([`crate::cost`]) and refit a Gaussian
//! to the elites; the best plan seen wins.
//!
//! With a deadline (real time) the planner sizes every batch from what rollouts have cost on
//! this machine ([`budget::RolloutCost`]), runs the configured iterations only while they fit,
//! and has the imagination give up a batch between two imagined steps once the deadline has
//! passed: a slow or busy CPU plans less well, never late. Without one (lockstep, offline) the
//! configured work always runs to the end, so plans are reproducible.

use std::time::Instant;

use anyhow::ensure;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::cost::{Cost, Terms};
use crate::drive::{Drive, Wheels};

pub mod budget;
mod stats;
pub use stats::{PlanStats, PlanningSummary};

/// Rolls candidate plans out through a model of the world.
pub trait Imagination {
    /// What a plan starts from: the model's state after the latest observation.
    type Start;
    /// Sets the start of the next [`Imagination::imagine`] calls: `from`, rolled forward through
    /// `committed`, the command already sent for the segment in progress (delay compensation:
    /// the plan is for the segment after it).
    fn start(&mut self, from: Self::Start, committed: Wheels) -> anyhow::Result<()>;
    /// For each plan, the frame expected at the end of each of its segments, concatenated:
    /// `plans.len()` vectors of `segments x pixels` grey values.
    fn imagine(&mut self, plans: &[Vec<Drive>]) -> anyhow::Result<Vec<Vec<f32>>>;
    /// [`Imagination::imagine`], given up (`None`) when `deadline` has passed between two
    /// imagined steps. The default rolls out to the end (an imagination that cannot stop
    /// half-way; only the batch sizing then keeps the deadline).
    fn imagine_until(
        &mut self,
        plans: &[Vec<Drive>],
        deadline: Instant,
    ) -> anyhow::Result<Option<Vec<Vec<f32>>>> {
        let _ = deadline;
        self.imagine(plans).map(Some)
    }
    /// The clock deadlines are kept by and rollouts are timed on. Default: the wall clock; a
    /// test's imagination can run on a clock of its own and so check timing exactly.
    fn now(&self) -> Instant {
        Instant::now()
    }
    /// Rolls a batch of each of `batch_sizes` out once, before plans with deadlines (a model's
    /// first batch of a new size can cost several times a later one). Default: nothing to do.
    fn warm_up(&mut self, batch_sizes: &[usize], horizon: usize) -> anyhow::Result<()> {
        let _ = (batch_sizes, horizon);
        Ok(())
    }
}

/// The longest plan, in segments: the room a command has to carry it (`mtanet_ipc::PLAN_SEGMENTS`).
pub const MAX_HORIZON: usize = 8;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlannerConfig {
    /// Segments per plan (each one model step of `frame_skip` control steps).
    pub horizon: usize,
    /// Candidates per CEM iteration (the best plan so far included); with a deadline, at most.
    pub samples: usize,
    /// Best candidates the next iteration's Gaussian is fitted to.
    pub elites: usize,
    /// CEM iterations after the warm start's batch; with a deadline, at most.
    pub iterations: usize,
    /// Forward speed bounds, rad/s. The top is the rule's cruise plus one: faster, active
    /// inference drifts off the line in bends sharper than it learnt on; at 9 it keeps about
    /// the rule's error and still laps no slower (docs/experiments.md, "generalise").
    pub min_speed: f32,
    pub max_speed: f32,
    /// Turn bound (|turn|), rad/s.
    pub max_turn: f32,
    /// Initial standard deviation of speed and turn around the warm start.
    pub speed_std: f32,
    pub turn_std: f32,
    /// Seed of the sampling (plans are reproducible).
    pub seed: u64,
}

impl Default for PlannerConfig {
    fn default() -> Self {
        Self {
            horizon: 4,
            samples: 32,
            elites: 6,
            iterations: 3,
            min_speed: 2.0,
            max_speed: 9.0,
            max_turn: 8.0,
            speed_std: 3.0,
            turn_std: 2.0,
            seed: 0,
        }
    }
}

/// What one call of [`Planner::plan`] found and what it could afford.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    pub plan: Vec<Drive>,
    /// The plan's expected free energy; `None` when the deadline came before any candidate was
    /// scored (the plan is then the warm start, unscored).
    pub terms: Option<Terms>,
    /// Candidate plans rolled out.
    pub evaluations: usize,
    /// CEM iterations completed after the warm start's batch.
    pub iterations: usize,
    /// Fewest candidates in one of those iterations (0 if none ran).
    pub candidates: usize,
    /// The deadline stopped it short of the configured iterations or candidates.
    pub cut: bool,
    /// Wall time per candidate-segment of a rollout, as measured so far (seconds).
    pub rollout_s_per_candidate_segment: Option<f64>,
}

/// Fewest candidates worth an iteration beyond the elites, and the step between the batch
/// sizes a deadline may choose (few distinct shapes: see [`budget::RolloutCost::affordable`]).
const MIN_EXTRA: usize = 2;
const SIZE_STEP: usize = 8;

pub struct Planner {
    cfg: PlannerConfig,
    rng: ChaCha8Rng,
    /// Warm start: the best plan of the last call, shifted by one segment.
    warm: Vec<Drive>,
    rollout_cost: budget::RolloutCost,
}

/// One scored batch: (total cost, index, terms), best first.
type Scored = Vec<(f32, usize, Terms)>;

impl Planner {
    pub fn new(cfg: &PlannerConfig) -> anyhow::Result<Self> {
        ensure!(
            (1..=MAX_HORIZON).contains(&cfg.horizon),
            "planner.horizon must be in 1..={MAX_HORIZON} (the plan a command carries), not {}",
            cfg.horizon
        );
        ensure!(cfg.samples >= 2, "planner.samples must be >= 2");
        ensure!(
            (1..=cfg.samples).contains(&cfg.elites),
            "planner.elites must be in 1..=samples"
        );
        ensure!(cfg.iterations >= 1, "planner.iterations must be >= 1");
        ensure!(
            cfg.min_speed <= cfg.max_speed && cfg.max_turn >= 0.0,
            "planner speed/turn bounds are empty"
        );
        let mut p = Self {
            cfg: cfg.clone(),
            rng: ChaCha8Rng::seed_from_u64(cfg.seed),
            warm: Vec::new(),
            rollout_cost: budget::RolloutCost::default(),
        };
        p.reset(Drive::new(cfg.min_speed.max(0.0), 0.0));
        Ok(p)
    }

    pub fn config(&self) -> &PlannerConfig {
        &self.cfg
    }

    /// Every batch size a plan may roll out: the warm start's, then those a deadline chooses
    /// from (the configured one included).
    pub fn batch_sizes(&self) -> Vec<usize> {
        let fixed = self.fixed_candidates(&self.warm, self.warm[0]).len();
        let min = (self.cfg.elites + MIN_EXTRA).min(self.cfg.samples);
        let mut sizes: Vec<usize> = std::iter::once(fixed)
            .chain((min..self.cfg.samples).step_by(SIZE_STEP))
            .chain(std::iter::once(self.cfg.samples))
            .collect();
        sizes.sort_unstable();
        sizes.dedup();
        sizes
    }

    /// Forgets the warm start: the next plan starts from holding `drive`.
    pub fn reset(&mut self, drive: Drive) {
        self.warm = vec![self.clamp(drive); self.cfg.horizon];
    }

    fn clamp(&self, d: Drive) -> Drive {
        let c = &self.cfg;
        Drive::new(
            d.speed.clamp(c.min_speed, c.max_speed),
            d.turn.clamp(-c.max_turn, c.max_turn),
        )
    }

    /// Plans the segments after the committed one, by `deadline` if there is one. `before` is
    /// the command in force when the plan starts (the committed one), for the smoothness prior.
    /// Afterwards the warm start is the best plan shifted by one segment.
    pub fn plan<I: Imagination + ?Sized>(
        &mut self,
        imagination: &mut I,
        cost: &Cost,
        before: Drive,
        deadline: Option<Instant>,
    ) -> anyhow::Result<Outcome> {
        let (h, samples) = (self.cfg.horizon, self.cfg.samples);
        let mut mean = self.warm.clone();
        let mut std = vec![Drive::new(self.cfg.speed_std, self.cfg.turn_std); h];
        let mut out = Outcome {
            plan: self.warm.clone(),
            terms: None,
            evaluations: 0,
            iterations: 0,
            candidates: 0,
            cut: false,
            rollout_s_per_candidate_segment: None,
        };
        // The warm start and the fixed candidates first: from then on a plan is in hand.
        let fixed = self.fixed_candidates(&mean, before);
        match self.score(imagination, cost, before, &fixed, deadline)? {
            Some(scored) => {
                out.evaluations += fixed.len();
                out.take_best(&fixed, &scored);
            }
            None => out.cut = true,
        }
        let min = (self.cfg.elites + MIN_EXTRA).min(samples);
        for _ in 0..self.cfg.iterations {
            if out.cut {
                break;
            }
            let Some(k) = self.batch_size(&*imagination, deadline, min) else {
                out.cut = true;
                break;
            };
            let cands = self.sample(k, &out.plan, &mean, &std);
            let Some(scored) = self.score(imagination, cost, before, &cands, deadline)? else {
                out.cut = true;
                break;
            };
            out.evaluations += cands.len();
            out.iterations += 1;
            out.candidates = if out.iterations == 1 {
                k
            } else {
                out.candidates.min(k)
            };
            out.take_best(&cands, &scored);
            self.refit(&cands, &scored, &mut mean, &mut std);
        }
        out.cut |= out.iterations < self.cfg.iterations || out.candidates < samples;
        if let Some(t) = out.terms {
            ensure!(
                t.total.is_finite(),
                "every candidate plan had a non-finite cost: {t:?}"
            );
        }
        out.rollout_s_per_candidate_segment = self.rollout_cost.per_unit();
        self.warm = out.plan[1..].to_vec();
        self.warm.push(*out.plan.last().expect("horizon >= 1"));
        Ok(out)
    }

    /// Candidates for the next CEM iteration: `k` a deadline can afford (all `samples` without
    /// one); `None` when not even `min` fit in the time left.
    fn batch_size<I: Imagination + ?Sized>(
        &self,
        imagination: &I,
        deadline: Option<Instant>,
        min: usize,
    ) -> Option<usize> {
        let (h, samples) = (self.cfg.horizon, self.cfg.samples);
        match deadline {
            None => Some(samples),
            Some(d) => {
                let left = d.saturating_duration_since(imagination.now());
                self.rollout_cost
                    .affordable(left, h, min, samples, SIZE_STEP)
            }
        }
    }

    /// `best` (the best plan so far competes again) and `k - 1` plans drawn from the Gaussian
    /// (`mean`, `std`) per segment, clamped to the bounds.
    fn sample(
        &mut self,
        k: usize,
        best: &[Drive],
        mean: &[Drive],
        std: &[Drive],
    ) -> Vec<Vec<Drive>> {
        let mut cands: Vec<Vec<Drive>> = vec![best.to_vec()];
        while cands.len() < k {
            let plan = (0..self.cfg.horizon)
                .map(|s| {
                    let (zs, zt) = (self.normal(), self.normal());
                    self.clamp(Drive::new(
                        mean[s].speed + std[s].speed * zs,
                        mean[s].turn + std[s].turn * zt,
                    ))
                })
                .collect();
            cands.push(plan);
        }
        cands
    }

    /// Rolls `cands` out and scores them, best first; `None` if the deadline stopped the
    /// rollout. Each finished rollout's wall time feeds the cost model.
    fn score<I: Imagination + ?Sized>(
        &mut self,
        imagination: &mut I,
        cost: &Cost,
        before: Drive,
        cands: &[Vec<Drive>],
        deadline: Option<Instant>,
    ) -> anyhow::Result<Option<Scored>> {
        let t0 = imagination.now();
        let frames = match deadline {
            None => imagination.imagine(cands)?,
            Some(d) => match imagination.imagine_until(cands, d)? {
                Some(f) => f,
                None => return Ok(None),
            },
        };
        let took = imagination.now().saturating_duration_since(t0);
        self.rollout_cost
            .observe(cands.len() * self.cfg.horizon, took);
        ensure!(
            frames.len() == cands.len(),
            "imagination returned {} rollouts for {} plans",
            frames.len(),
            cands.len()
        );
        let mut scored: Scored = frames
            .iter()
            .zip(cands)
            .enumerate()
            .map(|(i, (f, p))| {
                let t = cost.evaluate(f, p, before);
                // A NaN from a broken model must never win.
                let total = if t.total.is_finite() {
                    t.total
                } else {
                    f32::INFINITY
                };
                (total, i, t)
            })
            .collect();
        scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        Ok(Some(scored))
    }

    /// The next iteration's Gaussian, fitted to the elites.
    fn refit(&self, cands: &[Vec<Drive>], scored: &Scored, mean: &mut [Drive], std: &mut [Drive]) {
        let elites: Vec<&Vec<Drive>> = scored
            .iter()
            .take(self.cfg.elites)
            .map(|(_, i, _)| &cands[*i])
            .collect();
        let n = elites.len() as f32;
        for s in 0..mean.len() {
            let ms = elites.iter().map(|p| p[s].speed).sum::<f32>() / n;
            let mt = elites.iter().map(|p| p[s].turn).sum::<f32>() / n;
            let vs = elites
                .iter()
                .map(|p| (p[s].speed - ms).powi(2))
                .sum::<f32>()
                / n;
            let vt = elites.iter().map(|p| (p[s].turn - mt).powi(2)).sum::<f32>() / n;
            mean[s] = Drive::new(ms, mt);
            // Keep some spread so later iterations still search.
            std[s] = Drive::new(
                vs.sqrt().max(0.1 * self.cfg.speed_std),
                vt.sqrt().max(0.1 * self.cfg.turn_std),
            );
        }
    }

    /// The warm start, and straight on and constant turns both ways at the speed in force. The
    /// gentlest turn (a quarter of the largest) is what corrects a slow drift off a straight
    /// when a slow machine's plan has time for no CEM iteration (docs/measurements.md).
    fn fixed_candidates(&self, warm: &[Drive], before: Drive) -> Vec<Vec<Drive>> {
        let h = warm.len();
        let t = self.cfg.max_turn;
        let mut out = vec![warm.to_vec()];
        for turn in [0.0, -0.25 * t, 0.25 * t, -0.5 * t, 0.5 * t, -t, t] {
            out.push(vec![self.clamp(Drive::new(before.speed, turn)); h]);
        }
        out
    }

    fn normal(&mut self) -> f32 {
        // Box-Muller; 1 - u in (0, 1] keeps the log finite.
        let u1: f32 = 1.0 - self.rng.random::<f32>();
        let u2: f32 = self.rng.random::<f32>();
        (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
    }
}

impl Outcome {
    /// Keeps the batch's best if it beats the plan in hand (or nothing was scored yet).
    fn take_best(&mut self, cands: &[Vec<Drive>], scored: &Scored) {
        let (top_cost, top, terms) = scored[0];
        if self.terms.is_none_or(|t| top_cost < t.total) {
            self.plan = cands[top].clone();
            self.terms = Some(terms);
        }
    }
}

#[cfg(test)]
mod tests;
