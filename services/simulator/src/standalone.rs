//! A run with no other process: the teacher drives for a given simulated time; writes a report
//! and optionally records a dataset. Used by tests, benchmarks and data collection.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use mtanet_ipc::latency::{LatencyStats, LatencySummary};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_scenes::{Circuit, LateralError, ResetRule, Teacher, World};
use mtanet_summaries::CommandSource;
use serde::{Deserialize, Serialize};

use crate::recorder::Recorder;

/// What `--report FILE.json` holds.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    pub track: PathBuf,
    pub seed: u64,
    pub sim_seconds: f64,
    pub steps: u64,
    pub laps: u32,
    pub lateral_error_m: LateralError,
    pub on_line_fraction: f64,
    /// Simulated seconds per wall-clock second.
    pub real_time_factor: f64,
    pub wall_seconds: f64,
    pub rejected_commands: u64,
    pub recorded_sequences: usize,
    /// Wall time of one control step (physics + sensors + image + teacher).
    pub step_time: LatencySummary,
}

pub struct StandaloneRun {
    pub sim_seconds: f64,
    pub record: Option<PathBuf>,
    pub seq_len: usize,
    pub seed: u64,
}

pub fn run(
    world: &mut World,
    teacher: &mut Teacher,
    run: &StandaloneRun,
    shutdown: &Shutdown,
) -> anyhow::Result<Report> {
    anyhow::ensure!(
        run.sim_seconds > 0.0,
        "--sim-seconds must be positive, got {}",
        run.sim_seconds
    );
    let period = world.config().control_period_s;
    let steps = (run.sim_seconds / period).round() as u64;
    let mut recorder = run.record.as_ref().map(|_| Recorder::new(run.seq_len));
    let mut step_time = LatencyStats::new();
    let bar = ProgressBar::new(steps).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps {per_sec} eta {eta}")
            .expect("valid template"),
    );
    let start = Instant::now();
    // The teacher never loses the line: a car put back would be a fault worth a test, not a rule.
    let never = ResetRule {
        after_lost_s: 0.0,
        ..Default::default()
    };
    let mut car = Circuit::new(world, never);
    let mut done = 0;
    for _ in 0..steps {
        if shutdown.requested() {
            tracing::warn!(steps = done, "stopped early by a signal");
            break;
        }
        let t0 = Instant::now();
        let f = car.sense();
        if let Some(rec) = recorder.as_mut() {
            // The command that led to this frame, as in the replay chunks.
            rec.push(&f.sensors.image, f.applied);
        }
        car.step(teacher.act(&f.sensors), CommandSource::Teacher);
        step_time.record_ns(t0.elapsed().as_nanos() as u64);
        done += 1;
        if done % 500 == 0 {
            bar.set_position(done);
        }
    }
    bar.finish_and_clear();
    let wall = start.elapsed().as_secs_f64();
    let score = car.score().clone();
    if let (Some(rec), Some(path)) = (recorder.as_ref(), run.record.as_ref()) {
        rec.write(path)
            .with_context(|| format!("recording {}", path.display()))?;
        tracing::info!(path = %path.display(), sequences = rec.sequences(), "dataset written");
    }
    Ok(Report {
        track: world.config().track.clone(),
        seed: run.seed,
        sim_seconds: done as f64 * period,
        steps: done,
        laps: score.laps(),
        lateral_error_m: score.lateral(),
        on_line_fraction: score.on_line_fraction(),
        real_time_factor: done as f64 * period / wall.max(1e-9),
        wall_seconds: wall,
        rejected_commands: world.rejected_commands(),
        recorded_sequences: recorder.map_or(0, |r| r.sequences()),
        step_time: step_time.summary(),
    })
}
