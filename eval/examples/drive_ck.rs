//! Scratch: drive a checkpoint in-process with the agent (exploration on), trace to stderr.
use mtanet_control::*;
use mtanet_eval::*;
use mtanet_models::live::{Imagined, LiveModel};
use mtanet_scenes::{SceneConfig, World, shipped_track};

struct LiveSees(LiveModel);
impl SeesWorld for LiveSees {}
impl AgentModel for LiveSees {
    type Snapshot = mtanet_models::State;
    fn frame_skip(&self) -> Option<usize> { self.0.frame_skip() }
    fn observe(&mut self, f: &[f32], a: Wheels) -> anyhow::Result<()> { self.0.observe(f, a) }
    fn reset(&mut self) { self.0.reset() }
    fn snapshot(&mut self) -> anyhow::Result<Self::Snapshot> { self.0.snapshot() }
    fn health(&self) -> Health { self.0.health() }
}

fn main() -> anyhow::Result<()> {
    tch::set_num_threads(1);
    let args: Vec<String> = std::env::args().collect();
    let bytes = std::fs::read(&args[1])?;
    let track = args.get(2).map(String::as_str).unwrap_or("oval");
    let steps: u64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(3000);
    let explore = std::env::var_os("EXPLORE").is_some();
    let scene = SceneConfig::default().with_track(shipped_track(track));
    let cfg: AgentConfig = toml::from_str(&std::env::var("AGENT").unwrap_or_default())?;
    let mut w = World::new(&scene)?;
    let mut live = LiveModel::from_bytes(&bytes, 1)?;
    live.probe = Some(1.0);
    let mut ag = Agent::new(&cfg, &ReactiveConfig::default(), &ExplorationConfig { enabled: explore, ..Default::default() }, FrameShape::CAR, 0.02);
    let mut plans = Inline::new(Planner::new(&cfg.planner)?, Imagined::from_bytes(&bytes)?);
    let r = drive(&mut w, &mut ag, &mut LiveSees(live), &mut plans, &DriveConfig { max_steps: steps, trace_every: 0, ..Default::default() })?;
    println!("{track}: laps {} ai_laps {} lost {} fallbacks {} lat_r {:.4} lat_ai {:.4} ai_steps {} plan {:.1}ms {:?}", r.laps, r.laps_under_active_inference, r.lost_events, r.agent.fallbacks, r.lateral_reactive_m.unwrap_or(f64::NAN), r.lateral_active_inference_m.unwrap_or(f64::NAN), r.agent.active_inference_steps, r.plan_ms.p50, r.agent);
    Ok(())
}
