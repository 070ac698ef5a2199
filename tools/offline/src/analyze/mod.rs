//! `mta analyze`: what a learnt checkpoint's layers hold, measured on a drive. The paper claims
//! that a larger tau makes a layer change more slowly and so carry longer-term context; this
//! drives a track with the reactive rule (seeded exploration, as the probe and the held-out drive
//! do), steps the model over the frames at its own frame skip, and measures per layer
//! - its timescale: the e-folding time of R_l's and of each generative unit's autocorrelation
//!   (`mtanet_models::timescale`), with a block-bootstrap interval;
//! - its context: cross-validated ridge read-outs (folds by lap, `readout.rs`) from R_l to the
//!   curvature ahead, the heading error and lateral offset now, and the distance since the last
//!   bend (`targets.rs`), beside the same read-outs from the raw frame, from the last 5
//!   frames stacked, and from the same network untrained (seeded initialisation: what the
//!   architecture and the taus give before any learning);
//!
//! and draws the paper's figure strip (the first unit's output of every layer at frames 1, 10,
//! 50, 100, 130) beside the autocorrelations. Everything lands in `analysis.json` and PNGs.

pub mod figure;
mod figures;
pub mod held_out;
pub mod readout;
pub mod strip;
mod table;
pub mod targets;

use std::path::{Path, PathBuf};

use anyhow::Context;
use mtanet_eval::drive::Recorded;
use mtanet_models::MtaPredNet;
use mtanet_models::analysis::{LayerTimescales, collect_states, layer_timescales};
use mtanet_models::data::Dataset;
use mtanet_models::sequences::push_window;
use mtanet_models::timescale::TimescaleOptions;
use mtanet_scenes::SceneConfig;
use serde::{Deserialize, Serialize};
use tch::{Kind, Tensor};

use self::readout::{Folds, Readout, ridge_cv};
use self::targets::{TARGETS, Targets};

pub use table::print_table;

#[derive(Debug, clap::Args)]
pub struct AnalyzeArgs {
    /// A checkpoint (model.safetensors of a run, or `mta train`'s)
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Track to drive: a CSV, a shipped name's file, or generated:N
    #[arg(long)]
    pub track: PathBuf,
    /// Simulated seconds of driving (at least 5 laps are needed for the read-outs' folds)
    #[arg(long, default_value_t = 300.0)]
    pub sim_seconds: f64,
    /// Seed of the drive's exploration
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Folder for analysis.json and the figures
    #[arg(long)]
    pub out: PathBuf,
}

/// How the drive is measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Options {
    pub sim_seconds: f64,
    pub seed: u64,
    /// Model steps dropped at the start (the state settling from zero).
    pub transient_steps: usize,
    /// Read-out folds (laps go round-robin into them).
    pub folds: usize,
    /// Model steps left out of training on either side of a test sample.
    pub gap_steps: usize,
    pub timescale: TimescaleOptions,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            sim_seconds: 300.0,
            seed: 0,
            transient_steps: 20,
            folds: 5,
            gap_steps: 20,
            timescale: TimescaleOptions::default(),
        }
    }
}

/// Everything `mta analyze` measured (analysis.json).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Analysis {
    pub checkpoint: String,
    pub track: String,
    pub options: Options,
    /// Model steps analysed (after the transient) and their length in seconds.
    pub model_steps: usize,
    pub step_s: f64,
    pub laps: u32,
    pub mean_speed_mps: f64,
    /// Per layer, bottom first.
    pub layers: Vec<LayerTimescales>,
    /// The same for the untrained network (its initialisation, seeded with the drive's seed).
    pub layers_untrained: Vec<LayerTimescales>,
    /// Read-out targets: (name, meaning); `context` rows give one R^2 per target in this order.
    pub targets: Vec<(String, String)>,
    /// Per state (`R_0`.., then the baselines `frame`, `frames_5` and the untrained network's
    /// `R_0 untrained`..), the read-outs.
    pub context: Vec<ContextRow>,
    /// How the targets are defined (`targets.rs`).
    pub bend_curvature_per_m: f64,
    pub curvature_half_window_m: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ContextRow {
    pub source: String,
    pub features: usize,
    pub readouts: Vec<Readout>,
}

impl ContextRow {
    /// The pooled R^2 of target `name`.
    pub fn r2(&self, targets: &[(String, String)], name: &str) -> Option<f64> {
        let i = targets.iter().position(|t| t.0 == name)?;
        self.readouts.get(i).map(|r| r.r2)
    }
}

/// `mta analyze`: drive, analyse, write analysis.json and the figures, print the table.
pub fn run(args: AnalyzeArgs) -> anyhow::Result<()> {
    let scene = SceneConfig::default().with_track(&args.track);
    let o = Options {
        sim_seconds: args.sim_seconds,
        seed: args.seed,
        ..Options::default()
    };
    let a = analyze_checkpoint(&args.checkpoint, &scene, &o, &args.out)?;
    print_table(&a, &mut std::io::stdout())?;
    println!(
        "\nanalysis.json and the figures (timescales.png, context.png, strip.png) in {}",
        args.out.display()
    );
    Ok(())
}

/// Drives `scene`'s track, analyses `checkpoint` on the drive and writes `out/analysis.json`
/// and the figures.
pub fn analyze_checkpoint(
    checkpoint: &Path,
    scene: &SceneConfig,
    o: &Options,
    out: &Path,
) -> anyhow::Result<Analysis> {
    // The same checkpoint and drive give the same bits: one thread for libtorch and for faer
    // (a parallel reduction sums in whatever order its threads finish).
    tch::set_num_threads(1);
    faer::set_global_parallelism(faer::Par::Seq);
    let ck = mtanet_models::checkpoint::load(checkpoint)
        .with_context(|| format!("loading {}", checkpoint.display()))?;
    let (_vs, model) = ck.build()?;
    tch::manual_seed(o.seed as i64);
    let untrained_vs = tch::nn::VarStore::new(tch::Device::Cpu);
    let untrained = MtaPredNet::f_new(&untrained_vs.root(), &ck.config)?;
    let skip = ck.config.frame_skip.max(1) as usize;
    let mut world = mtanet_scenes::World::new(scene)
        .with_context(|| format!("the track {}", scene.track.display()))?;
    let steps = (o.sim_seconds / scene.control_period_s).round() as usize;
    tracing::info!(steps, track = %scene.track.display(), "driving");
    let rec = mtanet_eval::drive::record_reactive(&mut world, steps, o.seed)?;
    let seq = Sequence::new(&rec, skip, scene.control_period_s);
    let mut a = analyze(&model, Some(&untrained), world.track(), &seq, o)?;
    a.checkpoint = checkpoint.display().to_string();
    a.track = scene.track.display().to_string();
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    mtanet_summaries::files::write_json(&out.join("analysis.json"), &a)?;
    figures::write(out, &a, &model, &seq)?;
    Ok(a)
}

/// A drive at the model's cadence: frames, mean commands and truths per model step.
pub struct Sequence {
    pub images: Tensor,
    pub actions: Tensor,
    pub truth: Vec<mtanet_scenes::GroundTruth>,
    pub step_s: f64,
}

impl Sequence {
    pub fn new(rec: &Recorded, skip: usize, control_period_s: f64) -> Self {
        let len = (rec.frames.len() + 1).saturating_sub(skip) / skip;
        let (mut f, mut a) = (Vec::new(), Vec::new());
        push_window(
            &rec.frames,
            &rec.applied,
            skip - 1,
            skip,
            len,
            &mut f,
            &mut a,
        );
        let (h, w) = (
            mtanet_ipc::IMAGE_HEIGHT as i64,
            mtanet_ipc::IMAGE_WIDTH as i64,
        );
        Self {
            images: Tensor::from_slice(&f).view([len as i64, h, w]),
            actions: Tensor::from_slice(&a).view([len as i64, 2]),
            truth: (0..len).map(|j| rec.truth[skip - 1 + j * skip]).collect(),
            step_s: skip as f64 * control_period_s,
        }
    }

    fn len(&self) -> usize {
        self.truth.len()
    }
}

/// Timescales and read-outs of `model` (and of `untrained`, the same network at its
/// initialisation) over `seq` on `track`.
pub fn analyze(
    model: &MtaPredNet,
    untrained: Option<&MtaPredNet>,
    track: &mtanet_track::Track,
    seq: &Sequence,
    o: &Options,
) -> anyhow::Result<Analysis> {
    let skip = o.transient_steps;
    anyhow::ensure!(
        seq.len() > skip + 4 * o.timescale.max_lag,
        "{} model steps are too few: drive longer (--sim-seconds)",
        seq.len()
    );
    let (layers, mut sources) = layer_states(model, seq, o, "")?;
    let n = (seq.len() - skip) as i64;
    let frames = seq.images.flatten(1, -1).to_kind(Kind::Double);
    let stacked = Tensor::cat(
        &(0..5)
            .map(|back| frames.narrow(0, skip as i64 - back, n))
            .collect::<Vec<_>>(),
        1,
    );
    sources.push(("frame".into(), frames.narrow(0, skip as i64, n)));
    sources.push(("frames_5".into(), stacked));
    let mut layers_untrained = Vec::new();
    if let Some(u) = untrained {
        let (l, s) = layer_states(u, seq, o, " untrained")?;
        layers_untrained = l;
        sources.extend(s);
    }

    let t = Targets::new(track, &seq.truth[skip..], seq.step_s);
    let laps = t.laps.last().copied().unwrap_or(0) + 1;
    let folds = Folds::by_group(&t.laps, o.folds, o.gap_steps).with_context(|| {
        format!(
            "the drive went round {laps} time(s); the read-outs need {} laps: drive longer \
             (--sim-seconds)",
            o.folds
        )
    })?;
    // A track without bends has no distance since one: that target is left out (NaN R^2).
    let values: Vec<f64> = t.values.iter().flatten().copied().collect();
    let y = Tensor::from_slice(&values).view([n, TARGETS.len() as i64]);
    let y = y.nan_to_num(0.0, None, None);
    let context = sources
        .iter()
        .map(|(name, x)| {
            tracing::info!(source = %name, features = x.size()[1], "read-outs");
            ContextRow {
                source: name.clone(),
                features: x.size()[1] as usize,
                readouts: ridge_cv(x, &y, &folds),
            }
        })
        .collect();
    Ok(Analysis {
        checkpoint: String::new(),
        track: String::new(),
        options: o.clone(),
        model_steps: n as usize,
        step_s: seq.step_s,
        laps,
        mean_speed_mps: t.mean_speed_mps,
        layers,
        layers_untrained,
        targets: TARGETS
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect(),
        context,
        bend_curvature_per_m: targets::BEND_CURVATURE_PER_M,
        curvature_half_window_m: targets::CURVATURE_HALF_WINDOW_M,
    })
}

/// Per layer of `model` over `seq` (after the transient): its timescales, and its R_l named
/// `R_<l><suffix>` for the read-outs.
fn layer_states(
    model: &MtaPredNet,
    seq: &Sequence,
    o: &Options,
    suffix: &str,
) -> anyhow::Result<(Vec<LayerTimescales>, Vec<(String, Tensor)>)> {
    let skip = o.transient_steps as i64;
    let data = Dataset::new(seq.images.unsqueeze(0), seq.actions.unsqueeze(0))?;
    let states = collect_states(model, &data, 1)?;
    let n = seq.len() as i64 - skip;
    let states: Vec<_> = (states.iter())
        .map(|(r, h)| (r.narrow(1, skip, n), h.narrow(1, skip, n)))
        .collect();
    let layers = layer_timescales(model, &states, &o.timescale);
    let sources = (states.iter().enumerate())
        .map(|(l, (r, _))| {
            let r = r.squeeze_dim(0).to_kind(Kind::Double);
            (format!("R_{l}{suffix}"), r)
        })
        .collect();
    Ok((layers, sources))
}
