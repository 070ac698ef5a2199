//! `mta probe` and `mta drive`: a checkpoint judged for control without IPC, in this process.
//!
//! - `probe`: the counterfactual probe (`mtanet_eval::probe`) on a track: how well the model
//!   ranks held commands by the planner's risk against how the real MuJoCo world ranks them.
//! - `drive`: the agent drives a track in-process, planning through the checkpoint's model or,
//!   with `--oracle`, through the MuJoCo world itself (same planner, same cost); prints the
//!   laps, lateral errors and who drove, as JSON.

use std::path::PathBuf;

use mtanet_control::{
    AgentConfig, AgentModel, ExplorationConfig, FrameShape, Health, Inline, Planner, Wheels,
};
use mtanet_eval::{DriveConfig, OracleImagination, OracleModel, ProbeConfig, SeesWorld, drive};
use mtanet_ipc::config::ConfigFile;
use mtanet_models::live::{Imagined, LiveModel};
use mtanet_scenes::{SceneConfig, World};

#[derive(Debug, clap::Args)]
pub struct ProbeArgs {
    /// Checkpoint (.safetensors) from the trainer or `mta train`.
    #[arg(long)]
    checkpoint: PathBuf,
    /// Track CSV, or `generated:N` for a generated track (default: the config's, else the
    /// shipped oval).
    #[arg(long)]
    track: Option<PathBuf>,
    /// Stack config: [predictor.active_inference] gives the cost, [trainer.probe] the probe.
    #[arg(long)]
    config: Option<PathBuf>,
}

#[derive(Debug, clap::Args)]
pub struct DriveArgs {
    /// Plan through this checkpoint's model...
    #[arg(long, required_unless_present_any = ["oracle", "rule"], conflicts_with_all = ["oracle", "rule"])]
    checkpoint: Option<PathBuf>,
    /// ...or through the MuJoCo world itself...
    #[arg(long, conflicts_with = "rule")]
    oracle: bool,
    /// ...or let the reactive rule drive alone (no model, no exploration): the baseline.
    #[arg(long)]
    rule: bool,
    #[arg(long)]
    track: Option<PathBuf>,
    #[arg(long)]
    config: Option<PathBuf>,
    /// Control steps to drive (0.02 s each).
    #[arg(long, default_value_t = 6000)]
    steps: u64,
    /// Stop once this many laps were driven by active inference (0: drive all the steps).
    #[arg(long, default_value_t = 0)]
    laps: u32,
    /// Keep every n-th step in the report's trace (0: none).
    #[arg(long, default_value_t = 0)]
    trace_every: u64,
    /// The oracle's model step, in control steps (a checkpoint brings its own).
    #[arg(long, default_value_t = 5)]
    frame_skip: usize,
}

fn scene_and_agent(
    config: Option<&PathBuf>,
    track: Option<&PathBuf>,
) -> anyhow::Result<(ConfigFile, SceneConfig, AgentConfig)> {
    let file = ConfigFile::load(config.map(PathBuf::as_path))?;
    let mut scene: SceneConfig = file.section("simulator.scene")?;
    if let Some(t) = track {
        scene.track = t.clone();
    }
    let agent: AgentConfig = file.section("predictor.active_inference")?;
    Ok((file, scene, agent))
}

pub fn probe(args: ProbeArgs) -> anyhow::Result<()> {
    tch::set_num_threads(1);
    let (file, scene, agent) = scene_and_agent(args.config.as_ref(), args.track.as_ref())?;
    let cfg: ProbeConfig = file.section("trainer.probe")?;
    let (bytes, _) = mtanet_models::checkpoint::read(&args.checkpoint)?;
    let r = mtanet_eval::probe(&scene, &bytes, &agent, &cfg)?;
    println!("{}", serde_json::to_string_pretty(&r)?);
    Ok(())
}

/// A learned model the drive loop may not look behind.
struct Learned(LiveModel);

impl SeesWorld for Learned {}

impl AgentModel for Learned {
    type Snapshot = mtanet_models::State;
    fn frame_skip(&self) -> Option<usize> {
        self.0.frame_skip()
    }
    fn observe(&mut self, f: &[f32], a: Wheels) -> anyhow::Result<()> {
        self.0.observe(f, a)
    }
    fn reset(&mut self) {
        self.0.reset()
    }
    fn snapshot(&mut self) -> anyhow::Result<Self::Snapshot> {
        self.0.snapshot()
    }
    fn health(&self) -> Health {
        self.0.health()
    }
}

pub fn drive_cmd(args: DriveArgs) -> anyhow::Result<()> {
    tch::set_num_threads(1);
    let (file, scene, agent_cfg) = scene_and_agent(args.config.as_ref(), args.track.as_ref())?;
    let reactive: mtanet_control::ReactiveConfig = file.section("predictor.reactive")?;
    // Exploration is for learning: an evaluation drives without it.
    let off = ExplorationConfig {
        enabled: false,
        ..Default::default()
    };
    let mut world = World::new(&scene)?;
    let mut agent = mtanet_control::Agent::new(
        &agent_cfg,
        &reactive,
        &off,
        FrameShape::CAR,
        scene.control_period_s as f32,
    );
    let planner = Planner::new(&agent_cfg.planner)?;
    let run = DriveConfig {
        max_steps: args.steps,
        stop_after_ai_laps: args.laps,
        trace_every: args.trace_every,
        ..Default::default()
    };
    let report = match &args.checkpoint {
        // The same baseline every `mta up` report carries.
        None if args.rule => mtanet_eval::rule_alone(&mut world, &reactive, &run)?,
        Some(ck) => {
            let (bytes, decoded) = mtanet_models::checkpoint::read(ck)?;
            let mut live = LiveModel::from_checkpoint(&decoded, 1)?;
            // Trusted for control only with a passing probe: the one its training recorded, as
            // `mta up` takes it, else measured here on this track.
            let meta = decoded.meta;
            live.probe = match (meta.probe, meta.probe_step) {
                (Some(p), Some(_)) => Some(p),
                _ => {
                    let probe_cfg: ProbeConfig = file.section("trainer.probe")?;
                    let r = mtanet_eval::probe(&scene, &bytes, &agent_cfg, &probe_cfg)?;
                    Some(r.rank_correlation)
                }
            };
            tracing::info!(probe = ?live.probe, step = ?meta.probe_step, "the checkpoint's probe");
            let mut plans = Inline::new(planner, Imagined::from_bytes(&bytes)?);
            drive(&mut world, &mut agent, &mut Learned(live), &mut plans, &run)?
        }
        None => {
            let mut plans = Inline::new(planner, OracleImagination::new(&scene, args.frame_skip)?);
            drive(
                &mut world,
                &mut agent,
                &mut OracleModel::new(args.frame_skip),
                &mut plans,
                &run,
            )?
        }
    };
    eprint!("{}", curvature_table(&report));
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}

/// Lateral error and fallbacks by curvature, and lap times, as a console table.
fn curvature_table(r: &mtanet_eval::DriveReport) -> String {
    use std::fmt::Write;
    let mm = |v: Option<f64>| v.map_or("-".to_string(), |m| format!("{:.2}", m * 1e3));
    let mut out = String::from(
        "|curvature| 1/m   AI steps  AI mm   other steps  other mm  fallbacks begun\n",
    );
    for b in &r.control.by_curvature {
        let _ = writeln!(
            out,
            "{:>5.1} - {:<7.1} {:>8}  {:>6}  {:>11}  {:>8}  {:>15}",
            b.min_curvature,
            b.max_curvature.unwrap_or(f64::INFINITY),
            b.steps_active_inference,
            mm(b.lateral_active_inference_m),
            b.steps_other,
            mm(b.lateral_other_m),
            b.fallbacks
        );
    }
    let s = |v: Option<f64>| v.map_or("-".to_string(), |t| format!("{t:.2} s"));
    let _ = writeln!(
        out,
        "laps {} ({} by active inference); lap time {} (active inference {}); longest fallback {:.1} s",
        r.laps,
        r.laps_under_active_inference,
        s(r.control.lap_time_s),
        s(r.control.lap_time_active_inference_s),
        r.control.longest_fallback_s
    );
    out
}
