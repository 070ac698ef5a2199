//! `mta record --out FILE.mcap`: the live topics of a stack into an MCAP file (see
//! [`crate::format`] for the format), until Ctrl-C / SIGTERM or `--seconds`. Observations and
//! commands are read through deep queues (64 samples) and counted by step, so a step the
//! recorder missed is reported, never silently absent. `./ops/run_local.sh --record` runs it
//! beside the stack into the run folder.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use mtanet_ipc::cli::CommonArgs;
use mtanet_ipc::node::{create_node, create_waitset};
use mtanet_ipc::ports::{Receiver, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::weights_topic::WeightsReceiver;
use mtanet_ipc::{Command, Observation, ReplayChunk, TrainerStatus, names, systemd};
use serde::{Deserialize, Serialize};

use crate::format::{RecordingWriter, TOPICS};

#[derive(Debug, clap::Args)]
pub struct RecordArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// The recording to write (MCAP).
    #[arg(long)]
    out: PathBuf,
    /// Topics to record (default: all of them).
    #[arg(long, value_delimiter = ',', value_parser = clap::builder::PossibleValuesParser::new(TOPICS))]
    topics: Vec<String>,
    /// Record the weights' checkpoint bytes too (~1 MB each), not only their headers; replay
    /// can then hand the same weights to a predictor.
    #[arg(long)]
    weight_blobs: bool,
    /// Stop after this many seconds (0: until Ctrl-C / SIGTERM).
    #[arg(long, default_value_t = 0.0)]
    seconds: f64,
}

/// What a recording run reports at its end (stderr, and `--summary`).
#[derive(Debug, Default, Serialize, Deserialize)]
pub struct RecordSummary {
    /// Messages recorded, by topic.
    pub messages: std::collections::BTreeMap<String, u64>,
    pub bytes: u64,
    pub seconds: f64,
    /// Steps missing between recorded observations (commands) of one simulator run.
    pub missed_observations: u64,
    pub missed_commands: u64,
}

/// Counts the steps a sequence of step numbers skipped (a restarted simulator starts again).
#[derive(Default)]
struct Gaps {
    last: Option<u64>,
    missed: u64,
}

impl Gaps {
    fn see(&mut self, step: u64) {
        if let Some(l) = self.last
            && step > l
        {
            self.missed += step - l - 1;
        }
        self.last = Some(step);
    }
}

/// Everything pending on a topic (copied out, so the samples go back to the publisher at once).
fn drain<T: std::fmt::Debug + Copy + ZeroCopySend>(
    r: &Option<Receiver<T>>,
) -> anyhow::Result<Vec<T>> {
    let mut batch = Vec::new();
    if let Some(r) = r {
        r.drain_events()?;
        r.for_each(|m| batch.push(*m))?;
    }
    Ok(batch)
}

/// The topics being recorded: a port for each one asked for.
struct Taps {
    obs: Option<Receiver<Observation>>,
    cmds: Option<Receiver<Command>>,
    replay: Option<Receiver<ReplayChunk>>,
    status: Option<Receiver<TrainerStatus>>,
    weights: Option<WeightsReceiver>,
}

/// Steps skipped between recorded observations and between recorded commands.
#[derive(Default)]
struct StepGaps {
    obs: Gaps,
    cmds: Gaps,
}

impl Taps {
    fn open(node: &Node<ipc::Service>, topics: &[String]) -> anyhow::Result<Self> {
        let want = |t: &str| topics.is_empty() || topics.iter().any(|x| x == t);
        Ok(Self {
            obs: want("observation")
                .then(|| Receiver::open_deep(node, names::OBSERVATION, TopicShape::STEP))
                .transpose()?,
            cmds: want("command")
                .then(|| Receiver::open_deep(node, names::COMMAND, TopicShape::STEP))
                .transpose()?,
            replay: want("replay")
                .then(|| Receiver::open(node, names::REPLAY, TopicShape::REPLAY))
                .transpose()?,
            status: want("trainer_status")
                .then(|| Receiver::open(node, names::TRAINER_STATUS, TopicShape::STATUS))
                .transpose()?,
            weights: want("weights")
                .then(|| WeightsReceiver::open(node))
                .transpose()?,
        })
    }

    /// Wakes `waitset` on every topic that notifies (the trainer's status only publishes).
    fn attach<'w>(
        &'w self,
        waitset: &'w WaitSet<ipc::Service>,
    ) -> anyhow::Result<Vec<WaitSetGuard<'w, 'w, ipc::Service>>> {
        let mut guards = Vec::new();
        let listeners = [
            self.obs.as_ref().map(|r| r.listener()),
            self.cmds.as_ref().map(|r| r.listener()),
            self.replay.as_ref().map(|r| r.listener()),
            self.weights.as_ref().map(|r| r.listener()),
        ];
        for l in listeners.into_iter().flatten() {
            guards.push(waitset.attach_notification(l)?);
        }
        Ok(guards)
    }

    /// Writes everything pending on every topic, whichever woke the loop.
    fn drain_into(
        &self,
        out: &mut RecordingWriter<impl std::io::Write + std::io::Seek>,
        gaps: &mut StepGaps,
        blobs: bool,
    ) -> anyhow::Result<()> {
        for o in drain(&self.obs)? {
            gaps.obs.see(o.step);
            out.observation(&o)?;
        }
        for c in drain(&self.cmds)? {
            gaps.cmds.see(c.step);
            out.command(&c)?;
        }
        for c in drain(&self.replay)? {
            out.replay(&c)?;
        }
        if let Some(r) = &self.status
            && let Some(s) = r.latest()?
        {
            out.trainer_status(&s)?;
        }
        if let Some(w) = &self.weights {
            let got = w.latest(|h, bytes| (*h, blobs.then(|| bytes.to_vec())))?;
            if let Some((h, b)) = got {
                out.weights(&h, b.as_deref())?;
            }
        }
        Ok(())
    }
}

pub fn run(args: RecordArgs) -> anyhow::Result<()> {
    let (_, ipc) = args.common.load()?;
    let shutdown = Shutdown::install()?;
    let node = create_node(&ipc, &format!("mta-record-{}", std::process::id()))?;
    let taps = Taps::open(&node, &args.topics)?;
    let mut gaps = StepGaps::default();
    let waitset = create_waitset()?;
    let _guards = taps.attach(&waitset)?;
    let mut out = RecordingWriter::create(&args.out)?;
    systemd::ready("recording");
    tracing::info!(out = %args.out.display(), namespace = %ipc.namespace, "recording");
    let start = Instant::now();
    let mut last_flush = Instant::now();
    let mut failure = None;
    while !shutdown.requested()
        && (args.seconds <= 0.0 || start.elapsed().as_secs_f64() < args.seconds)
    {
        waitset.wait_and_process_once_with_timeout(
            |_| CallbackProgression::Continue,
            Duration::from_millis(100),
        )?;
        if let Err(e) = taps.drain_into(&mut out, &mut gaps, args.weight_blobs) {
            failure = Some(e);
            break;
        }
        if last_flush.elapsed() >= Duration::from_secs(1) {
            last_flush = Instant::now();
            out.flush()?;
        }
    }
    let counts = out.counts.clone();
    out.finish()?;
    let summary = RecordSummary {
        messages: counts
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect(),
        bytes: std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0),
        seconds: start.elapsed().as_secs_f64(),
        missed_observations: gaps.obs.missed,
        missed_commands: gaps.cmds.missed,
    };
    systemd::stopping();
    tracing::info!(summary = %serde_json::to_string(&summary)?, "recording closed");
    args.common.write_summary(&summary)?;
    match failure {
        Some(e) => Err(e),
        None => Ok(()),
    }
}
