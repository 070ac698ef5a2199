//! The simulator as a process among processes: publishes an observation per control step, takes
//! the predictor's command for it (lockstep: bounded wait; realtime: latest at a 50 Hz tick), and
//! streams replay chunks to the trainer. Without a predictor the teacher drives.

use std::time::{Duration, Instant};

use anyhow::Context;
use iceoryx2::prelude::*;
use mtanet_ipc::incident::{self, IncidentKind};
use mtanet_ipc::latency::LatencyStats;
use mtanet_ipc::ports::{Receiver, Sender, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::stats::StatsPublisher;
use mtanet_ipc::systemd::Watchdog;
use mtanet_ipc::{Command, CommandSource, Observation, ReplayChunk, TrainerStatus, names, stamp};
use mtanet_scenes::{Drive, ResetRule, Sensors, Teacher, Verdict, World};

use crate::chunk::ChunkBuilder;
use crate::config::{MissPolicy, Mode, SimulatorConfig};
use crate::control_stats::ControlStats;
use crate::drive_stats::DriveStats;
use crate::pacing::Pace;
pub use crate::summary::Summary;
use crate::trace::Trace;

/// The simulator's iceoryx2 endpoints.
pub struct Ports {
    pub observations: Sender<Observation>,
    pub commands: Receiver<Command>,
    pub replay: Sender<ReplayChunk>,
    pub trainer_status: Receiver<TrainerStatus>,
    pub stats: std::cell::RefCell<StatsPublisher>,
}

impl Ports {
    pub fn open(node: &Node<ipc::Service>) -> anyhow::Result<Self> {
        Ok(Self {
            observations: Sender::open(node, names::OBSERVATION, TopicShape::STEP)?,
            commands: Receiver::open(node, names::COMMAND, TopicShape::STEP)?,
            replay: Sender::open(node, names::REPLAY, TopicShape::REPLAY)?,
            trainer_status: Receiver::open(node, names::TRAINER_STATUS, TopicShape::STATUS)?,
            stats: StatsPublisher::open(node, "simulator")?.into(),
        })
    }
}

/// Consecutive missed commands after which the simulator checks for a dead predictor.
const MISSES_BEFORE_CLEANUP: u32 = 3;

/// Runs until `cfg.max_steps` or a signal; `trace` gets the car's path with who drove.
pub fn run(
    node: &Node<ipc::Service>,
    ports: &Ports,
    world: &mut World,
    teacher: &mut Teacher,
    cfg: &SimulatorConfig,
    shutdown: &Shutdown,
    mut trace: Option<&mut Trace>,
) -> anyhow::Result<Summary> {
    let period = world.config().control_period_s;
    let mut watchdog = Watchdog::from_env();
    if cfg.mode == Mode::Lockstep {
        wait_for_peers(ports, cfg, shutdown, &mut watchdog);
    }
    let mut summary = Summary::default();
    let mut drive = DriveStats::default();
    let mut control = ControlStats::default();
    let mut pace = Pace::new(cfg.pace_updates_per_1000_steps, cfg.mode == Mode::Lockstep);
    // Who decided the command in force (it led to the next frame).
    let mut applied_source = CommandSource::Teacher;
    let (mut round_trip, mut step_time) = (LatencyStats::new(), LatencyStats::new());
    // Real time: how late each step finished against its 50 Hz tick (0 when on time), and how
    // late it started; command publish -> receive.
    let mut tick_late = LatencyStats::new();
    let mut tick_jitter = LatencyStats::new();
    let mut cmd_to_sim = LatencyStats::new();
    let mut chunk = ChunkBuilder::default();
    let mut last_cmd = [0.0f32; 2];
    let mut consecutive_misses = 0u32;
    // Realtime still waits for the answer to the frame just sent, but never past half a period:
    // the 50 Hz tick must hold even when the predictor is slow.
    let command_wait = match cfg.mode {
        Mode::Lockstep => Duration::from_millis(cfg.command_timeout_ms),
        Mode::Realtime => {
            Duration::from_millis(cfg.command_timeout_ms).min(Duration::from_secs_f64(period / 2.0))
        }
    };
    let start = Instant::now();
    let mut last_log = start;
    let mut car = Drive::new(
        world,
        ResetRule {
            after_lost_s: cfg.reset_after_lost_s,
            lost_lateral_m: cfg.lost_lateral_m,
            reverse_m: cfg.reverse_reset_m,
        },
    );
    while !shutdown.requested() && (cfg.max_steps == 0 || car.steps() < cfg.max_steps) {
        let step = car.steps();
        pace.wait_for_trainer(&ports.trainer_status, step, shutdown, &mut watchdog)?;
        let t0 = Instant::now();
        let t0_ns = stamp::monotonic_ns();
        if cfg.mode == Mode::Realtime {
            let due = start + Duration::from_secs_f64(step as f64 * period);
            tick_jitter.record_ns(t0.saturating_duration_since(due).as_nanos() as u64);
        }
        let frame = car.sense();
        let (sensors, episode, applied) = (frame.sensors, frame.episode, frame.applied);
        drive.record(&sensors.truth);
        let lockstep = cfg.mode == Mode::Lockstep;
        let obs = ObsMeta {
            step,
            episode,
            time_s: frame.time_s,
            applied,
            lockstep,
        };
        let obs_stamp = publish_observation(ports, &obs, &sensors)?;
        let predictor = ports.commands.publishers() > 0;
        // Without a predictor only look (no wait): one that answered and left still counts.
        let answer = await_command(
            ports,
            step,
            if predictor {
                command_wait
            } else {
                Duration::ZERO
            },
            shutdown,
            &mut summary.stale_commands,
        )?;
        let (cmd, source) = match answer {
            Some((c, received_ns)) => {
                consecutive_misses = 0;
                if c.step == step {
                    summary.commands_received += 1;
                    round_trip.record_ns(stamp::elapsed_ns(obs_stamp));
                    cmd_to_sim.record_ns(received_ns.saturating_sub(c.stamp_ns));
                }
                let source = CommandSource::from_u32(c.source).unwrap_or(CommandSource::Reactive);
                (c.wheel_velocity, source)
            }
            None if !predictor => {
                summary.teacher_steps += 1;
                (teacher.act(&sensors), CommandSource::Teacher)
            }
            None => {
                summary.missed_commands += 1;
                if !lockstep {
                    incident::record(
                        &mut summary.incidents,
                        step,
                        IncidentKind::MissedCommand,
                        t0_ns,
                    );
                }
                consecutive_misses += 1;
                if consecutive_misses == 1 {
                    // Once per run of misses: a frozen peer must not flood the log.
                    tracing::warn!(step, wait_ms = command_wait.as_secs_f64() * 1e3, policy = ?cfg.on_missed_command, "no command in time for this step");
                }
                if consecutive_misses >= MISSES_BEFORE_CLEANUP {
                    // A predictor killed with SIGKILL still counts as connected until its node is
                    // cleaned; without this every later step would wait the full timeout.
                    consecutive_misses = 0;
                    let cleaned = node.try_cleanup_dead_nodes().cleanups;
                    if cleaned > 0 {
                        tracing::warn!(
                            cleaned,
                            "predictor stopped answering: removed dead nodes; the teacher drives until one connects"
                        );
                    }
                    summary.dead_nodes_cleaned += cleaned;
                }
                let cmd = match cfg.on_missed_command {
                    MissPolicy::Teacher => teacher.act(&sensors),
                    MissPolicy::Stop => [0.0, 0.0],
                    MissPolicy::Hold => last_cmd,
                };
                (cmd, CommandSource::Teacher)
            }
        };
        control.record(source, sensors.truth.lateral_m, drive.laps());
        if let Some(t) = trace.as_deref_mut() {
            t.record(step, episode, &sensors.truth, source)?;
        }
        if cfg.replay {
            chunk.pace = pace.rate();
            chunk.push(
                &ports.replay,
                step,
                episode,
                &sensors,
                applied,
                applied_source,
            )?;
        }
        let stepped = car.step(cmd);
        if stepped.accepted {
            last_cmd = cmd;
            applied_source = source;
        } else {
            tracing::warn!(
                step,
                ?cmd,
                "rejected a non-finite wheel command; keeping the last good one"
            );
        }
        if let Some(verdict) = stepped.reset {
            let why = match verdict {
                Verdict::Lost => "car lost the line",
                _ => "car drives the wrong way round",
            };
            tracing::warn!(
                step,
                episode,
                lateral_m = sensors.truth.lateral_m,
                "{why}: back to the start, new episode"
            );
            teacher.reset();
            drive.end_episode();
            control.end_episode();
            applied_source = CommandSource::Teacher; // the reset's zero command
            chunk.discard(); // a training sequence never spans a reset
            summary.resets += 1;
            if verdict == Verdict::WrongWay {
                summary.wrong_way_resets += 1;
            }
        }
        // The step's own work (in real time the wait for the next tick comes after).
        let work = t0.elapsed();
        step_time.record_ns(work.as_nanos() as u64);
        if work.as_secs_f64() > period {
            summary.overruns += 1;
            incident::record(&mut summary.incidents, step, IncidentKind::Overrun, t0_ns);
        }
        let done = car.steps();
        if cfg.mode == Mode::Realtime {
            let next = start + Duration::from_secs_f64(done as f64 * period);
            let late = Instant::now().saturating_duration_since(next);
            tick_late.record_ns(late.as_nanos() as u64);
            std::thread::sleep(next.saturating_duration_since(Instant::now()));
        }
        watchdog.pet();
        ports.stats.borrow_mut().tick(
            done,
            || step_time.summary(),
            |s| {
                s.laps_or_driver_or_fill = drive.laps();
                s.faults = summary.missed_commands.min(u32::MAX as u64) as u32;
            },
        )?;
        if last_log.elapsed().as_secs_f64() >= cfg.log_every_s {
            last_log = Instant::now();
            tracing::info!(
                step = done,
                laps = drive.laps(),
                laps_ai = control.laps_under_active_inference(),
                driver = applied_source.name(),
                received = summary.commands_received,
                missed = summary.missed_commands,
                round_trip = %round_trip.summary(),
                "running"
            );
        }
    }
    let step = car.steps();
    summary.steps = step;
    summary.replay_chunks_sent = chunk.sent;
    summary.rejected_commands = car.world().rejected_commands();
    summary.round_trip = round_trip.summary();
    summary.step_time = step_time.summary();
    summary.tick_late = tick_late.summary();
    summary.step_time_hist = step_time.histogram();
    summary.round_trip_hist = round_trip.histogram();
    summary.cmd_to_sim = cmd_to_sim.summary();
    summary.cmd_to_sim_hist = cmd_to_sim.histogram();
    summary.tick_jitter = tick_jitter.summary();
    summary.laps = drive.laps();
    summary.lateral_error_m = drive.lateral();
    summary.control = control.summary();
    summary.pace = pace.summary(step);
    summary.sim_seconds = step as f64 * period; // world time restarts with each episode
    summary.wall_seconds = start.elapsed().as_secs_f64();
    if cfg.replay {
        linger_for_replay(ports, cfg, &mut watchdog);
    }
    Ok(summary)
}

/// Lockstep runs are only reproducible if every step is answered, so wait (bounded) for the
/// predictor, and for the trainer when one is expected, before the first step.
fn wait_for_peers(
    ports: &Ports,
    cfg: &SimulatorConfig,
    shutdown: &Shutdown,
    watchdog: &mut Watchdog,
) {
    let deadline = Instant::now() + Duration::from_secs_f64(cfg.wait_for_peers_s.max(0.0));
    let ready = || {
        ports.commands.publishers() > 0 && (!cfg.expect_trainer || ports.replay.subscribers() > 0)
    };
    let mut told = false;
    while !ready() && !shutdown.requested() && Instant::now() < deadline {
        if !told {
            tracing::info!(
                expect_trainer = cfg.expect_trainer,
                "waiting for peers to connect"
            );
            told = true;
        }
        watchdog.pet();
        std::thread::sleep(Duration::from_millis(10));
    }
    if !ready() {
        tracing::warn!(
            "peers missing after {:.1} s: starting anyway (the teacher drives without a predictor)",
            cfg.wait_for_peers_s
        );
    }
}

/// Keeps the replay publisher (this process) alive for `replay_linger_s` while a trainer
/// subscribes, so one that has not connected yet still can and takes the chunks.
fn linger_for_replay(ports: &Ports, cfg: &SimulatorConfig, watchdog: &mut Watchdog) {
    if ports.replay.subscribers() == 0 || cfg.replay_linger_s <= 0.0 {
        return;
    }
    tracing::info!(
        seconds = cfg.replay_linger_s,
        "lingering so the trainer can take the last replay chunks"
    );
    let deadline = Instant::now() + Duration::from_secs_f64(cfg.replay_linger_s);
    while Instant::now() < deadline {
        watchdog.pet();
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// What an observation says besides the sensors.
struct ObsMeta {
    step: u64,
    episode: u32,
    time_s: f64,
    /// The command applied during the step that led to this frame.
    applied: [f32; 2],
    lockstep: bool,
}

fn publish_observation(ports: &Ports, m: &ObsMeta, s: &Sensors) -> anyhow::Result<u64> {
    let mut stamp_ns = 0;
    ports
        .observations
        .send_with(|o| {
            o.step = m.step;
            o.sim_time_s = m.time_s;
            o.image = s.image;
            o.wheel_velocity = s.wheel_velocity;
            o.command = m.applied;
            o.line_sensors = s.line.map(u8::from);
            o.episode = m.episode as u8; // wraps: receivers only look for a change
            o.lockstep = u8::from(m.lockstep);
            let t = &s.truth;
            o.truth.x_m = t.x;
            o.truth.y_m = t.y;
            o.truth.yaw_rad = t.yaw;
            o.truth.track_s_m = t.track_s;
            o.truth.lateral_m = t.lateral_m;
            o.truth.laps = t.laps;
            o.truth.on_line = u32::from(t.on_line);
            // Stamped last, right before sending: the round trip starts here.
            o.stamp_ns = stamp::monotonic_ns();
            stamp_ns = o.stamp_ns;
        })
        .context("publishing an observation")?;
    Ok(stamp_ns)
}

/// Waits up to `timeout` for the command answering `step` (with the time it was taken in);
/// drops answers to earlier steps.
fn await_command(
    ports: &Ports,
    step: u64,
    timeout: Duration,
    shutdown: &Shutdown,
    stale: &mut u64,
) -> anyhow::Result<Option<(Command, u64)>> {
    let deadline = Instant::now() + timeout;
    loop {
        let mut found = None;
        ports.commands.for_each(|c| {
            if c.step == step {
                found = Some((*c, stamp::monotonic_ns()));
            } else {
                *stale += 1;
            }
        })?;
        if found.is_some() {
            return Ok(found);
        }
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() || shutdown.requested() {
            return Ok(None);
        }
        // Short slices so a signal ends the wait quickly even if no command ever comes.
        ports.commands.wait(left.min(Duration::from_millis(50)))?;
    }
}
