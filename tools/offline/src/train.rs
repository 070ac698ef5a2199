//! `mta train`: offline training of MTA-PredNet from a dataset `.npz`.
//!
//! Writes into `--out`: `config.toml` (the effective run configuration), `train_log.csv` (every
//! update), `epochs.jsonl` (held-out metrics per epoch), `checkpoint.safetensors` (latest, atomic),
//! `model.safetensors` (final), `figure.png` (the paper's strip) and `metrics.json`.

use crate::analyze::figure::DEFAULT_FRAMES;
use crate::analyze::held_out as analysis;
use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use mtanet_models::data::Dataset;
use mtanet_models::eval::evaluate;
use mtanet_models::{ModelConfig, TrainConfig, Trainer};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Debug, clap::Args)]
pub struct TrainArgs {
    /// Training data .npz (`images` [N,T,H,W] float32 in [0,1], `actions` [N,T,A] float32);
    /// several files, comma-separated or repeated, are concatenated.
    #[arg(long, value_delimiter = ',', required = true)]
    data: Vec<PathBuf>,
    /// Held-out data .npz (one or more); without it `train.eval_fraction` of --data is held out.
    #[arg(long, value_delimiter = ',')]
    eval: Vec<PathBuf>,
    /// Passes over the training data.
    #[arg(long, default_value_t = 20)]
    epochs: u64,
    /// Stop after this many updates even if epochs remain.
    #[arg(long)]
    max_updates: Option<u64>,
    /// Run configuration TOML with optional `[model]` and `[train]` tables.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Output directory (created).
    #[arg(long)]
    out: PathBuf,
    /// Frames drawn in figure.png (frames past the sequence's end are left out and reported).
    #[arg(long, value_delimiter = ',', default_values_t = DEFAULT_FRAMES)]
    frames: Vec<usize>,
    /// Held-out sequence drawn in figure.png.
    #[arg(long, default_value_t = 0)]
    figure_sequence: i64,
    /// Seed (overrides `train.seed`).
    #[arg(long)]
    seed: Option<u64>,
}

/// The `--config` file.
#[derive(Debug, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct RunConfig {
    model: ModelConfig,
    train: TrainConfig,
}

#[derive(Serialize)]
struct Metrics<'a> {
    /// Held-out metrics of the final weights (mse, copy_last_mse, mean_frame_mse,
    /// mse_shuffled_actions, timescales, figure, notes).
    #[serde(flatten)]
    report: &'a analysis::AnalysisReport,
    updates: u64,
    refused_updates: u64,
    epochs: u64,
    wall_time_s: f64,
    parameters: i64,
    train_sequences: i64,
    eval_sequences: i64,
    model: &'a ModelConfig,
    train: &'a TrainConfig,
}

pub fn run(args: TrainArgs) -> anyhow::Result<()> {
    // One intra-op thread: see mtanet_models' crate docs (2 shared cores, tiny ops).
    tch::set_num_threads(1);
    let (run, train, held) = prepare(&args)?;
    let out = |name: &str| args.out.join(name);
    let mut trainer = Trainer::f_new(&run.model, &run.train).context("building the model")?;
    let parameters: i64 = trainer
        .vs
        .trainable_variables()
        .iter()
        .map(|t| t.numel() as i64)
        .sum();
    let start = Instant::now();
    let (last_loss, epochs_done) = fit(&args, &run, &mut trainer, &train, &held, parameters)?;
    let wall_time_s = start.elapsed().as_secs_f64();
    trainer
        .save_checkpoint(&out("model.safetensors"), last_loss)
        .context("saving model")?;

    let report = analysis::analyse(
        &trainer.model,
        &held,
        &args.frames,
        args.figure_sequence,
        &out("figure.png"),
        run.train.seed,
    )
    .context("final evaluation")?;
    for note in &report.notes {
        tracing::warn!("{note}");
    }
    let eval = &report.eval;
    let metrics = Metrics {
        report: &report,
        updates: trainer.step(),
        refused_updates: trainer.refused(),
        epochs: epochs_done,
        wall_time_s,
        parameters,
        train_sequences: train.len(),
        eval_sequences: held.len(),
        model: &run.model,
        train: &run.train,
    };
    mtanet_summaries::files::write_json(&out("metrics.json"), &metrics)?;
    tracing::info!(
        mse = eval.mse,
        copy_last_mse = eval.copy_last_mse,
        mse_shuffled_actions = ?eval.mse_shuffled_actions,
        updates = trainer.step(),
        wall_time_s,
        out = %args.out.display(),
        "training finished"
    );
    Ok(())
}

/// The run's config (with the data's shape), the training and held-out sequences, and the
/// output folder with the config as used.
fn prepare(args: &TrainArgs) -> anyhow::Result<(RunConfig, Dataset, Dataset)> {
    let mut run: RunConfig = match &args.config {
        Some(p) => mtanet_summaries::files::read_toml(p)?,
        None => RunConfig::default(),
    };
    if let Some(s) = args.seed {
        run.train.seed = s;
    }
    let data = load_all(&args.data, "training")?;
    let (train, held) = if !args.eval.is_empty() {
        (data, load_all(&args.eval, "eval")?)
    } else if data.len() >= 2 {
        data.split(run.train.eval_fraction, run.train.seed)
    } else {
        bail!("one training sequence cannot be split into train and eval; pass --eval");
    };
    adopt_data_shape(&mut run.model, &train, &held)?;
    run.model.validate().context("model configuration")?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let text = toml::to_string(&run).context("serialising config")?;
    mtanet_summaries::files::write_bytes(&args.out.join("config.toml"), text.as_bytes())?;
    Ok((run, train, held))
}

/// The epochs, with a progress bar: every update in `train_log.csv`, the held-out error after
/// each epoch in `epochs.jsonl` and a checkpoint. The last loss and the epochs done.
fn fit(
    args: &TrainArgs,
    run: &RunConfig,
    trainer: &mut Trainer,
    train: &Dataset,
    held: &Dataset,
    parameters: i64,
) -> anyhow::Result<(Option<f64>, u64)> {
    let out = |name: &str| args.out.join(name);
    let planned = planned_updates(args, run, train, held, parameters);
    let bar = ProgressBar::new(planned).with_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} updates, eta {eta} {msg}",
        )
        .context("progress template")?,
    );
    let mut log = std::io::BufWriter::new(std::fs::File::create(out("train_log.csv"))?);
    writeln!(log, "update,loss,grad_norm,clipped")?;
    let mut epochs_log = std::fs::File::create(out("epochs.jsonl"))?;
    let start = Instant::now();
    let (mut last_loss, mut epochs_done) = (None, 0);
    let mut io_error = None;
    for epoch in 0..args.epochs {
        let mut stop = false;
        let mut running = (0.0, 0u32);
        trainer.fit_epoch(
            train,
            run.train.seed.wrapping_mul(1_000_003).wrapping_add(epoch),
            |r| match r {
                Ok(s) => {
                    running = (running.0 + s.loss, running.1 + 1);
                    last_loss = Some(s.loss);
                    if let Err(e) =
                        writeln!(log, "{},{},{},{}", s.step, s.loss, s.grad_norm, s.clipped)
                    {
                        io_error.get_or_insert(e);
                    }
                    bar.inc(1);
                    if running.1 == 20 {
                        bar.set_message(format!("loss {:.5}", running.0 / 20.0));
                        running = (0.0, 0);
                    }
                    stop |= args.max_updates.is_some_and(|m| s.step >= m);
                    if stop {
                        ControlFlow::Break(())
                    } else {
                        ControlFlow::Continue(())
                    }
                }
                Err(e) => {
                    bar.suspend(|| tracing::warn!("{e}"));
                    ControlFlow::Continue(())
                }
            },
        )?;
        if let Some(e) = io_error.take() {
            return Err(e).context("writing train_log.csv");
        }
        epochs_done = epoch + 1;
        let wall_s = start.elapsed().as_secs_f64();
        let m = after_epoch(
            trainer,
            held,
            epochs_done,
            last_loss,
            wall_s,
            &bar,
            &args.out,
        )?;
        writeln!(epochs_log, "{m}")?;
        if stop {
            break;
        }
    }
    log.flush()?;
    bar.finish_with_message("done");
    Ok((last_loss, epochs_done))
}

/// The updates `fit` will make (logged with the data's shapes): the progress bar's length.
fn planned_updates(
    args: &TrainArgs,
    run: &RunConfig,
    train: &Dataset,
    held: &Dataset,
    parameters: i64,
) -> u64 {
    let batches = (train.len() as u64).div_ceil(run.train.batch_size.max(1) as u64);
    let windows = (train.steps() as u64).div_ceil(run.train.bptt.max(1) as u64);
    let planned = (batches * windows * args.epochs).min(args.max_updates.unwrap_or(u64::MAX));
    tracing::info!(
        parameters,
        train = ?train.images.size(),
        eval = ?held.images.size(),
        planned_updates = planned,
        "training"
    );
    planned
}

/// After an epoch: the held-out error (its `epochs.jsonl` line is returned), logged, and the
/// checkpoint saved in `out`.
fn after_epoch(
    trainer: &Trainer,
    held: &Dataset,
    epoch: u64,
    last_loss: Option<f64>,
    wall_time_s: f64,
    bar: &ProgressBar,
    out: &Path,
) -> anyhow::Result<serde_json::Value> {
    let m = evaluate(&trainer.model, held, 64, None).context("evaluating")?;
    // Through tracing (stderr) so that logs to a file keep them; the bar hides off a tty.
    bar.suspend(|| {
        tracing::info!(
            epoch,
            updates = trainer.step(),
            mse = m.mse,
            mse_over_copy_last = m.mse_over_copy_last,
            "held-out"
        )
    });
    trainer
        .save_checkpoint(&out.join("checkpoint.safetensors"), last_loss)
        .context("saving checkpoint")?;
    Ok(
        serde_json::json!({"epoch": epoch, "updates": trainer.step(), "loss": last_loss,
        "mse": m.mse, "copy_last_mse": m.copy_last_mse, "mse_over_copy_last": m.mse_over_copy_last,
        "wall_time_s": wall_time_s}),
    )
}

/// Loads and concatenates data sets, naming the file that fails.
fn load_all(paths: &[PathBuf], what: &str) -> anyhow::Result<Dataset> {
    let sets = paths
        .iter()
        .map(|p| {
            Dataset::load_npz(p).with_context(|| format!("loading {what} data {}", p.display()))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    Dataset::concat(&sets).with_context(|| format!("concatenating {what} data {paths:?}"))
}

/// Image and action sizes come from the data; a config that says otherwise is overridden (with
/// a warning), and train/eval sets must agree.
fn adopt_data_shape(cfg: &mut ModelConfig, train: &Dataset, held: &Dataset) -> anyhow::Result<()> {
    let (h, w) = train.image_size();
    let a = train.action_dim();
    if held.image_size() != (h, w) || held.action_dim() != a {
        bail!(
            "eval data has images {:?} and {} action values, training data {:?} and {a}",
            held.image_size(),
            held.action_dim(),
            (h, w)
        );
    }
    if (cfg.image_height, cfg.image_width, cfg.action_dim) != (h, w, a) {
        tracing::info!(from_config = ?(cfg.image_height, cfg.image_width, cfg.action_dim), from_data = ?(h, w, a), "image/action sizes taken from the data");
    }
    (cfg.image_height, cfg.image_width, cfg.action_dim) = (h, w, a);
    if cfg.action_offset.is_empty() && cfg.action_scale.is_empty() {
        // Wheel velocities in rad/s would saturate the action MLP: normalise with the training
        // data's statistics, stored in the model config (and so in every checkpoint).
        (cfg.action_offset, cfg.action_scale) = train.action_normalisation();
        tracing::info!(offset = ?cfg.action_offset, scale = ?cfg.action_scale, "action normalisation from the training data");
    }
    Ok(())
}
