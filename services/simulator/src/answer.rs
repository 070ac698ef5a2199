//! The command for a step: the predictor's answer to its observation, waited for up to a bound;
//! or, without one, the teacher's or the miss policy's stand-in. Counts what it saw.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use mtanet_ipc::incident::{self, IncidentKind};
use mtanet_ipc::latency::LatencyStats;
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::{Command, CommandSource, stamp};
use mtanet_scenes::{Frame, Teacher};

use crate::config::{MissPolicy, Mode, SimulatorConfig};
use crate::service::Ports;
use crate::summary::Summary;

/// Consecutive missed commands after which the simulator checks for a dead predictor.
const MISSES_BEFORE_CLEANUP: u32 = 3;
/// A lockstep wait this long is logged (once per step): a stopped predictor, say.
const LONG_WAIT: Duration = Duration::from_secs(10);

pub struct Answers {
    wait: Duration,
    lockstep: bool,
    on_miss: MissPolicy,
    /// The last command the world accepted (what `Hold` repeats).
    pub last: [f32; 2],
    /// The last command received, with the plan it carries (followed through missed steps).
    planned: Option<Command>,
    misses_in_a_row: u32,
    /// Observation published -> its command received.
    pub round_trip: LatencyStats,
    /// Command published by the predictor -> taken in here.
    pub cmd_to_sim: LatencyStats,
}

impl Answers {
    pub fn new(cfg: &SimulatorConfig, period_s: f64) -> Self {
        let timeout = Duration::from_millis(cfg.command_timeout_ms);
        Self {
            // Real time still waits for the answer to the frame just sent, but never past half
            // a period: the 50 Hz tick must hold even when the predictor is slow.
            wait: match cfg.mode {
                Mode::Lockstep => timeout,
                Mode::Realtime => timeout.min(Duration::from_secs_f64(period_s / 2.0)),
            },
            lockstep: cfg.mode == Mode::Lockstep,
            on_miss: cfg.on_missed_command,
            last: [0.0; 2],
            planned: None,
            misses_in_a_row: 0,
            round_trip: LatencyStats::new(),
            cmd_to_sim: LatencyStats::new(),
        }
    }

    /// The command for `frame` (published at `obs_stamp`, its step begun at `begun_ns`) and
    /// who decided it.
    #[allow(clippy::too_many_arguments)]
    pub fn take(
        &mut self,
        node: &Node<ipc::Service>,
        ports: &Ports,
        frame: &Frame,
        obs_stamp: u64,
        begun_ns: u64,
        teacher: &mut Teacher,
        summary: &mut Summary,
        shutdown: &Shutdown,
    ) -> anyhow::Result<([f32; 2], CommandSource)> {
        let predictor = ports.commands.publishers() > 0;
        // Without a predictor only look (no wait): one that answered and left still counts.
        let wait = if predictor { self.wait } else { Duration::ZERO };
        let answer = self.receive(node, ports, frame.step, wait, summary, shutdown)?;
        if let Some((c, received_ns)) = answer {
            self.misses_in_a_row = 0;
            if c.step == frame.step {
                summary.commands_received += 1;
                self.round_trip.record_ns(stamp::elapsed_ns(obs_stamp));
                self.cmd_to_sim
                    .record_ns(received_ns.saturating_sub(c.stamp_ns));
            }
            let source = CommandSource::from_u32(c.source).unwrap_or(CommandSource::Reactive);
            self.planned = Some(c);
            return Ok((c.wheel_velocity, source));
        }
        if !predictor {
            summary.teacher_steps += 1;
            return Ok((teacher.act(&frame.sensors), CommandSource::Teacher));
        }
        self.stand_in(node, frame, begun_ns, teacher, summary)
    }

    /// The predictor's command for `step`, waited for up to `wait`; in lockstep for as long as
    /// the predictor lives: a stand-in would make the run depend on the machine's speed (an
    /// evaluation run on a loaded machine would be driven partly by the teacher). A dead
    /// predictor's node is cleaned and ends the wait.
    fn receive(
        &mut self,
        node: &Node<ipc::Service>,
        ports: &Ports,
        step: u64,
        wait: Duration,
        summary: &mut Summary,
        shutdown: &Shutdown,
    ) -> anyhow::Result<Option<(Command, u64)>> {
        let stale = &mut summary.stale_commands;
        let mut answer = await_command(ports, step, wait, shutdown, stale)?;
        let since = Instant::now();
        let mut said = false;
        while answer.is_none()
            && self.lockstep
            && !shutdown.requested()
            && ports.commands.publishers() > 0
        {
            if clean_dead_nodes(node, &mut summary.dead_nodes_cleaned) > 0 {
                break;
            }
            if !said && since.elapsed() > LONG_WAIT {
                said = true;
                tracing::warn!(step, "lockstep: still waiting for the predictor's command");
            }
            answer = await_command(ports, step, wait, shutdown, stale)?;
        }
        Ok(answer)
    }

    /// No answer in time from a predictor that is there: the plan its last command carried,
    /// or else the miss policy's command.
    fn stand_in(
        &mut self,
        node: &Node<ipc::Service>,
        frame: &Frame,
        begun_ns: u64,
        teacher: &mut Teacher,
        summary: &mut Summary,
    ) -> anyhow::Result<([f32; 2], CommandSource)> {
        self.misses_in_a_row += 1;
        // A paused predictor: in real time the car goes on with the plan its last command
        // carried (lockstep waits for every command, or the predictor is dead).
        let planned = self.planned.as_ref().filter(|_| !self.lockstep);
        if let Some(w) = planned.and_then(|c| c.planned_at(frame.step)) {
            if self.misses_in_a_row == 1 {
                tracing::info!(
                    step = frame.step,
                    "no command in time: following the last plan"
                );
            }
            summary.plan_followed += 1;
            let source = planned.map_or(0, |c| c.source);
            let source = CommandSource::from_u32(source).unwrap_or(CommandSource::Reactive);
            return Ok((w, source));
        }
        summary.missed_commands += 1;
        if !self.lockstep {
            let kind = IncidentKind::MissedCommand;
            incident::record(&mut summary.incidents, frame.step, kind, begun_ns);
        }
        if self.misses_in_a_row == 1 {
            // Once per run of misses: a frozen peer must not flood the log.
            tracing::warn!(step = frame.step, wait_ms = self.wait.as_secs_f64() * 1e3, policy = ?self.on_miss, "no command in time for this step");
        }
        if self.misses_in_a_row >= MISSES_BEFORE_CLEANUP {
            // A predictor killed with SIGKILL still counts as connected until its node is
            // cleaned; without this every later step would wait the full timeout.
            self.misses_in_a_row = 0;
            clean_dead_nodes(node, &mut summary.dead_nodes_cleaned);
        }
        let cmd = match self.on_miss {
            MissPolicy::Teacher => teacher.act(&frame.sensors),
            MissPolicy::Stop => [0.0, 0.0],
            MissPolicy::Hold => self.last,
        };
        Ok((cmd, CommandSource::Teacher))
    }
}

/// Removes the nodes of dead peers (a SIGKILLed predictor); returns and counts how many.
fn clean_dead_nodes(node: &Node<ipc::Service>, count: &mut u64) -> u64 {
    let cleaned = node.try_cleanup_dead_nodes().cleanups;
    if cleaned > 0 {
        tracing::warn!(
            cleaned,
            "predictor stopped answering: removed dead nodes; the teacher drives until one connects"
        );
    }
    *count += cleaned;
    cleaned
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
        // Bounded so a signal ends the wait soon even if no command ever comes.
        ports
            .commands
            .wait(left.min(mtanet_ipc::wait::SIGNAL_LATENCY))?;
    }
}
