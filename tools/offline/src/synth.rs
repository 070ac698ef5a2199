//! `mta synth`: writes the synthetic action-conditioned dataset used by the model tests
//! (a dot whose displacement per step is the action; see `mtanet_models::synth`).

use anyhow::Context;
use mtanet_models::synth::{SynthConfig, generate};
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct SynthArgs {
    /// Output .npz (`images` [N,T,H,W] float32 in [0,1], `actions` [N,T,2] float32).
    #[arg(long)]
    out: PathBuf,
    /// Number of sequences N.
    #[arg(long, default_value_t = SynthConfig::default().sequences)]
    sequences: i64,
    /// Steps per sequence T (>= 131 covers the figure's default frames).
    #[arg(long, default_value_t = SynthConfig::default().steps)]
    steps: i64,
    /// Random seed (same seed, same file).
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

pub fn run(args: SynthArgs) -> anyhow::Result<()> {
    let cfg = SynthConfig {
        sequences: args.sequences,
        steps: args.steps,
        seed: args.seed,
        ..Default::default()
    };
    let data = generate(&cfg).context("generating the synthetic data set")?;
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    data.save_npz(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    tracing::info!(path = %args.out.display(), shape = ?data.images.size(), seed = args.seed, "synthetic data set written");
    Ok(())
}
