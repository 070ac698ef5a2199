//! Receding-horizon planning by the cross-entropy method over piecewise-constant commands.
//!
//! A plan is `horizon` segments, each a [`Drive`] held for one model step (`frame_skip` control
//! steps). Each call samples candidates around the warm start (the previous plan shifted by one
//! segment), adds a few fixed ones (the warm start itself, straight on, constant turns), has the
//! imagination roll all of them out in one batch, scores the imagined frames by expected free
//! energy ([`crate::cost`]), refits a Gaussian to the elites and repeats; the best plan seen wins.

use anyhow::ensure;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::cost::{Cost, Terms};
use crate::drive::{Drive, Wheels};

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
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlannerConfig {
    /// Segments per plan (each one model step of `frame_skip` control steps).
    pub horizon: usize,
    /// Candidates per iteration (the fixed ones included).
    pub samples: usize,
    /// Best candidates the next iteration's Gaussian is fitted to.
    pub elites: usize,
    pub iterations: usize,
    /// Forward speed bounds, rad/s.
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
            max_speed: 12.0,
            max_turn: 8.0,
            speed_std: 3.0,
            turn_std: 4.0,
            seed: 0,
        }
    }
}

/// What one call of [`Planner::plan`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    pub plan: Vec<Drive>,
    pub terms: Terms,
    /// Candidate plans rolled out.
    pub evaluations: usize,
}

pub struct Planner {
    cfg: PlannerConfig,
    rng: ChaCha8Rng,
    /// Warm start: the best plan of the last call, shifted by one segment.
    warm: Vec<Drive>,
}

impl Planner {
    pub fn new(cfg: &PlannerConfig) -> anyhow::Result<Self> {
        ensure!(cfg.horizon >= 1, "planner.horizon must be >= 1");
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
        };
        p.reset(Drive::new(cfg.min_speed.max(0.0), 0.0));
        Ok(p)
    }

    pub fn config(&self) -> &PlannerConfig {
        &self.cfg
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

    /// Plans the segments after the committed one. `before` is the command in force when the
    /// plan starts (the committed one), for the smoothness prior. Afterwards the warm start is
    /// the best plan shifted by one segment.
    pub fn plan<I: Imagination + ?Sized>(
        &mut self,
        imagination: &mut I,
        cost: &Cost,
        before: Drive,
    ) -> anyhow::Result<Outcome> {
        let (h, k) = (self.cfg.horizon, self.cfg.samples);
        let mut mean = self.warm.clone();
        let mut std = vec![Drive::new(self.cfg.speed_std, self.cfg.turn_std); h];
        let mut best: Option<(Vec<Drive>, Terms)> = None;
        let mut evaluations = 0;
        for it in 0..self.cfg.iterations {
            let mut cands: Vec<Vec<Drive>> = Vec::with_capacity(k);
            if it == 0 {
                cands.extend(self.fixed_candidates(&mean, before));
            } else if let Some((b, _)) = &best {
                cands.push(b.clone());
            }
            while cands.len() < k {
                let mut plan = Vec::with_capacity(h);
                for s in 0..h {
                    let (zs, zt) = (self.normal(), self.normal());
                    plan.push(self.clamp(Drive::new(
                        mean[s].speed + std[s].speed * zs,
                        mean[s].turn + std[s].turn * zt,
                    )));
                }
                cands.push(plan);
            }
            cands.truncate(k);
            let frames = imagination.imagine(&cands)?;
            ensure!(
                frames.len() == cands.len(),
                "imagination returned {} rollouts for {} plans",
                frames.len(),
                cands.len()
            );
            evaluations += cands.len();
            let mut scored: Vec<(f32, usize, Terms)> = frames
                .iter()
                .zip(&cands)
                .enumerate()
                .map(|(i, (f, p))| {
                    let t = cost.evaluate(f, p, before);
                    // A NaN from a broken model must never win.
                    (
                        if t.total.is_finite() {
                            t.total
                        } else {
                            f32::INFINITY
                        },
                        i,
                        t,
                    )
                })
                .collect();
            scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let (top_cost, top, terms) = scored[0];
            if best.as_ref().is_none_or(|(_, t)| top_cost < t.total) {
                best = Some((cands[top].clone(), terms));
            }
            let elites: Vec<&Vec<Drive>> = scored
                .iter()
                .take(self.cfg.elites)
                .map(|(_, i, _)| &cands[*i])
                .collect();
            for s in 0..h {
                let n = elites.len() as f32;
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
        let (plan, terms) = best.expect("at least one iteration scores candidates");
        if !terms.total.is_finite() {
            anyhow::bail!("every candidate plan had a non-finite cost: {terms:?}");
        }
        self.warm = plan[1..].to_vec();
        self.warm.push(*plan.last().expect("horizon >= 1"));
        Ok(Outcome {
            plan,
            terms,
            evaluations,
        })
    }

    /// The warm start, and straight on and constant turns both ways at the speed in force.
    fn fixed_candidates(&self, warm: &[Drive], before: Drive) -> Vec<Vec<Drive>> {
        let h = warm.len();
        let t = self.cfg.max_turn;
        let mut out = vec![warm.to_vec()];
        for turn in [0.0, -0.5 * t, 0.5 * t, -t, t] {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cost::CostConfig;
    use crate::preference::tests::{learnt, line_frame};

    /// A toy world: the line's column moves by the turn each segment (a positive turn, to the
    /// left, moves the line right in the image), from a start offset.
    struct Toy {
        start: f32,
        offset: f32,
    }

    impl Imagination for Toy {
        type Start = f32;
        fn start(&mut self, from: f32, committed: Wheels) -> anyhow::Result<()> {
            self.offset = from + 0.1 * Drive::from_wheels(committed).turn;
            Ok(())
        }
        fn imagine(&mut self, plans: &[Vec<Drive>]) -> anyhow::Result<Vec<Vec<f32>>> {
            Ok(plans
                .iter()
                .map(|p| {
                    let mut off = self.offset;
                    p.iter()
                        .flat_map(|d| {
                            off += 0.1 * d.turn;
                            line_frame(6.0 + off, 0.0)
                        })
                        .collect()
                })
                .collect())
        }
    }

    #[test]
    fn steers_the_line_back_to_the_centre_and_keeps_moving() {
        let cost = Cost::new(learnt(), CostConfig::default());
        let mut planner = Planner::new(&PlannerConfig::default()).unwrap();
        // Line 3 pixels left of the centre: turning left (positive turn) brings it back.
        let mut toy = Toy {
            start: -3.0,
            offset: 0.0,
        };
        toy.start(toy.start, [8.0, 8.0]).unwrap();
        let out = planner.plan(&mut toy, &cost, Drive::new(8.0, 0.0)).unwrap();
        assert!(out.plan[0].turn > 2.0, "{out:?}");
        assert!(
            out.plan[0].speed > 5.0,
            "the progress prior keeps it moving: {out:?}"
        );
        assert_eq!(out.evaluations, 96);
        // Same seed, same inputs: the same plan.
        let mut again = Planner::new(&PlannerConfig::default()).unwrap();
        let out2 = again.plan(&mut toy, &cost, Drive::new(8.0, 0.0)).unwrap();
        assert_eq!(out, out2);
    }

    #[test]
    fn bad_configs_are_refused() {
        for cfg in [
            PlannerConfig {
                horizon: 0,
                ..Default::default()
            },
            PlannerConfig {
                elites: 40,
                ..Default::default()
            },
        ] {
            assert!(Planner::new(&cfg).is_err());
        }
    }
}
