//! `mta report RUN_DIR`: the run's `report.json` and pictures, from what the services left in
//! the run folder (their summaries, the simulator's trace, the trainer's checkpoint). `mta up`
//! calls it at the end of every run.
//!
//! - `report.json`: who drove and how well, laps, prediction, probe, latencies, trainer, replay;
//! - `lap_trace.png`: the car's path coloured by who drove, over the track;
//! - `latency.png`: histograms of the simulator's step and the predictor's compute per step;
//! - `figure.png`: the model's figure strip on a fresh drive of the run's track (drawn by the
//!   [`FigureStrip`] the caller passes: the model is not this crate's);
//! - `learning.png`, `model_error.png`: the learning curve and the live model's error (`mta plot`).

use mtanet_summaries::run_folder;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use mtanet_summaries::predictor::Summary as PredictorSummary;
use mtanet_summaries::simulator::Summary as SimulatorSummary;
use mtanet_summaries::soak::Control;
use mtanet_summaries::supervisor::SupervisorSummary;
use mtanet_summaries::trainer::Summary as TrainerSummary;
use mtanet_summaries::{LatencySummary, PlanningSummary};
use serde::{Deserialize, Serialize};

use crate::pictures;

#[derive(Debug, clap::Args)]
pub struct ReportArgs {
    /// The run folder (`runs/<timestamp>/` of `./ops/run_local.sh`).
    pub dir: PathBuf,
}

/// What `mta up` records about the run it started.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct RunInfo {
    pub track: PathBuf,
    pub lockstep: bool,
    pub learning: bool,
    pub checkpoint: Option<PathBuf>,
    pub config: Option<PathBuf>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Report {
    pub steps: u64,
    pub sim_seconds: f64,
    pub wall_seconds: f64,
    pub track: PathBuf,
    pub lockstep: bool,
    pub control: Control,
    /// What the plans could afford in real time (iterations, candidates, the share cut by
    /// their deadline, the cost reached); absent without a predictor.
    pub planning: Option<PlanningSummary>,
    pub laps: Laps,
    pub lateral_error_m: LateralByDriver,
    /// The reactive rule driving alone on the same track for the same simulated time (no
    /// model, no exploration), the baseline this run's driving is judged by; absent where
    /// `mta up` did not drive it (`rule_alone.json`).
    #[serde(default)]
    pub rule_alone: Option<RuleAlone>,
    pub prediction: Prediction,
    pub probe: Probe,
    pub latency: BTreeMap<String, LatencySummary>,
    /// Steps whose command did not come within the simulator's wait and no plan covered (the
    /// miss policy drove).
    pub missed_commands: u64,
    /// Steps whose command did not come in time, driven by the plan the last command carried.
    #[serde(default)]
    pub plan_followed: u64,
    /// Steps whose work took longer than their 20 ms period.
    pub overruns: u64,
    pub trainer: TrainerFigures,
    pub replay: ReplayFigures,
    /// Restarts of each process by the supervisor (`mta up`).
    pub restarts: BTreeMap<String, u32>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Laps {
    pub completed: u32,
    /// Laps in which active inference decided every step, from the lap's first.
    pub completed_under_active_inference: u32,
    /// Times the car lost the line (or drove the wrong way) and was put back at the start.
    pub lost_line_events: u64,
    pub wrong_way_events: u64,
    /// Median simulated seconds of a whole lap, over all laps and over those active inference
    /// drove from start to end.
    #[serde(default)]
    pub lap_time_s: Option<f64>,
    #[serde(default)]
    pub lap_time_active_inference_s: Option<f64>,
}

/// `rule_alone.json`: the reactive rule alone, in-process, on the run's track for its time.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct RuleAlone {
    pub sim_seconds: f64,
    pub laps: u32,
    pub lost_line_events: u32,
    pub lateral_mean_m: Option<f64>,
    pub lap_time_s: Option<f64>,
}

/// The file `mta up` writes the rule's baseline to, beside the run's summaries.
pub const RULE_ALONE_FILE: &str = "rule_alone.json";

/// Mean |lateral error| in metres over the steps each driver drove (None: it never drove).
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct LateralByDriver {
    /// The reactive rule's own steps in this run, its exploration segments and the fallback
    /// apart: while learning, mostly the rule recovering from exploration, so not the baseline
    /// (that is `rule_alone`).
    pub reactive_mean: Option<f64>,
    pub active_inference_mean: Option<f64>,
    pub exploration_mean: Option<f64>,
    pub fallback_mean: Option<f64>,
    pub all_mean: f64,
}

/// The live model's next-frame error and the copy-last-frame baseline's, over the run.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Prediction {
    pub mse: Option<f64>,
    pub copy_last_mse: Option<f64>,
}

/// The counterfactual probe of the newest weights: the trainer's, else the predictor's.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Probe {
    pub rank_correlation: Option<f64>,
    /// The training update it was measured at.
    pub step: Option<u64>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct TrainerFigures {
    pub updates: Option<u64>,
    pub session_updates: Option<u64>,
    /// Lockstep: the pace reached, and the one asked for (0: not paced).
    pub updates_per_1000_steps: Option<f64>,
    pub pace_target: f64,
    pub update_time: Option<LatencySummary>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ReplayFigures {
    pub chunks_sent: u64,
    pub chunks_received: Option<u64>,
    pub chunks_lost: Option<u64>,
    pub exploration_fraction: Option<f64>,
}

/// A summary, or `None` where the process wrote none.
pub(crate) fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> anyhow::Result<Option<T>> {
    match mtanet_summaries::files::read_json(path) {
        Ok(v) => Ok(Some(v)),
        Err(e) if e.is_not_found() => Ok(None),
        Err(e) => Err(e.into()),
    }
}

/// Draws the model's figure strip: the checkpoint `model` on a fresh drive of `track`, written to
/// `out`. The model and the world live in heavier crates; the caller passes it in.
pub type FigureStrip = dyn Fn(&Path, &Path, &Path) -> anyhow::Result<()>;

/// `mta report`: writes the report and prints it.
pub fn run(args: ReportArgs, figure: &FigureStrip) -> anyhow::Result<()> {
    let report = write(&args.dir, figure)?;
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}

/// Builds `report.json` and the pictures in `dir` (`figure.png` with `figure`); returns the
/// report.
pub fn write(dir: &Path, figure: &FigureStrip) -> anyhow::Result<Report> {
    let info: RunInfo = read_json(&dir.join(run_folder::RUN))?.unwrap_or_default();
    let sim: SimulatorSummary = read_json(&dir.join(run_folder::summary_of("mta-simulator")))?
        .with_context(|| {
            format!(
                "{} has no mta-simulator.json: the simulator did not finish",
                dir.display()
            )
        })?;
    let pred: Option<PredictorSummary> =
        read_json(&dir.join(run_folder::summary_of("mta-predictor")))?;
    let tr: Option<TrainerSummary> = read_json(&dir.join(run_folder::summary_of("mta-trainer")))?;
    let sup: Option<SupervisorSummary> = read_json(&dir.join(run_folder::SUPERVISOR))?;
    let c = &sim.control;
    let lat = |k: &str| c.lateral_mean_m.get(k).copied();
    let latency = latency_table(&sim, pred.as_ref());
    let report = Report {
        steps: sim.steps,
        sim_seconds: sim.sim_seconds,
        wall_seconds: sim.wall_seconds,
        track: info.track.clone(),
        lockstep: info.lockstep,
        control: Control::new(c, pred.as_ref().map(|p| &p.control)),
        planning: pred.as_ref().map(|p| p.planning),
        laps: Laps {
            completed: sim.laps,
            completed_under_active_inference: c.laps_completed_under_active_inference,
            lost_line_events: sim.resets - sim.wrong_way_resets,
            wrong_way_events: sim.wrong_way_resets,
            lap_time_s: c.lap_time_s,
            lap_time_active_inference_s: c.lap_time_active_inference_s,
        },
        rule_alone: read_json(&dir.join(RULE_ALONE_FILE))?,
        lateral_error_m: LateralByDriver {
            reactive_mean: lat("reactive"),
            active_inference_mean: lat("active_inference"),
            exploration_mean: lat("exploration"),
            fallback_mean: lat("fallback"),
            all_mean: sim.lateral_error_m.mean,
        },
        prediction: Prediction {
            mse: pred.as_ref().and_then(|p| p.model_mse),
            copy_last_mse: pred.as_ref().and_then(|p| p.copy_last_mse),
        },
        probe: Probe {
            rank_correlation: tr
                .as_ref()
                .and_then(|t| t.probe)
                .or(pred.as_ref().and_then(|p| p.probe)),
            step: tr.as_ref().and_then(|t| t.probe_step),
        },
        latency,
        missed_commands: sim.missed_commands,
        plan_followed: sim.plan_followed,
        overruns: sim.overruns,
        trainer: TrainerFigures {
            updates: tr.as_ref().map(|t| t.updates),
            session_updates: tr.as_ref().map(|t| t.session_updates),
            updates_per_1000_steps: (sim.pace.paced_steps > 0)
                .then_some(sim.pace.updates_per_1000_steps),
            pace_target: sim.pace.target_updates_per_1000_steps,
            update_time: tr.as_ref().map(|t| t.update_time),
        },
        replay: ReplayFigures {
            chunks_sent: sim.replay_chunks_sent,
            chunks_received: tr.as_ref().map(|t| t.chunks_received),
            chunks_lost: tr.as_ref().map(|t| t.chunks_lost),
            exploration_fraction: tr.as_ref().map(|t| t.exploration_fraction),
        },
        restarts: sup.map(|s| s.restarts).unwrap_or_default(),
    };
    mtanet_summaries::files::write_json(&dir.join(run_folder::REPORT), &report)?;
    draw_pictures(dir, &info.track, &sim, pred.as_ref(), figure)?;
    Ok(report)
}

/// The latencies report.json lists: the simulator's, and the predictor's when it reported.
fn latency_table(
    sim: &SimulatorSummary,
    pred: Option<&PredictorSummary>,
) -> BTreeMap<String, LatencySummary> {
    let mut latency = BTreeMap::new();
    latency.insert("step".into(), sim.step_time);
    latency.insert("round_trip".into(), sim.round_trip);
    if sim.tick_late.count > 0 {
        latency.insert("tick_late".into(), sim.tick_late);
    }
    if let Some(p) = pred {
        latency.insert("predictor".into(), p.compute);
        latency.insert("plan".into(), p.plan);
    }
    latency
}

/// The run's pictures; one that cannot be drawn is a warning, not a failed report.
fn draw_pictures(
    dir: &Path,
    track: &Path,
    sim: &SimulatorSummary,
    pred: Option<&PredictorSummary>,
    figure: &FigureStrip,
) -> anyhow::Result<()> {
    if let Err(e) = pictures::lap_trace(dir, track) {
        tracing::warn!("no lap trace picture: {e:#}");
    }
    pictures::latency_from(dir, sim, pred)?;
    for (name, draw) in [
        (
            "learning.png",
            crate::plot::learning as fn(&Path) -> anyhow::Result<bool>,
        ),
        ("model_error.png", crate::plot::model_error),
    ] {
        if let Err(e) = draw(dir) {
            tracing::warn!("no {name}: {e:#}");
        }
    }
    let model = dir.join(run_folder::MODEL);
    if model.exists()
        && let Err(e) = figure(&model, track, &dir.join("figure.png"))
    {
        tracing::warn!("no figure strip: {e:#}");
    }
    Ok(())
}
