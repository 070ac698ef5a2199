//! `mta`: the operator CLI.

mod synth;
mod train;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "mta", version, about = "mtanet operator CLI: training, reports, soak runs, status")]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Train MTA-PredNet offline from a dataset .npz.
    Train(train::TrainArgs),
    /// Write a synthetic action-conditioned dataset .npz.
    Synth(synth::SynthArgs),
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt().with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into())).init();
    match Cli::parse().cmd {
        Cmd::Train(a) => train::run(a),
        Cmd::Synth(a) => synth::run(a),
    }
}
