//! `mta-predictor`: answers each observation from the simulator with a wheel command.

use anyhow::Context;
use clap::Parser;
use mtanet_ipc::cli::CommonArgs;
use mtanet_ipc::node::create_node;
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::{logging, report, systemd};
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
}

fn main() -> anyhow::Result<()> {
    logging::init();
    let args = Args::parse();
    let shutdown = Shutdown::install().context("installing signal handlers")?;
    let (file, ipc) = args.common.load()?;
    let cfg: PredictorConfig = file.section("predictor")?;
    tch::set_num_threads(cfg.torch_threads);
    let node = create_node(&ipc, "mta-predictor")?;
    let ports = service::Ports::open(&node)?;
    systemd::ready("predictor running");
    tracing::info!(namespace = %ipc.namespace, "predictor service started");
    let summary = service::run(&ports, &cfg, &shutdown);
    systemd::stopping();
    let summary = summary?;
    tracing::info!(answered = summary.commands_sent, gaps = summary.step_gaps, compute = %summary.compute, "predictor stopped");
    if let Some(path) = &args.common.summary {
        report::write_json(path, &summary)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
