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
    /// Config sections read: [ipc], [trainer].
    #[command(flatten)]
    common: CommonArgs,
}

fn main() -> anyhow::Result<()> {
    logging::init();
    let args = Args::parse();
    let (cfg, ipc, shutdown): (TrainerConfig, _, _) = args.common.start("trainer")?;
    tch::set_num_threads(cfg.torch_threads);
    // The predictor's latency matters more than training speed: yield the CPU to it.
    // SAFETY: setpriority(2) on this process only.
    if unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, cfg.nice) } != 0 {
        tracing::warn!(nice = cfg.nice, "could not lower the trainer's priority");
    }
    let node = create_node(&ipc, "mta-trainer")?;
    let ports = service::Ports::open(&node)?;
    systemd::ready("trainer running");
    tracing::info!(namespace = %ipc.namespace, "trainer service started");
    let summary = service::run(&ports, &cfg, &shutdown);
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
