//! The counterfactual probe: the model's fitness for control, not its next-frame error. From
//! states of a real drive (the reactive rule with exploration, seeded), the real MuJoCo world and
//! the learned model roll out the same held commands for a few segments; each ranks the commands
//! by the planner's risk of the frames it produced. The Spearman correlation of the two rankings,
//! averaged over the states, says whether planning through the model picks what the world
//! would reward.
//!
//! The prior terms of the cost (progress, effort, smoothness) depend on the commands only, so
//! they rank alike for both and would inflate the score: `rank_correlation` uses the risk, the
//! part the model predicts; `rank_correlation_total` the whole expected free energy.

use mtanet_control::{
    Agent, AgentConfig, AgentModel, Cost, Drive, ExplorationConfig, FrameShape, Imagination,
    ReactiveConfig, Tick,
};
use mtanet_models::live::{Imagined, LiveModel};
use mtanet_scenes::{SceneConfig, World};
use serde::{Deserialize, Serialize};

use crate::oracle::OracleImagination;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ProbeConfig {
    /// States probed (at least 50 for a stable mean).
    pub states: usize,
    /// Model steps driven between probed states.
    pub spacing: usize,
    /// Model steps driven before the first state (the model's state and the preference settle).
    pub warmup: usize,
    /// Segments each held command is rolled out for.
    pub horizon: usize,
    /// The held commands compared: every speed with every turn, rad/s.
    pub speeds: Vec<f32>,
    pub turns: Vec<f32>,
    pub seed: u64,
}

impl Default for ProbeConfig {
    fn default() -> Self {
        Self {
            states: 50,
            spacing: 6,
            warmup: 200,
            horizon: 4,
            speeds: vec![4.0, 10.0],
            turns: vec![-6.0, -3.0, 0.0, 3.0, 6.0],
            seed: 7,
        }
    }
}

#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ProbeReport {
    /// Mean Spearman correlation (risk only) over the states where the world's ranking is
    /// defined (not every command equally good).
    pub rank_correlation: f64,
    /// The same with the whole expected free energy.
    pub rank_correlation_total: f64,
    /// Share of states where the model's best command is also one of the world's best two.
    pub top2_agreement: f64,
    pub states: usize,
    pub candidates: usize,
    pub horizon: usize,
}

/// Ranks with ties averaged (1-based).
fn ranks(v: &[f32]) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..v.len()).collect();
    idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
    let mut r = vec![0.0; v.len()];
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
            j += 1;
        }
        let avg = (i + j) as f64 / 2.0 + 1.0;
        for k in i..=j {
            r[idx[k]] = avg;
        }
        i = j + 1;
    }
    r
}

/// Spearman's rho; `None` when either side has no spread.
pub fn spearman(a: &[f32], b: &[f32]) -> Option<f64> {
    let (ra, rb) = (ranks(a), ranks(b));
    let n = ra.len() as f64;
    let (ma, mb) = (ra.iter().sum::<f64>() / n, rb.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in ra.iter().zip(&rb) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    (saa > 1e-12 && sbb > 1e-12).then(|| sab / (saa * sbb).sqrt())
}

/// Probes `checkpoint` (bytes) on `scene`. `agent` gives the preference settings and cost.
/// The reactive rule with exploration (active inference off): the agent only steers and learns
/// the preference, exactly as in the stack before the switch.
fn rule_driver(agent_cfg: &AgentConfig, cfg: &ProbeConfig, period_s: f32) -> Agent {
    let driving = AgentConfig {
        enabled: false,
        ..agent_cfg.clone()
    };
    let exploration = ExplorationConfig {
        seed: cfg.seed,
        ..Default::default()
    };
    Agent::new(
        &driving,
        &ReactiveConfig::default(),
        &exploration,
        FrameShape::CAR,
        period_s,
    )
}

/// Every speed with every turn, held for the probe's horizon.
fn candidates(cfg: &ProbeConfig) -> Vec<Vec<Drive>> {
    cfg.speeds
        .iter()
        .flat_map(|&v| {
            cfg.turns
                .iter()
                .map(move |&t| vec![Drive::new(v, t); cfg.horizon.max(1)])
        })
        .collect()
}

pub fn probe(
    scene: &SceneConfig,
    checkpoint: &[u8],
    agent_cfg: &AgentConfig,
    cfg: &ProbeConfig,
) -> anyhow::Result<ProbeReport> {
    let _guard = tch::no_grad_guard();
    let mut live = LiveModel::from_bytes(checkpoint, 0)?;
    let mut imagined = Imagined::from_bytes(checkpoint)?;
    let skip = live.frame_skip().unwrap_or(1);
    let mut world = World::new(scene)?;
    let mut oracle = OracleImagination::new(scene, skip)?;
    let mut agent = rule_driver(agent_cfg, cfg, world.config().control_period_s as f32);
    let mut none = mtanet_control::Inline::new(
        mtanet_control::Planner::new(&agent_cfg.planner)?,
        NoImagination,
    );
    let cands = candidates(cfg);
    let (mut rhos, mut rhos_total, mut top2) = (Vec::new(), Vec::new(), 0usize);
    let mut model_ticks = 0usize;
    let mut episode = 0u32;
    let period = world.config().control_period_s;
    let mut referee = mtanet_scenes::Referee::new(3.0, period, 0.1, 0.15);
    let max_ticks = (cfg.warmup + cfg.spacing * cfg.states * 3) * skip + 10_000;
    for step in 0..max_ticks as u64 {
        if rhos.len() >= cfg.states {
            break;
        }
        let s = world.sense();
        let applied = world.command().map(|v| v as f32);
        let before = live.steps;
        let d = agent.step(
            &Tick {
                step,
                episode,
                frame: &s.image,
                line: s.line,
                applied,
                measured: s.wheel_velocity,
                lockstep: true,
            },
            &mut live,
            &mut none,
        )?;
        if live.steps > before {
            model_ticks += 1;
            let due = model_ticks > cfg.warmup && (model_ticks - cfg.warmup) % cfg.spacing == 0;
            if due && let Some(cost) = agent.cost() {
                if let Some((rho, rho_total, agree)) =
                    probe_state(&mut world, &live, &mut imagined, &mut oracle, cost, &cands)?
                {
                    rhos.push(rho);
                    rhos_total.push(rho_total);
                    top2 += usize::from(agree);
                }
            }
        }
        world.step(d.wheels);
        // Like the simulator: a lost or turned-around car starts a new episode at the start.
        if referee.judge(&world.truth(), world.progress_m()) != mtanet_scenes::Verdict::Fine {
            world.reset();
            referee.reset();
            episode += 1;
        }
    }
    anyhow::ensure!(
        !rhos.is_empty(),
        "the probe found no state where the commands' outcomes differ"
    );
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    Ok(ProbeReport {
        rank_correlation: mean(&rhos),
        rank_correlation_total: mean(&rhos_total),
        top2_agreement: top2 as f64 / rhos.len() as f64,
        states: rhos.len(),
        candidates: cands.len(),
        horizon: cfg.horizon,
    })
}

/// One probed state: (rho of risk, rho of G, model's best among the world's best two).
fn probe_state(
    world: &mut World,
    live: &LiveModel,
    imagined: &mut Imagined,
    oracle: &mut OracleImagination,
    cost: &Cost,
    cands: &[Vec<Drive>],
) -> anyhow::Result<Option<(f64, f64, bool)>> {
    let snap = world.snapshot();
    let here = Drive::from_wheels(world.command().map(|v| v as f32));
    // Zero-length committed segment: both start from exactly this state.
    oracle.start_here(snap.clone());
    let real = oracle.imagine(cands)?;
    world.restore(&snap);
    imagined.start_here(live.state().deep_copy());
    let imag = imagined.imagine(cands)?;
    let risk = |frames: &[Vec<f32>]| -> Vec<f32> {
        frames
            .iter()
            .map(|f| {
                let px = cost.preferred.shape.pixels();
                let n = (f.len() / px).max(1) as f32;
                f.chunks_exact(px).map(|fr| cost.risk(fr)).sum::<f32>() / n
            })
            .collect()
    };
    let total = |frames: &[Vec<f32>]| -> Vec<f32> {
        frames
            .iter()
            .zip(cands)
            .map(|(f, p)| cost.evaluate(f, p, here).total)
            .collect()
    };
    let (rw, rm) = (risk(&real), risk(&imag));
    let Some(rho) = spearman(&rw, &rm) else {
        return Ok(None);
    };
    let rho_total = spearman(&total(&real), &total(&imag)).unwrap_or(rho);
    let best_model = rm
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, _)| i)
        .unwrap_or(0);
    let r = ranks(&rw);
    Ok(Some((rho, rho_total, r[best_model] <= 2.5)))
}

/// The probe's agent never plans.
struct NoImagination;

impl Imagination for NoImagination {
    type Start = mtanet_models::State;
    fn start(&mut self, _: Self::Start, _: mtanet_control::Wheels) -> anyhow::Result<()> {
        anyhow::bail!("the probe's agent does not plan")
    }
    fn imagine(&mut self, _: &[Vec<Drive>]) -> anyhow::Result<Vec<Vec<f32>>> {
        anyhow::bail!("the probe's agent does not plan")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spearman_ranks_with_ties() {
        assert_eq!(spearman(&[1.0, 2.0, 3.0], &[10.0, 20.0, 30.0]), Some(1.0));
        assert_eq!(spearman(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]), Some(-1.0));
        assert_eq!(spearman(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]), None);
        assert_eq!(ranks(&[5.0, 1.0, 5.0]), vec![2.5, 1.0, 2.5]);
    }
}
