//! `mta replay FILE.mcap`: plays a recording's observations (and, when recorded with
//! `--weight-blobs`, its weights) to a predictor in place of the simulator, and compares the
//! commands that come back with the recorded ones. In `--lockstep` each observation waits for
//! its command, so replaying a lockstep run to a predictor started from the same checkpoint and
//! config reproduces its commands bit for bit (`--expect-identical` makes a difference an
//! error). The recorded replay chunks go out too, for a trainer. Otherwise observations go out at the recorded pace times `--speed`. A truncated or
//! damaged recording is replayed as far as it can be read, and the summary says where it stopped.

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use iceoryx2::prelude::*;
use mtanet_ipc::cli::CommonArgs;
use mtanet_ipc::node::create_node;
use mtanet_ipc::ports::{Receiver, Sender, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::weights_topic::WeightsSender;
use mtanet_ipc::{Command, CommandSource, Observation, ReplayChunk, names, stamp};
use serde::{Deserialize, Serialize};

use crate::format::{self, Recorded};

#[derive(Debug, clap::Args)]
pub struct ReplayArgs {
    /// The recording (MCAP, from `mta record` or `./ops/run_local.sh --record`).
    file: PathBuf,
    #[command(flatten)]
    common: CommonArgs,
    /// Which process the recording stands in for (only the simulator, for now).
    #[arg(long, default_value = "simulator", value_parser = ["simulator"])]
    replace: String,
    /// Wait for each observation's command before the next (reproducible).
    #[arg(long)]
    lockstep: bool,
    /// Without --lockstep: the recorded pace times this (2: twice as fast).
    #[arg(long, default_value_t = 1.0)]
    speed: f64,
    /// Fail unless every command came back identical to the recorded one.
    #[arg(long)]
    expect_identical: bool,
    /// How long to wait for a predictor to subscribe.
    #[arg(long, default_value_t = 30.0)]
    wait_s: f64,
    /// How long to wait for a command: each one in lockstep, the last one when paced.
    #[arg(long, default_value_t = 5000)]
    command_timeout_ms: u64,
}

/// A command that differed from the recorded one.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Difference {
    pub step: u64,
    pub recorded: ([f32; 2], String),
    pub replayed: ([f32; 2], String),
}

/// What `mta replay` reports (`--summary FILE`).
#[derive(Debug, Default, Serialize, Deserialize)]
pub struct ReplaySummary {
    pub observations_sent: u64,
    pub weights_sent: u64,
    pub replay_chunks_sent: u64,
    pub commands_received: u64,
    /// Commands that had a recorded counterpart, and how many of those were identical (the
    /// wheel velocities and the plan carried bit for bit, and who decided).
    pub compared: u64,
    pub identical: u64,
    /// Lockstep: observations whose command did not come within the timeout.
    pub missing: u64,
    pub first_difference: Option<Difference>,
    /// Why the recording could not be read to its end, if it could not.
    pub damaged: Option<String>,
}

/// Replayed commands against the recorded ones, by step.
pub struct Comparison {
    recorded: HashMap<u64, Command>,
    pub summary: ReplaySummary,
}

fn name(source: u32) -> &'static str {
    CommandSource::from_u32(source).map_or("?", CommandSource::name)
}

impl Comparison {
    pub fn new(recorded: impl IntoIterator<Item = Command>) -> Self {
        Self {
            recorded: recorded.into_iter().map(|c| (c.step, c)).collect(),
            summary: ReplaySummary::default(),
        }
    }

    pub fn check(&mut self, c: &Command) {
        self.summary.commands_received += 1;
        let Some(r) = self.recorded.get(&c.step) else {
            return;
        };
        self.summary.compared += 1;
        let same = r.source == c.source
            && r.wheel_velocity.map(f32::to_bits) == c.wheel_velocity.map(f32::to_bits)
            && same_plan(r, c);
        if same {
            self.summary.identical += 1;
        } else if self.summary.first_difference.is_none() {
            self.summary.first_difference = Some(Difference {
                step: c.step,
                recorded: (r.wheel_velocity, name(r.source).into()),
                replayed: (c.wheel_velocity, name(c.source).into()),
            });
        }
    }
}

/// The plans two commands carry, bit for bit.
fn same_plan(a: &Command, b: &Command) -> bool {
    let bits = |c: &Command| c.plan.map(|w| w.map(f32::to_bits));
    (a.plan_first_step, a.plan_segment_steps, a.plan_len)
        == (b.plan_first_step, b.plan_segment_steps, b.plan_len)
        && bits(a) == bits(b)
}

pub fn run(args: ReplayArgs) -> anyhow::Result<()> {
    let (_, ipc) = args.common.load()?;
    anyhow::ensure!(args.speed > 0.0, "--speed must be > 0, not {}", args.speed);
    let shutdown = Shutdown::install()?;
    let reading = format::read(&args.file)?;
    if let Some(why) = &reading.damaged {
        tracing::warn!("{why}");
    }
    let recorded = reading.messages.iter().filter_map(|m| match &m.1 {
        Recorded::Command(c) => Some(*c),
        _ => None,
    });
    let mut cmp = Comparison::new(recorded);
    cmp.summary.damaged = reading.damaged.clone();
    let n_obs = reading
        .messages
        .iter()
        .filter(|m| matches!(m.1, Recorded::Observation(_)))
        .count();
    anyhow::ensure!(
        n_obs > 0,
        "{} holds no observations to replay",
        args.file.display()
    );

    let node = create_node(&ipc, "mta-replay")?;
    let out = Outlets::open(&node, &reading)?;
    if !out.await_predictor(&args, &ipc.namespace, &shutdown)? {
        return Ok(());
    }
    let pace = if args.lockstep {
        "lockstep".to_string()
    } else {
        format!("x{} pace", args.speed)
    };
    eprintln!(
        "[replay] {n_obs} observations from {} to the predictor in {:?} ({pace})",
        args.file.display(),
        ipc.namespace,
    );
    out.play(&reading, &args, &mut cmp, &shutdown)?;
    conclude(&args, &cmp.summary)
}

/// What stands in for the simulator (and the trainer's weights) before one predictor.
struct Outlets {
    obs: Sender<Observation>,
    cmds: Receiver<Command>,
    /// Only when the recording holds the weights' bytes.
    weights: Option<WeightsSender>,
    /// The simulator also feeds a trainer: its recorded chunks go out as they came.
    replay: Sender<ReplayChunk>,
}

impl Outlets {
    fn open(node: &Node<ipc::Service>, reading: &format::Reading) -> anyhow::Result<Self> {
        let has_blobs = reading
            .messages
            .iter()
            .any(|m| matches!(m.1, Recorded::Weights(_, Some(_))));
        Ok(Self {
            obs: Sender::open(node, names::OBSERVATION, TopicShape::STEP)?,
            cmds: Receiver::open_deep(node, names::COMMAND, TopicShape::STEP)?,
            weights: has_blobs.then(|| WeightsSender::open(node)).transpose()?,
            replay: Sender::open(node, names::REPLAY, TopicShape::REPLAY)?,
        })
    }

    /// Waits for a predictor (subscribed to observations, publishing commands); false when
    /// stopped first.
    fn await_predictor(
        &self,
        args: &ReplayArgs,
        ns: &str,
        shutdown: &Shutdown,
    ) -> anyhow::Result<bool> {
        let until = Instant::now() + Duration::from_secs_f64(args.wait_s);
        while self.obs.subscribers() == 0 || self.cmds.publishers() == 0 {
            if shutdown.requested() {
                return Ok(false);
            }
            if Instant::now() > until {
                bail!(
                    "no predictor in namespace {ns:?} within {} s (start mta-predictor first)",
                    args.wait_s
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        Ok(true)
    }

    /// Sends the recording's messages in order, at its pace or in lockstep, comparing the
    /// commands that come back.
    fn play(
        &self,
        reading: &format::Reading,
        args: &ReplayArgs,
        cmp: &mut Comparison,
        shutdown: &Shutdown,
    ) -> anyhow::Result<()> {
        let t0 = Instant::now();
        let mut sim0 = None;
        let mut last_step = None;
        for (_, m) in &reading.messages {
            if shutdown.requested() {
                break;
            }
            match m {
                Recorded::Weights(h, Some(blob)) => {
                    if let Some(w) = &self.weights {
                        w.send(*h, blob)?;
                        cmp.summary.weights_sent += 1;
                    }
                }
                Recorded::Replay(c) => {
                    self.replay.send_with(|slot| *slot = **c)?;
                    cmp.summary.replay_chunks_sent += 1;
                }
                Recorded::Observation(o) => {
                    if !args.lockstep {
                        let s0 = *sim0.get_or_insert(o.sim_time_s);
                        let after = ((o.sim_time_s - s0) / args.speed).max(0.0);
                        let due = t0 + Duration::from_secs_f64(after);
                        std::thread::sleep(due.saturating_duration_since(Instant::now()));
                    }
                    self.observe(o, args, cmp)?;
                    last_step = Some(o.step);
                }
                _ => {}
            }
        }
        // A paced replay has not waited for its last commands (a lockstep one awaited each).
        if let (false, Some(step)) = (args.lockstep, last_step) {
            wait_for(&self.cmds, step, args.command_timeout_ms, cmp)?;
        }
        Ok(())
    }

    /// Sends one observation (stamped now) and takes in the commands come back.
    fn observe(
        &self,
        o: &Observation,
        args: &ReplayArgs,
        cmp: &mut Comparison,
    ) -> anyhow::Result<()> {
        let mut sent = *o;
        sent.stamp_ns = stamp::monotonic_ns();
        self.obs.send_with(|slot| *slot = sent)?;
        cmp.summary.observations_sent += 1;
        if args.lockstep {
            if !wait_for(&self.cmds, o.step, args.command_timeout_ms, cmp)? {
                cmp.summary.missing += 1;
            }
        } else {
            self.cmds.for_each(|c| cmp.check(c))?;
        }
        Ok(())
    }
}

/// Prints and writes the summary; with `--expect-identical`, fails unless every command matched.
fn conclude(args: &ReplayArgs, s: &ReplaySummary) -> anyhow::Result<()> {
    println!("{}", serde_json::to_string_pretty(s)?);
    args.common.write_summary(s)?;
    if args.expect_identical {
        let ok = s.compared > 0 && s.identical == s.compared && s.missing == 0;
        anyhow::ensure!(
            ok,
            "replay differs from the recording: {} of {} commands identical, {} missing; first difference {:?}",
            s.identical,
            s.compared,
            s.missing,
            s.first_difference
        );
    }
    Ok(())
}

/// Lockstep: takes commands until the one for `step` (true) or the timeout (false).
fn wait_for(
    cmds: &Receiver<Command>,
    step: u64,
    timeout_ms: u64,
    cmp: &mut Comparison,
) -> anyhow::Result<bool> {
    let until = Instant::now() + Duration::from_millis(timeout_ms);
    loop {
        let mut got = false;
        cmds.drain_events()?;
        cmds.for_each(|c| {
            got |= c.step == step;
            cmp.check(c);
        })
        .context("reading commands")?;
        if got {
            return Ok(true);
        }
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Ok(false);
        }
        cmds.wait(left.min(Duration::from_millis(100)))?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cmd(step: u64, left: f32, source: CommandSource) -> Command {
        let mut c: Command = bytemuck::Zeroable::zeroed();
        c.step = step;
        c.wheel_velocity = [left, 8.0];
        c.source = source as u32;
        c
    }

    #[test]
    fn identical_means_the_same_bits_and_the_same_driver() {
        let ai = CommandSource::ActiveInference;
        let mut cmp = Comparison::new([cmd(1, 7.0, ai), cmd(2, 7.0, ai), cmd(3, 7.0, ai)]);
        cmp.check(&cmd(1, 7.0, ai));
        cmp.check(&cmd(2, 7.0 + f32::EPSILON * 4.0, ai));
        cmp.check(&cmd(3, 7.0, CommandSource::Reactive));
        cmp.check(&cmd(9, 7.0, ai)); // no recorded counterpart
        let s = &cmp.summary;
        assert_eq!((s.commands_received, s.compared, s.identical), (4, 3, 1));
        assert_eq!(s.first_difference.as_ref().unwrap().step, 2);
    }
}
