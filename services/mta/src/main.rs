//! `mta`: the operator CLI.

mod figures;
mod soak;
mod status;
mod synth;
mod train;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "mta",
    version,
    about = "mtanet operator CLI: training, reports, soak runs, status"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Train MTA-PredNet offline from a dataset .npz.
    Train(train::TrainArgs),
    /// Regenerate the figure strip and analysis of a checkpoint on a dataset.
    Figures(figures::FiguresArgs),
    /// Write a synthetic action-conditioned dataset .npz.
    Synth(synth::SynthArgs),
    /// Show the nodes and topics of a running stack.
    Status(status::StatusArgs),
    /// Run the three-process stack in lockstep for N steps and print latency percentiles.
    Soak(soak::SoakArgs),
}

fn main() -> anyhow::Result<()> {
    mtanet_ipc::logging::init();
    match Cli::parse().cmd {
        Cmd::Train(a) => train::run(a),
        Cmd::Figures(a) => figures::run(a),
        Cmd::Synth(a) => synth::run(a),
        Cmd::Status(a) => status::run(a),
        Cmd::Soak(a) => soak::run(a),
    }
}
