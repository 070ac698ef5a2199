//! `mta-predictor`: answers each observation from the simulator with a wheel command.

use clap::Parser;
use mtanet_ipc::cli::CommonArgs;
use mtanet_ipc::node::create_node;
use mtanet_ipc::{logging, systemd};
use mtanet_predictor::config::PredictorConfig;
use mtanet_predictor::service;

#[derive(Parser, Debug)]
#[command(
    name = "mta-predictor",
    version,
    about = "MTA-PredNet inference and wheel control for mtanet"
)]
struct Args {
    /// Config sections read: [ipc], [predictor].
    #[command(flatten)]
    common: CommonArgs,
    /// Start with the weights of this checkpoint (newer ones from a trainer replace them).
    #[arg(long)]
    checkpoint: Option<std::path::PathBuf>,
}

fn main() -> anyhow::Result<()> {
    mtanet_models::retain_freed_memory();
    logging::init();
    let args = Args::parse();
    let (cfg, ipc, shutdown): (PredictorConfig, _, _) = args.common.start("predictor")?;
    (cfg.active_inference.validate())
        .map_err(|e| args.common.invalid_config("predictor.active_inference", e))?;
    tch::set_num_threads(cfg.torch_threads);
    let mut policy = mtanet_predictor::policy::Policy::new(&cfg);
    if let Some(path) = &args.checkpoint {
        policy.load_file(path)?;
        let probe = policy.model().and_then(|m| m.probe);
        tracing::info!(path = %path.display(), ?probe, "weights loaded from file");
    }
    let node = create_node(&ipc, "mta-predictor")?;
    let ports = service::Ports::open(&node)?;
    tracing::info!(namespace = %ipc.namespace, "predictor service started");
    let summary = service::run_with(&ports, &cfg, policy, &shutdown);
    systemd::stopping();
    let summary = summary?;
    tracing::info!(answered = summary.commands_sent, gaps = summary.step_gaps, compute = %summary.compute, "predictor stopped");
    args.common.write_summary(&summary)
}
