//! `mta figures`: regenerates a run's analysis from a checkpoint without training: the paper's
//! strip (original, predicted, first GU's output per layer at chosen frames) as figure.png, and
//! analysis.json (held-out metrics and the timescale of each layer).

use std::path::PathBuf;

use crate::analyze::figure::DEFAULT_FRAMES;
use crate::analyze::held_out::analyse;
use anyhow::Context;
use mtanet_models::checkpoint;
use mtanet_models::data::Dataset;

#[derive(Debug, clap::Args)]
pub struct FiguresArgs {
    /// Checkpoint (.safetensors) written by `mta train` or the trainer.
    #[arg(long)]
    checkpoint: PathBuf,
    /// Dataset .npz to run the model on (several: comma-separated, concatenated).
    #[arg(long, value_delimiter = ',', required = true)]
    data: Vec<PathBuf>,
    /// Output directory (created).
    #[arg(long)]
    out: PathBuf,
    /// Frames drawn (frames past the sequence's end are left out and reported).
    #[arg(long, value_delimiter = ',', default_values_t = DEFAULT_FRAMES)]
    frames: Vec<usize>,
    /// Sequence of the dataset drawn.
    #[arg(long, default_value_t = 0)]
    sequence: i64,
}

pub fn run(args: FiguresArgs) -> anyhow::Result<()> {
    tch::set_num_threads(1);
    let sets = args
        .data
        .iter()
        .map(|p| Dataset::load_npz(p).with_context(|| format!("loading {}", p.display())))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let data = Dataset::concat(&sets)?;
    let ck = checkpoint::load(&args.checkpoint)
        .with_context(|| format!("loading {}", args.checkpoint.display()))?;
    let (_vs, model) = ck.build()?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let figure = args.out.join("figure.png");
    let report = analyse(&model, &data, &args.frames, args.sequence, &figure, 0)?;
    for note in &report.notes {
        tracing::warn!("{note}");
    }
    mtanet_summaries::files::write_json(&args.out.join("analysis.json"), &report)?;
    println!(
        "step {}: mse {:.6}, copy-last {:.6} ({:.3}x), shuffled actions {:?}, top layer slower than bottom: {:?}; wrote {}",
        ck.meta.step,
        report.eval.mse,
        report.eval.copy_last_mse,
        report.eval.mse_over_copy_last,
        report.eval.mse_shuffled_actions,
        report.top_slower_than_bottom,
        figure.display()
    );
    Ok(())
}
