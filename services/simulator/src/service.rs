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
use mtanet_ipc::stats::{StatsPublisher, saturate};
use mtanet_ipc::systemd::Watchdog;
use mtanet_ipc::wait::{self, Waited, Wake};
use mtanet_ipc::{
    Command, CommandSource, Observation, ProcessStats, ReplayChunk, TrainerStatus, names, stamp,
};
use mtanet_scenes::{Circuit, Frame, Score, Stepped, Teacher, Verdict, World};

use crate::answer::Answers;
use crate::chunk::ChunkBuilder;
use crate::clock::Clock;
use crate::config::{Mode, SimulatorConfig};
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

/// Runs until `cfg.max_steps` or a signal; `trace` gets the car's path with who drove. Each
/// step: wait for its turn (the trainer's pace, the 50 Hz tick), sense, publish, take the answer,
/// step the world core.
pub fn run(
    node: &Node<ipc::Service>,
    ports: &Ports,
    worlds: &mut [World],
    teacher: &mut Teacher,
    cfg: &SimulatorConfig,
    shutdown: &Shutdown,
    mut trace: Option<&mut Trace>,
) -> anyhow::Result<Summary> {
    let period = worlds[0].config().control_period_s;
    let lockstep = cfg.mode == Mode::Lockstep;
    let mut watchdog = Watchdog::from_env();
    if lockstep {
        wait_for_peers(ports, cfg, shutdown, &mut watchdog)?;
    }
    let mut lp = Loop::new(cfg, period, lockstep);
    let mut car = Circuit::round(worlds, cfg.reset_rule(), cfg.switch_track_after_s);
    while !shutdown.requested() && (cfg.max_steps == 0 || car.steps() < cfg.max_steps) {
        let step = car.steps();
        lp.pace
            .wait_for_trainer(&ports.trainer_status, step, shutdown, &mut watchdog)?;
        lp.pace
            .wait_for_weights(&ports.trainer_status, step, shutdown, &mut watchdog)?;
        let t0 = lp.clock.begin(step);
        let t0_ns = stamp::monotonic_ns();
        let frame = car.sense();
        let obs_stamp = publish_observation(ports, &frame, lockstep)?;
        // The stand-in for a missed command must know where the line was last seen.
        teacher.observe(frame.sensors.line);
        let (cmd, source) = lp.answers.take(
            node,
            ports,
            &frame,
            obs_stamp,
            t0_ns,
            teacher,
            &mut lp.summary,
            shutdown,
        )?;
        if let Some(t) = trace.as_deref_mut() {
            t.record(step, frame.episode, &frame.sensors.truth, source)?;
        }
        if cfg.replay {
            lp.chunk.pace = lp.pace.rate();
            let (s, e, a) = (&frame.sensors, frame.episode, frame.applied);
            lp.chunk
                .push(&ports.replay, step, e, s, a, lp.applied_source)?;
        }
        let stepped = car.step(cmd, source);
        lp.settle(&car, &frame, &stepped, (cmd, source), teacher);
        lp.account(step, t0, t0_ns);
        let done = car.steps();
        lp.clock.wait_for_tick(done);
        watchdog.pet();
        let score = car.score();
        let fill = |s: &mut ProcessStats| fill_stats(s, score, &lp.summary);
        let step_time = &lp.step_time;
        ports
            .stats
            .borrow_mut()
            .tick(done, || step_time.summary(), fill)?;
        if lp.last_log.elapsed().as_secs_f64() >= cfg.log_every_s {
            lp.last_log = Instant::now();
            log_running(done, score, lp.applied_source, &lp.summary, &lp.answers);
        }
    }
    let (summary, sent) = lp.conclude(&car, ports)?;
    if cfg.replay {
        linger_for_replay(ports, cfg, sent, shutdown, &mut watchdog)?;
    }
    Ok(summary)
}

/// What the loop carries from one step to the next.
struct Loop {
    summary: Summary,
    pace: Pace,
    clock: Clock,
    answers: Answers,
    step_time: LatencyStats,
    chunk: ChunkBuilder,
    /// Who decided the command in force (it led to the next frame).
    applied_source: CommandSource,
    last_log: Instant,
    period: f64,
}

impl Loop {
    fn new(cfg: &SimulatorConfig, period: f64, lockstep: bool) -> Self {
        Self {
            summary: Summary::default(),
            pace: Pace::new(cfg.pace_updates_per_1000_steps, lockstep),
            clock: Clock::new(period, !lockstep),
            answers: Answers::new(cfg, period),
            step_time: LatencyStats::new(),
            chunk: ChunkBuilder::default(),
            applied_source: CommandSource::Teacher,
            last_log: Instant::now(),
            period,
        }
    }

    /// Takes in how the world took the step's command: the command in force (a non-finite one
    /// is refused and the last good one kept) and, at a new episode, its counts and fresh start.
    fn settle(
        &mut self,
        car: &Circuit,
        frame: &Frame,
        stepped: &Stepped,
        (cmd, source): ([f32; 2], CommandSource),
        teacher: &mut Teacher,
    ) {
        if stepped.accepted {
            self.answers.last = cmd;
            self.applied_source = source;
        } else {
            tracing::warn!(
                step = frame.step,
                ?cmd,
                "rejected a non-finite wheel command; keeping the last good one"
            );
        }
        if stepped.reset.is_some() || stepped.switched_to.is_some() {
            new_episode(car, stepped, frame, &mut self.summary);
            teacher.reset();
            self.applied_source = CommandSource::Teacher; // the reset's zero command
            self.chunk.discard(); // a training sequence never spans two episodes
        }
    }

    /// Records the step's own work (in real time the wait for the next tick comes after) and
    /// counts an overrun of its period.
    fn account(&mut self, step: u64, t0: Instant, t0_ns: u64) {
        let work = t0.elapsed();
        self.step_time.record_ns(work.as_nanos() as u64);
        if work.as_secs_f64() > self.period {
            self.summary.overruns += 1;
            incident::record(
                &mut self.summary.incidents,
                step,
                IncidentKind::Overrun,
                t0_ns,
            );
        }
    }

    /// The run's summary, published as the last figures before lingering (what a watcher
    /// waits for); also the replay chunks sent.
    fn conclude(mut self, car: &Circuit, ports: &Ports) -> anyhow::Result<(Summary, u64)> {
        let steps = car.steps();
        let score = car.score().clone();
        let s = &mut self.summary;
        s.steps = steps;
        s.replay_chunks_sent = self.chunk.sent;
        s.rejected_commands = car.rejected_commands();
        s.pace = self.pace.summary(steps);
        s.wall_seconds = self.clock.elapsed().as_secs_f64();
        finish_summary(
            s,
            &score,
            &self.answers,
            &self.step_time,
            &self.clock,
            self.period,
        );
        let fill = |p: &mut ProcessStats| fill_stats(p, &score, &self.summary);
        let step_time = &self.step_time;
        ports
            .stats
            .borrow_mut()
            .publish(steps, || step_time.summary(), fill)?;
        Ok((self.summary, self.chunk.sent))
    }
}

/// The periodic progress line.
fn log_running(step: u64, score: &Score, driver: CommandSource, s: &Summary, answers: &Answers) {
    tracing::info!(
        step,
        laps = score.laps(),
        laps_ai = score.laps_under_active_inference(),
        driver = driver.name(),
        received = s.commands_received,
        missed = s.missed_commands,
        plan_followed = s.plan_followed,
        round_trip = %answers.round_trip.summary(),
        "running"
    );
}

/// Logs and counts the end of an episode: the car was put back at the start of its track, or
/// moved on to the next track.
fn new_episode(car: &Circuit, stepped: &Stepped, frame: &Frame, summary: &mut Summary) {
    let step = frame.step;
    if let Some(verdict) = stepped.reset {
        tracing::warn!(
            step,
            episode = frame.episode,
            lateral_m = frame.sensors.truth.lateral_m,
            "{}: back to the start, new episode",
            verdict_words(verdict)
        );
        summary.resets += 1;
        summary.wrong_way_resets += u64::from(verdict == Verdict::WrongWay);
    }
    if let Some(next) = stepped.switched_to {
        let track = car.world().config().track.display().to_string();
        tracing::info!(
            step,
            track,
            index = next,
            "next track: its start, new episode"
        );
        summary.track_switches += 1;
    }
}

/// The run's figures from the drive's score and the loop's latency records.
fn finish_summary(
    summary: &mut Summary,
    score: &Score,
    answers: &Answers,
    step_time: &LatencyStats,
    clock: &Clock,
    period: f64,
) {
    summary.round_trip = answers.round_trip.summary();
    summary.round_trip_hist = answers.round_trip.histogram();
    summary.cmd_to_sim = answers.cmd_to_sim.summary();
    summary.cmd_to_sim_hist = answers.cmd_to_sim.histogram();
    summary.step_time = step_time.summary();
    summary.step_time_hist = step_time.histogram();
    summary.tick_late = clock.late.summary();
    summary.tick_jitter = clock.jitter.summary();
    summary.laps = score.laps();
    summary.lateral_error_m = score.lateral();
    summary.control = score.control();
    // World time restarts with each episode.
    summary.sim_seconds = summary.steps as f64 * period;
}

fn fill_stats(s: &mut ProcessStats, score: &Score, summary: &Summary) {
    s.laps = score.laps();
    s.missed_commands = saturate(summary.missed_commands);
}

fn verdict_words(v: Verdict) -> &'static str {
    match v {
        Verdict::Lost => "car lost the line",
        _ => "car drives the wrong way round",
    }
}

/// Lockstep runs are only reproducible if every step is answered, so wait (bounded) for the
/// predictor, and for the trainer when one is expected, before the first step. A connection
/// raises no event: the wait looks every 10 ms.
fn wait_for_peers(
    ports: &Ports,
    cfg: &SimulatorConfig,
    shutdown: &Shutdown,
    watchdog: &mut Watchdog,
) -> anyhow::Result<()> {
    let ready = || {
        ports.commands.publishers() > 0 && (!cfg.expect_trainer || ports.replay.subscribers() > 0)
    };
    if ready() {
        return Ok(());
    }
    tracing::info!(
        expect_trainer = cfg.expect_trainer,
        "waiting for peers to connect"
    );
    let wake = Wake {
        every: Duration::from_millis(10),
        deadline: Instant::now() + Duration::from_secs_f64(cfg.wait_for_peers_s.max(0.0)),
    };
    let pet = || {
        watchdog.pet();
        Ok(())
    };
    if wait::until(&wake, shutdown, pet, ready)? == Waited::Deadline {
        tracing::warn!(
            "peers missing after {:.1} s: starting anyway (the teacher drives without a predictor)",
            cfg.wait_for_peers_s
        );
    }
    Ok(())
}

/// Keeps the replay publisher (this process) alive, up to `replay_linger_s`, until a subscribed
/// trainer says it has taken (or lost) every chunk sent: one that has not connected yet still
/// can, and takes the last chunks.
fn linger_for_replay(
    ports: &Ports,
    cfg: &SimulatorConfig,
    sent: u64,
    shutdown: &Shutdown,
    watchdog: &mut Watchdog,
) -> anyhow::Result<()> {
    if ports.replay.subscribers() == 0 || cfg.replay_linger_s <= 0.0 {
        return Ok(());
    }
    tracing::info!(
        seconds = cfg.replay_linger_s,
        sent,
        "lingering so the trainer can take the last replay chunks"
    );
    let deadline = Instant::now() + Duration::from_secs_f64(cfg.replay_linger_s);
    loop {
        watchdog.pet();
        let taken = ports
            .trainer_status
            .latest()?
            .is_some_and(|s| s.chunks_received + s.chunks_lost >= sent);
        let left = deadline.saturating_duration_since(Instant::now());
        if taken || left.is_zero() || shutdown.requested() {
            return Ok(());
        }
        // On the trainer's status event: no WaitSet (and no descriptor) just for the exit.
        ports.trainer_status.wait(left.min(wait::SIGNAL_LATENCY))?;
    }
}

/// Publishes what the car senses; returns the stamp the round trip starts from.
fn publish_observation(ports: &Ports, m: &Frame, lockstep: bool) -> anyhow::Result<u64> {
    let s = &m.sensors;
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
            o.lockstep = u8::from(lockstep);
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
