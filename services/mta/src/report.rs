//! `mta report RUN_DIR`: the run's `report.json` and pictures, from what the services left in
//! the run folder (their summaries, the simulator's trace, the trainer's checkpoint). `mta up`
//! calls it at the end of every run.
//!
//! - `report.json`: who drove and how well, laps, prediction, probe, latencies, trainer, replay;
//! - `lap_trace.png`: the car's path coloured by who drove, over the track;
//! - `latency.png`: histograms of the simulator's step and the predictor's compute per step;
//! - `figure.png`: the model's figure strip on a fresh drive of the run's track;
//! - `learning.png`, `model_error.png`: the learning curve and the live model's error (`mta plot`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use mtanet_ipc::latency::LatencySummary;
use mtanet_mta::summary::Control;
use mtanet_predictor::service::Summary as PredictorSummary;
use mtanet_simulator::service::Summary as SimulatorSummary;
use mtanet_trainer::service::Summary as TrainerSummary;
use serde::{Deserialize, Serialize};

use crate::canvas::{BLACK, Canvas, GREY, Rgb};

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
    pub planning: Option<mtanet_control::PlanningSummary>,
    pub laps: serde_json::Value,
    pub lateral_error_m: serde_json::Value,
    pub prediction: serde_json::Value,
    pub probe: serde_json::Value,
    pub latency: BTreeMap<String, LatencySummary>,
    /// Steps whose command did not come within the simulator's wait (the fallback drove).
    pub missed_commands: u64,
    /// Steps whose work took longer than their 20 ms period.
    pub overruns: u64,
    pub trainer: serde_json::Value,
    pub replay: serde_json::Value,
    /// Restarts of each process by the supervisor (`mta up`).
    pub restarts: serde_json::Value,
}

/// A summary, or `None` where the process wrote none.
fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> anyhow::Result<Option<T>> {
    match mtanet_files::read_json(path) {
        Ok(v) => Ok(Some(v)),
        Err(e) if e.is_not_found() => Ok(None),
        Err(e) => Err(e.into()),
    }
}

pub fn run(args: ReportArgs) -> anyhow::Result<()> {
    let report = write(&args.dir)?;
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}

/// Builds `report.json` and the pictures in `dir`; returns the report.
pub fn write(dir: &Path) -> anyhow::Result<Report> {
    let info: RunInfo = read_json(&dir.join("run.json"))?.unwrap_or_default();
    let sim: SimulatorSummary = read_json(&dir.join("mta-simulator.json"))?.with_context(|| {
        format!(
            "{} has no mta-simulator.json: the simulator did not finish",
            dir.display()
        )
    })?;
    let pred: Option<PredictorSummary> = read_json(&dir.join("mta-predictor.json"))?;
    let tr: Option<TrainerSummary> = read_json(&dir.join("mta-trainer.json"))?;
    let sup: Option<serde_json::Value> = read_json(&dir.join("supervisor.json"))?;
    let c = &sim.control;
    let lat = |k: &str| c.lateral_mean_m.get(k).copied();
    let mut latency = BTreeMap::new();
    latency.insert("step".into(), sim.step_time);
    latency.insert("round_trip".into(), sim.round_trip);
    if sim.tick_late.count > 0 {
        latency.insert("tick_late".into(), sim.tick_late);
    }
    if let Some(p) = &pred {
        latency.insert("predictor".into(), p.compute);
        latency.insert("plan".into(), p.plan);
    }
    let report = Report {
        steps: sim.steps,
        sim_seconds: sim.sim_seconds,
        wall_seconds: sim.wall_seconds,
        track: info.track.clone(),
        lockstep: info.lockstep,
        control: Control::new(c, pred.as_ref().map(|p| &p.control)),
        planning: pred.as_ref().map(|p| p.planning),
        laps: serde_json::json!({
            "completed": sim.laps,
            "completed_under_active_inference": c.laps_completed_under_active_inference,
            "lost_line_events": sim.resets - sim.wrong_way_resets,
            "wrong_way_events": sim.wrong_way_resets,
        }),
        lateral_error_m: serde_json::json!({
            // The reactive rule's own steps; its exploration segments and the fallback apart.
            "reactive_mean": lat("reactive"),
            "active_inference_mean": lat("active_inference"),
            "exploration_mean": lat("exploration"),
            "fallback_mean": lat("fallback"),
            "all_mean": sim.lateral_error_m.mean,
        }),
        prediction: serde_json::json!({
            "mse": pred.as_ref().and_then(|p| p.model_mse),
            "copy_last_mse": pred.as_ref().and_then(|p| p.copy_last_mse),
        }),
        probe: serde_json::json!({
            "rank_correlation": tr.as_ref().and_then(|t| t.probe).or(pred.as_ref().and_then(|p| p.probe)),
            "step": tr.as_ref().and_then(|t| t.probe_step),
        }),
        latency,
        missed_commands: sim.missed_commands,
        overruns: sim.overruns,
        trainer: serde_json::json!({
            "updates": tr.as_ref().map(|t| t.updates),
            "session_updates": tr.as_ref().map(|t| t.session_updates),
            "updates_per_1000_steps": (sim.pace.paced_steps > 0).then_some(sim.pace.updates_per_1000_steps),
            "pace_target": sim.pace.target_updates_per_1000_steps,
            "update_time": tr.as_ref().map(|t| t.update_time),
        }),
        replay: serde_json::json!({
            "chunks_sent": sim.replay_chunks_sent,
            "chunks_received": tr.as_ref().map(|t| t.chunks_received),
            "chunks_lost": tr.as_ref().map(|t| t.chunks_lost),
            "exploration_fraction": tr.as_ref().map(|t| t.exploration_fraction),
        }),
        restarts: sup.map(|s| s["restarts"].clone()).unwrap_or_default(),
    };
    mtanet_files::write_json(&dir.join("report.json"), &report)?;
    if let Err(e) = lap_trace(dir, &info.track) {
        tracing::warn!("no lap trace picture: {e:#}");
    }
    latency_from(dir, &sim, pred.as_ref())?;
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
    let model = dir.join("model.safetensors");
    if model.exists()
        && let Err(e) = crate::figures::strip_on_track(&model, &info.track, &dir.join("figure.png"))
    {
        tracing::warn!("no figure strip: {e:#}");
    }
    Ok(report)
}

fn colour(source: &str) -> Rgb {
    match source {
        "active_inference" => [0, 110, 220],
        "exploration" => [240, 150, 0],
        "fallback" => [220, 0, 0],
        "teacher" => [140, 0, 160],
        _ => [0, 160, 60],
    }
}

/// The car's path over the track, coloured by who drove.
fn lap_trace(dir: &Path, track: &Path) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(dir.join("trace.csv")).context("reading trace.csv")?;
    let pts: Vec<(f64, f64, String)> = text
        .lines()
        .skip(1)
        .filter_map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            Some((
                f.get(2)?.parse().ok()?,
                f.get(3)?.parse().ok()?,
                f.get(5)?.to_string(),
            ))
        })
        .collect();
    let track = mtanet_scenes::Track::load(track).context("loading the run's track")?;
    let line: Vec<[f64; 2]> = track.points().to_vec();
    let all = line
        .iter()
        .map(|p| (p[0], p[1]))
        .chain(pts.iter().map(|p| (p.0, p.1)));
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in all {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    let (w, h, m) = (900usize, 700usize, 50.0);
    let scale = ((w as f64 - 2.0 * m) / (x1 - x0).max(1e-3))
        .min((h as f64 - 2.0 * m - 40.0) / (y1 - y0).max(1e-3));
    let to = |x: f64, y: f64| {
        (
            (m + (x - x0) * scale) as i64,
            (h as f64 - m - (y - y0) * scale) as i64,
        )
    };
    let mut c = Canvas::new(w, h);
    for k in 0..line.len() {
        let (a, b) = (line[k], line[(k + 1) % line.len()]);
        c.line(to(a[0], a[1]), to(b[0], b[1]), GREY);
    }
    for (x, y, s) in &pts {
        let (px, py) = to(*x, *y);
        c.dot(px, py, 1, colour(s));
    }
    let mut x = 10;
    for s in [
        "reactive",
        "exploration",
        "active_inference",
        "fallback",
        "teacher",
    ] {
        c.rect((x, 12), (x + 12, 24), colour(s));
        c.text(x + 18, 12, s, 1, BLACK);
        x += 30 + 8 * s.len() as i64;
    }
    c.write(&dir.join("lap_trace.png"))
}

/// `latency.png` from the simulator's and the predictor's summaries in `dir`; false without a
/// simulator summary.
pub fn latency_from_summaries(dir: &Path) -> anyhow::Result<bool> {
    let Some(sim) = read_json::<SimulatorSummary>(&dir.join("mta-simulator.json"))? else {
        return Ok(false);
    };
    let pred: Option<PredictorSummary> = read_json(&dir.join("mta-predictor.json"))?;
    latency_from(dir, &sim, pred.as_ref())?;
    Ok(true)
}

/// `latency.png` in `dir` from summaries already read.
fn latency_from(
    dir: &Path,
    sim: &SimulatorSummary,
    pred: Option<&PredictorSummary>,
) -> anyhow::Result<()> {
    let empty = Vec::new();
    let pred_hist = pred.map_or(&empty, |p| &p.compute_hist);
    latency_picture(
        &dir.join("latency.png"),
        &[
            ("simulator step", &sim.step_time_hist),
            ("predictor compute", pred_hist),
        ],
    )
}

/// Log-x histograms, one row each.
pub fn latency_picture(path: &Path, series: &[(&str, &Vec<[f64; 2]>)]) -> anyhow::Result<()> {
    let (w, row_h, left) = (900usize, 200usize, 60i64);
    let mut c = Canvas::new(w, row_h * series.len() + 40);
    // 1 us .. 1 s over the width.
    let xs =
        |us: f64| left + ((us.max(1.0).log10() / 6.0) * (w as f64 - left as f64 - 20.0)) as i64;
    for (i, (name, hist)) in series.iter().enumerate() {
        let top = 10 + (i * row_h) as i64;
        let base = top + row_h as i64 - 40;
        c.text(left, top, name, 2, BLACK);
        c.line((left, base), (w as i64 - 20, base), BLACK);
        let peak = hist.iter().map(|b| b[1]).fold(0.0, f64::max).max(1.0);
        for b in hist.iter() {
            // Each bin is a tenth of a decade wide, ending at its upper bound.
            let lo = b[0] / 10f64.powf(0.1);
            let hgt = ((b[1] / peak).sqrt() * (row_h as f64 - 70.0)) as i64;
            c.rect(
                (xs(lo) + 1, base - hgt),
                (xs(b[0]).max(xs(lo) + 1), base),
                [0, 110, 220],
            );
        }
        for (k, lbl) in ["1us", "10us", "100us", "1ms", "10ms", "100ms", "1s"]
            .iter()
            .enumerate()
        {
            let x = xs(10f64.powi(k as i32));
            c.line((x, base), (x, base + 4), BLACK);
            c.text(x - 8, base + 8, lbl, 1, BLACK);
        }
    }
    c.text(
        left,
        (row_h * series.len()) as i64 + 10,
        "count (sqrt scale) per 1/10 decade",
        1,
        BLACK,
    );
    c.write(path)
}
