//! Drives an agent around a track in-process (no IPC), stepping the world through
//! [`mtanet_scenes::Circuit`] as the simulator service does; laps and lateral error per driver
//! come from its score.

use std::time::Instant;

use hdrhistogram::Histogram;
use mtanet_control::{Agent, AgentModel, AgentStats, Decision, Driver, PlanService, Tick};
use mtanet_scenes::{Circuit, Frame, ResetRule, World};
use mtanet_summaries::CommandSource;
use mtanet_summaries::LatencySummary;
use serde::{Deserialize, Serialize};

use crate::oracle::SeesWorld;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DriveConfig {
    /// Stop after this many control steps...
    pub max_steps: u64,
    /// ...or once this many laps were completed under active inference (0: no such stop).
    pub stop_after_ai_laps: u32,
    /// Put the car back at the start after this long more than `lost_lateral_m` off the line.
    pub reset_after_lost_s: f64,
    pub lost_lateral_m: f64,
    /// ...or after driving this far backwards along the track in that time.
    pub reverse_reset_m: f64,
    /// Keep every n-th step's position in the trace (0: no trace).
    pub trace_every: u64,
}

impl Default for DriveConfig {
    fn default() -> Self {
        Self {
            max_steps: 3000,
            stop_after_ai_laps: 0,
            reset_after_lost_s: 3.0,
            lost_lateral_m: 0.1,
            reverse_reset_m: 0.15,
            trace_every: 5,
        }
    }
}

#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct TracePoint {
    pub step: u64,
    pub x: f32,
    pub y: f32,
    /// Signed distance of the line from the sensor bar (m, + left) and the line's curvature
    /// there (1/m).
    pub lateral_m: f32,
    pub curvature: f32,
    pub driver: Driver,
    /// The command sent.
    pub wheels: [f32; 2],
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct DriveReport {
    pub steps: u64,
    pub sim_seconds: f64,
    /// Laps completed, and those driven from start to end by active inference.
    pub laps: u32,
    pub laps_under_active_inference: u32,
    /// Times the car was lost (or drove the wrong way) and was put back (new episodes).
    pub lost_events: u32,
    /// Mean |lateral error| in metres over the steps each driver drove.
    pub lateral_reactive_m: Option<f64>,
    pub lateral_active_inference_m: Option<f64>,
    pub agent: AgentStats,
    /// Who drove and how well, from the score: lap times, the longest fallback, lateral error
    /// and fallbacks by the line's curvature.
    pub control: mtanet_scenes::score::ControlSummary,
    /// Wall time of the plans taken up.
    pub plan: LatencySummary,
    pub wall_seconds: f64,
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub trace: Vec<TracePoint>,
}

/// Drives until `cfg.max_steps` or the lap goal.
pub fn drive<M, P>(
    world: &mut World,
    agent: &mut Agent,
    model: &mut M,
    plans: &mut P,
    cfg: &DriveConfig,
) -> anyhow::Result<DriveReport>
where
    M: AgentModel + SeesWorld,
    P: PlanService<M::Snapshot>,
{
    let period = world.config().control_period_s;
    let rule = ResetRule {
        after_lost_s: cfg.reset_after_lost_s,
        lost_lateral_m: cfg.lost_lateral_m,
        reverse_m: cfg.reverse_reset_m,
    };
    let mut car = Circuit::new(world, rule);
    let wall = Instant::now();
    let mut report = DriveReport::default();
    let mut plan_ns = Histogram::<u64>::new(3)?;
    while car.steps() < cfg.max_steps {
        let f = car.sense();
        let s = &f.sensors;
        model.sees(car.world_mut());
        let tick = Tick {
            step: f.step,
            episode: f.episode,
            frame: &s.image,
            line: s.line,
            applied: f.applied,
            measured: s.wheel_velocity,
            lockstep: true,
        };
        let d = agent.step(&tick, model, plans)?;
        if let Some((_, compute)) = &d.plan {
            plan_ns.record(compute.as_nanos() as u64)?;
        }
        if cfg.trace_every > 0 && f.step % cfg.trace_every == 0 {
            report.trace.push(TracePoint::of(&car, &f, &d));
        }
        let stepped = car.step(d.wheels, d.driver.source());
        if let Some(verdict) = stepped.reset {
            tracing::warn!(
                step = f.step,
                episode = f.episode,
                ?verdict,
                "car put back at the start"
            );
            report.lost_events += 1;
        }
        if cfg.stop_after_ai_laps > 0
            && car.score().laps_under_active_inference() >= cfg.stop_after_ai_laps
        {
            break;
        }
        // Progress, a tenth of the drive at a time (a drive of minutes prints nothing else).
        if car.steps() % (cfg.max_steps / 10).max(1) == 0 {
            log_progress(&car, cfg.max_steps, wall);
        }
    }
    let score = car.score();
    report.steps = score.steps();
    report.laps = score.laps();
    report.laps_under_active_inference = score.laps_under_active_inference();
    report.sim_seconds = report.steps as f64 * period;
    report.lateral_reactive_m = score.lateral_mean_of(|s| s != CommandSource::ActiveInference);
    report.lateral_active_inference_m =
        score.lateral_mean_of(|s| s == CommandSource::ActiveInference);
    report.agent = agent.stats;
    report.control = score.control();
    report.plan = LatencySummary::of_ns(&plan_ns);
    report.wall_seconds = wall.elapsed().as_secs_f64();
    Ok(report)
}

fn log_progress(car: &Circuit, max_steps: u64, wall: Instant) {
    let sc = car.score();
    tracing::info!(
        "drove {} of {} steps ({:.0}%), {:.0} s wall; laps {} ({} by active inference)",
        car.steps(),
        max_steps,
        100.0 * car.steps() as f64 / max_steps as f64,
        wall.elapsed().as_secs_f64(),
        sc.laps(),
        sc.laps_under_active_inference()
    );
}

impl TracePoint {
    fn of(car: &Circuit, f: &Frame, d: &Decision) -> Self {
        let s = &f.sensors;
        Self {
            step: f.step,
            x: s.truth.x as f32,
            y: s.truth.y as f32,
            lateral_m: s.truth.lateral_m as f32,
            curvature: car.world().track().curvature_at(s.truth.track_s, 0.1) as f32,
            driver: d.driver,
            wheels: d.wheels,
        }
    }
}

impl SeesWorld for mtanet_control::Blind {}

/// The reactive rule alone on `world` for `cfg.max_steps` (no model, no exploration, no active
/// inference): the clean baseline a learnt driver is compared with on the same track and time.
pub fn rule_alone(
    world: &mut World,
    reactive: &mtanet_control::ReactiveConfig,
    cfg: &DriveConfig,
) -> anyhow::Result<DriveReport> {
    use mtanet_control::{AgentConfig, Blind, ExplorationConfig, FrameShape, NoPlans};
    let off = AgentConfig {
        enabled: false,
        ..Default::default()
    };
    let no_exploration = ExplorationConfig {
        enabled: false,
        ..Default::default()
    };
    let period = world.config().control_period_s as f32;
    let mut agent = Agent::new(&off, reactive, &no_exploration, FrameShape::CAR, period);
    drive(world, &mut agent, &mut Blind, &mut NoPlans, cfg)
}

/// A drive as recorded: per control step the frame, the command in force that led to it
/// (`applied[i]`: frame i-1 -> i), and
/// where the car really was (for analysis; a model never sees it).
#[derive(Debug, Clone, Default)]
pub struct Recorded {
    pub frames: Vec<[f32; 96]>,
    pub applied: Vec<[f32; 2]>,
    pub truth: Vec<mtanet_scenes::GroundTruth>,
}

/// `steps` control steps of the reactive rule with seeded exploration (what the probe, the
/// figure strip, the held-out drive and `mta analyze` drive). A recording never spans a reset:
/// a car put back at the start begins it again.
pub fn record_reactive(world: &mut World, steps: usize, seed: u64) -> anyhow::Result<Recorded> {
    use mtanet_control::{
        AgentConfig, Blind, ExplorationConfig, FrameShape, NoPlans, ReactiveConfig,
    };
    let period = world.config().control_period_s;
    let cfg = AgentConfig {
        enabled: false,
        ..Default::default()
    };
    let exploration = ExplorationConfig {
        seed,
        ..Default::default()
    };
    let mut agent = Agent::new(
        &cfg,
        &ReactiveConfig::default(),
        &exploration,
        FrameShape::CAR,
        period as f32,
    );
    let mut car = Circuit::new(world, ResetRule::default());
    let mut rec = Recorded::default();
    while rec.frames.len() < steps {
        let f = car.sense();
        let t = Tick {
            step: f.step,
            episode: f.episode,
            frame: &f.sensors.image,
            line: f.sensors.line,
            applied: f.applied,
            measured: f.sensors.wheel_velocity,
            lockstep: true,
        };
        let d = agent.step(&t, &mut Blind, &mut NoPlans)?;
        rec.frames.push(f.sensors.image);
        rec.applied.push(f.applied);
        rec.truth.push(f.sensors.truth);
        if car.step(d.wheels, d.driver.source()).reset.is_some() {
            rec = Recorded::default();
        }
    }
    Ok(rec)
}
