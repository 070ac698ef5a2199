//! Scratch: collect exploratory driving, train at a frame skip with imagined steps, and evaluate
//! the probe and closed-loop driving through the learned model every so often.
use mtanet_control::*;
use mtanet_eval::*;
use mtanet_models::live::{Imagined, LiveModel};
use mtanet_models::sequences::{push_window, window_span};
use mtanet_models::{ModelConfig, TrainConfig, Trainer};
use mtanet_scenes::{SceneConfig, World, shipped_track};
use rand::{Rng, SeedableRng};
use std::time::Instant;

fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|s| s.parse().ok()).unwrap_or(d)
}

fn main() -> anyhow::Result<()> {
    tch::set_num_threads(1);
    let skip: usize = env("SKIP", 5);
    let t_len: usize = env("T", 12);
    let imag: i64 = env("IMAG", 4);
    let steps: usize = env("STEPS", 30000);
    let updates: u64 = env("UPDATES", 2000);
    let every: u64 = env("EVERY", 500);
    let track = std::env::var("TRACK").unwrap_or("oval".into());
    let scene = SceneConfig::default().with_track(shipped_track(&track));
    let agent_cfg: AgentConfig = toml::from_str(&std::env::var("AGENT").unwrap_or_default())?;
    // 1. Collect.
    let mut world = World::new(&scene)?;
    let explore: ExplorationConfig = toml::from_str(&std::env::var("EXPLORE").unwrap_or_default())?;
    let mut agent = Agent::new(&AgentConfig { enabled: false, ..agent_cfg.clone() }, &ReactiveConfig::default(), &explore, FrameShape::CAR, 0.02);
    let mut referee = mtanet_scenes::Referee::new(3.0, 0.02, 0.1, 0.15);
    let (mut frames, mut applied, mut episodes) = (Vec::new(), Vec::new(), Vec::new());
    let (mut episode, mut lost, mut explored) = (0u32, 0u32, 0usize);
    for _ in 0..steps {
        let s = world.sense();
        let a = world.command().map(|v| v as f32);
        let d = agent.tick(&Tick { episode, frame: &s.image, line: s.line, applied: a, lockstep: true }, &mut Blind, &mut NoPlans)?;
        explored += usize::from(d.driver == Driver::Exploration);
        frames.push(s.image);
        applied.push(a);
        episodes.push(episode);
        world.step(d.wheels);
        if referee.judge(&world.truth(), world.progress_m()) != mtanet_scenes::Verdict::Fine { world.reset(); referee.reset(); episode += 1; lost += 1; }
    }
    let span = window_span(skip, t_len);
    let starts: Vec<usize> = (skip - 1..steps.saturating_sub(span))
        .filter(|&i| episodes[i + 1 - skip] == episodes[i - (skip - 1) + span - 1])
        .collect();
    eprintln!("collected {steps} steps, {} episodes, {:.1}% exploration, {} windows", episode + 1, 100.0 * explored as f64 / steps as f64, starts.len());
    // 2. Train.
    let mut mcfg: ModelConfig = toml::from_str(&std::env::var("MODEL").unwrap_or_default())?;
    mcfg.frame_skip = skip as i64;
    mcfg.action_offset = vec![8.0, 8.0];
    mcfg.action_scale = vec![4.0, 4.0];
    let tcfg = TrainConfig { imagined_steps: imag, ..Default::default() };
    let mut trainer = Trainer::f_new(&mcfg, &tcfg)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let t0 = Instant::now();
    let b = tcfg.batch_size as usize;
    for u in 1..=updates {
        let (mut f, mut a) = (Vec::new(), Vec::new());
        for _ in 0..b {
            let st = starts[rng.random_range(0..starts.len())];
            push_window(&frames, &applied, st, skip, t_len, &mut f, &mut a);
        }
        let imgs = tch::Tensor::from_slice(&f).view([b as i64, t_len as i64, 8, 12]);
        let acts = tch::Tensor::from_slice(&a).view([b as i64, t_len as i64, 2]);
        let st = trainer.update(&imgs, &acts)?;
        if u % 100 == 0 {
            eprintln!("update {u} loss {:.5} grad {:.3} {:.0}s", st.loss, st.grad_norm, t0.elapsed().as_secs_f64());
        }
        if u % every == 0 {
            let bytes = trainer.checkpoint_bytes(Some(st.loss))?;
            std::fs::write(format!("/tmp/learn_{u}.safetensors"), &bytes)?;
            let p = probe(&scene, &bytes, &agent_cfg, &ProbeConfig::default())?;
            eprintln!("update {u} probe rho {:.3} total {:.3} top2 {:.2} ({} states)", p.rank_correlation, p.rank_correlation_total, p.top2_agreement, p.states);
            for tr in std::env::var("DRIVE_TRACKS").unwrap_or("oval".into()).split(',') {
                let sc = SceneConfig::default().with_track(shipped_track(tr));
                let mut w = World::new(&sc)?;
                let mut live = LiveModel::from_bytes(&bytes, 1)?;
                live.probe = Some(p.rank_correlation);
                let mut ag = Agent::new(&agent_cfg, &ReactiveConfig::default(), &ExplorationConfig { enabled: false, ..Default::default() }, FrameShape::CAR, 0.02);
                let mut plans = Inline::new(Planner::new(&agent_cfg.planner)?, Imagined::from_bytes(&bytes)?);
                let r = drive(&mut w, &mut ag, &mut LiveSees(&mut live), &mut plans, &DriveConfig { max_steps: env("DRIVE_STEPS", 3000), trace_every: 0, ..Default::default() })?;
                std::fs::copy(format!("/tmp/learn_{u}.safetensors"), format!("/tmp/learn_{}_{u}.safetensors", std::env::var("TAG").unwrap_or_default()))?;
                eprintln!("update {u} drive {tr}: laps {} ai_laps {} lost {} fallbacks {} lat_r {:.4} lat_ai {:.4} ai_steps {} ratio {:?} plan {:.1}ms", r.laps, r.laps_under_active_inference, r.lost_events, r.agent.fallbacks, r.lateral_reactive_m.unwrap_or(f64::NAN), r.lateral_active_inference_m.unwrap_or(f64::NAN), r.agent.active_inference_steps, live.error_ratio(), r.plan_ms.p50);
            }
        }
    }
    Ok(())
}

struct LiveSees<'a>(&'a mut LiveModel);
impl SeesWorld for LiveSees<'_> {}
impl AgentModel for LiveSees<'_> {
    type Snapshot = mtanet_models::State;
    fn frame_skip(&self) -> Option<usize> { self.0.frame_skip() }
    fn observe(&mut self, f: &[f32], a: Wheels) -> anyhow::Result<()> { self.0.observe(f, a) }
    fn reset(&mut self) { self.0.reset() }
    fn snapshot(&mut self) -> anyhow::Result<Self::Snapshot> { self.0.snapshot() }
    fn health(&self) -> Health { self.0.health() }
}
