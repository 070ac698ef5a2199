//! Scratch: the oracle on one track. AGENT='toml' overrides AgentConfig keys.
use mtanet_control::*;
use mtanet_eval::*;
use mtanet_scenes::{SceneConfig, shipped_track};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let track = args.get(1).map(String::as_str).unwrap_or("oval");
    let skip: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(5);
    let steps: u64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(3000);
    let scene = SceneConfig::default().with_track(shipped_track(track));
    let mut world = mtanet_scenes::World::new(&scene)?;
    let cfg: AgentConfig = toml::from_str(&std::env::var("AGENT").unwrap_or_default())?;
    let mut agent = Agent::new(&cfg, &ReactiveConfig::default(), &ExplorationConfig { enabled: false, ..Default::default() }, FrameShape::CAR, 0.02);
    let mut model = OracleModel::new(skip);
    let mut plans = Inline::new(Planner::new(&cfg.planner)?, OracleImagination::new(&scene, skip)?);
    let r = drive(&mut world, &mut agent, &mut model, &mut plans, &DriveConfig { max_steps: steps, trace_every: 0, ..Default::default() })?;
    println!("{} laps {} ai_laps {} lost {} fallbacks {} lat_r {:.4} lat_ai {:.4} ai_steps {} plan_p50 {:.1}ms late {}",
        track, r.laps, r.laps_under_active_inference, r.lost_events, r.agent.fallbacks,
        r.lateral_reactive_m.unwrap_or(f64::NAN), r.lateral_active_inference_m.unwrap_or(f64::NAN),
        r.agent.active_inference_steps, r.plan_ms.p50, r.agent.late_plans);
    if std::env::var_os("PREF").is_some() { if let Some(c) = agent.cost() { eprintln!("pref {:?}", c.preferred); } }
    Ok(())
}
