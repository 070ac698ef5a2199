//! `mta-trainer`: learns from the replay chunks the simulator streams through shared memory.

use clap::Parser;
use mtanet_ipc::cli::CommonArgs;
use mtanet_ipc::node::create_node;
use mtanet_ipc::{logging, systemd};
use mtanet_trainer::config::TrainerConfig;
use mtanet_trainer::service;

#[derive(Parser, Debug)]
#[command(
    name = "mta-trainer",
    version,
    about = "Online MTA-PredNet training from shared-memory replay"
)]
struct Args {
    /// Config sections read: [ipc], [trainer]; for the counterfactual probe also
    /// [simulator.scene] (the track) and [predictor.active_inference] (the planner's cost).
    #[command(flatten)]
    common: CommonArgs,
    /// Track of the probe's world (overrides [simulator.scene] track, like the simulator's).
    #[arg(long)]
    track: Option<std::path::PathBuf>,
}

fn main() -> anyhow::Result<()> {
    mtanet_models::retain_freed_memory();
    logging::init();
    let args = Args::parse();
    let (cfg, ipc, shutdown): (TrainerConfig, _, _) = args.common.start("trainer")?;
    let (file, _) = args.common.load()?;
    let mut scene: mtanet_scenes::SceneConfig = file.section("simulator.scene")?;
    if let Some(t) = args.track {
        scene.track = t;
    }
    let agent: mtanet_control::AgentConfig = file.section("predictor.active_inference")?;
    let mut learner = mtanet_trainer::learner::Learner::new(&cfg)?;
    if cfg.probe_every_updates > 0 {
        // Fail at start on a bad track, not at the first probe an hour in.
        mtanet_scenes::World::new(&scene)?;
        learner.set_prober(mtanet_trainer::probe::Prober {
            scene,
            agent,
            cfg: cfg.probe.clone(),
            every: cfg.probe_every_updates,
        });
    }
    tch::set_num_threads(cfg.torch_threads);
    let stack: mtanet_ipc::stack::StackConfig = file.section("stack")?;
    niceness(&cfg, &stack);
    let node = create_node(&ipc, "mta-trainer")?;
    let ports = service::Ports::open(&node)?;
    systemd::ready("trainer running");
    tracing::info!(namespace = %ipc.namespace, "trainer service started");
    let summary = service::run_with(&ports, &cfg, learner, &shutdown);
    systemd::stopping();
    let summary = summary?;
    tracing::info!(
        chunks = summary.chunks_received,
        lost = summary.chunks_lost,
        updates = summary.updates,
        published = summary.weights_published,
        "trainer stopped"
    );
    args.common.write_summary(&summary)
}

/// The predictor's latency matters more than training speed: on the normal scheduler the
/// trainer yields the CPU to it (`nice`); when the 50 Hz path runs SCHED_FIFO, which no normal
/// process delays, it need yield to nothing else (`nice_beside_fifo`).
fn niceness(cfg: &TrainerConfig, stack: &mtanet_ipc::stack::StackConfig) {
    let fifo = mtanet_ipc::sched::realtime_path_is_fifo(stack);
    let nice = if fifo { cfg.nice_beside_fifo } else { cfg.nice };
    if mtanet_ipc::sched::set_process_nice(nice) {
        tracing::info!(nice, realtime_path_fifo = fifo, "trainer niceness");
    } else {
        let now = mtanet_ipc::sched::process_nice();
        tracing::warn!(nice, now, "could not set the trainer's niceness");
    }
}
