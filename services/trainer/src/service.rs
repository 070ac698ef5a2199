//! The trainer loop: copy replay chunks from shared memory into the replay buffer, and between
//! arrivals train one update at a time, publishing weights as they improve.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use mtanet_ipc::latency::LatencyStats;
use mtanet_ipc::node::create_waitset;
use mtanet_ipc::ports::{Receiver, Sender, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::stats::{StatsPublisher, saturate};
use mtanet_ipc::systemd::Watchdog;
use mtanet_ipc::weights_topic::WeightsSender;
use mtanet_ipc::{ReplayChunk, TrainerStatus, names, stamp};

use crate::config::TrainerConfig;
use crate::curve::{Curve, CurvePoint};
use crate::learner::{Learner, Publication, Update};
use crate::replay::ReplayBuffer;

/// What the trainer reports at exit (a plain data type of `mtanet-summaries`).
pub use mtanet_summaries::trainer::Summary;

pub struct Ports {
    pub replay: Receiver<ReplayChunk>,
    pub weights: WeightsSender,
    pub status: Sender<TrainerStatus>,
    pub stats: std::cell::RefCell<StatsPublisher>,
}

impl Ports {
    pub fn open(node: &Node<ipc::Service>) -> anyhow::Result<Self> {
        Ok(Self {
            replay: Receiver::open(node, names::REPLAY, TopicShape::REPLAY)?,
            weights: WeightsSender::open(node)?,
            status: Sender::open(node, names::TRAINER_STATUS, TopicShape::STATUS)?,
            stats: StatsPublisher::open(node, "trainer")?.into(),
        })
    }
}

/// Hands weights to the predictor.
fn send(ports: &Ports, p: Publication) -> anyhow::Result<()> {
    ports.weights.send(p.header, &p.bytes)?;
    let h = p.header;
    tracing::info!(
        version = h.version,
        step = h.train_step,
        loss = h.loss,
        bytes = p.bytes.len(),
        "weights published"
    );
    Ok(())
}

/// Tells the simulator (pacing) how far training has come.
fn publish_status(
    ports: &Ports,
    learner: &Learner,
    buffer: &ReplayBuffer,
    session: u64,
    training: bool,
) -> anyhow::Result<()> {
    ports.status.send_with(|s| {
        s.updates = learner.updates();
        s.session_updates = session;
        s.chunks_received = buffer.received();
        s.chunks_lost = buffer.lost();
        s.sequences = buffer.len() as u32;
        s.training = u32::from(training);
        s.stamp_ns = stamp::monotonic_ns();
    })?;
    Ok(())
}

/// Lockstep pacing from the trainer's side: the simulator waits when it is ahead of the rate in
/// its chunks; the trainer waits for steps when it is ahead, so the rate holds both ways.
#[derive(Default)]
struct KeepPace {
    start: Option<(u64, u64)>,
}

impl KeepPace {
    fn may_update(&mut self, buffer: &ReplayBuffer, session: u64) -> bool {
        let rate = f64::from(buffer.pace());
        if rate <= 0.0 {
            self.start = None;
            return true;
        }
        let (s0, u0) = *self.start.get_or_insert((buffer.steps_received(), session));
        // Slack: chunks arrive 20 steps at a time and the simulator's own slack is one update,
        // so being this far ahead never stops both sides at once.
        let slack = 2.0 + 40.0 * rate / 1000.0;
        let allowed = buffer.steps_received().saturating_sub(s0) as f64 * rate / 1000.0 + slack;
        (session.saturating_sub(u0) as f64) < allowed
    }
}

/// Runs until a signal. `learner` is built by the caller (with or without a probe).
pub fn run(ports: &Ports, cfg: &TrainerConfig, shutdown: &Shutdown) -> anyhow::Result<Summary> {
    run_with(ports, cfg, Learner::new(cfg)?, shutdown)
}

pub fn run_with(
    ports: &Ports,
    cfg: &TrainerConfig,
    mut learner: Learner,
    shutdown: &Shutdown,
) -> anyhow::Result<Summary> {
    let waitset = create_waitset()?;
    let replay_guard = waitset.attach_notification(ports.replay.listener())?;
    let mut buffer = ReplayBuffer::new(cfg.replay_capacity);
    if learner.has_trained_weights() {
        send(ports, learner.publication()?)?;
    }
    let mut session = 0u64;
    let mut keep_pace = KeepPace::default();
    publish_status(ports, &learner, &buffer, session, false)?;
    tracing::info!(
        min_sequences = cfg.min_sequences,
        "model ready; waiting for replay chunks"
    );
    let mut curve = cfg.learning_log.as_deref().map(Curve::open).transpose()?;
    let mut update_time = LatencyStats::new();
    let mut watchdog = Watchdog::from_env();
    let mut last_log = Instant::now();
    let mut failure = None;
    while !shutdown.requested() && failure.is_none() {
        // With data to learn from, only look for new chunks and go on training; otherwise block
        // (also while ahead of a lockstep simulator's pace).
        let ready = learner.ready(&buffer);
        let training = ready && keep_pace.may_update(&buffer, session);
        let timeout = if training {
            Duration::ZERO
        } else {
            Duration::from_millis(100)
        };
        let mut took = 0;
        let mut on_event = |id: WaitSetAttachmentId<ipc::Service>| {
            if id.has_event_from(&replay_guard) {
                let res = ports
                    .replay
                    .drain_events()
                    .and_then(|_| ports.replay.for_each(|c| buffer.push(c)));
                match res {
                    Ok(n) => took += n,
                    Err(e) => {
                        failure = Some(e);
                        return CallbackProgression::Stop;
                    }
                }
            }
            CallbackProgression::Continue
        };
        waitset.wait_and_process_once_with_timeout(&mut on_event, timeout)?;
        if training && failure.is_none() {
            let t0 = Instant::now();
            if let Some(Update { stats: u, publish }) = learner.train_once(&buffer)? {
                if let Some(p) = publish {
                    send(ports, p)?;
                }
                let took = t0.elapsed();
                update_time.record_ns(took.as_nanos() as u64);
                session += 1;
                if let Some(c) = curve.as_mut() {
                    let point = CurvePoint {
                        step: u.step,
                        wall_s: c.wall_s(),
                        loss: u.loss,
                        grad_norm: u.grad_norm,
                        clipped: u.clipped,
                        update_ms: took.as_secs_f64() * 1e3,
                        replay_sequences: buffer.len(),
                        chunks_received: buffer.received(),
                        chunks_lost: buffer.lost(),
                        steps_received: buffer.steps_received(),
                        probe: learner.probe().map(|p| p.1),
                    };
                    c.record(&point);
                }
            }
            publish_status(ports, &learner, &buffer, session, true)?;
        } else if ready || took > 0 {
            // Also while filling the buffer: a simulator lingering at exit waits for its last
            // chunks to be taken.
            publish_status(ports, &learner, &buffer, session, ready)?;
        }
        ports.weights.serve_new_subscribers()?;
        watchdog.pet();
        ports.stats.borrow_mut().tick(
            learner.updates(),
            || update_time.summary(),
            |s| {
                s.replay_sequences = saturate(buffer.len() as u64);
                s.chunks_lost = saturate(buffer.lost());
                s.loss = learner.last_loss().map_or(f32::NAN, |l| l as f32);
                s.weights_published = saturate(learner.published());
                s.resumed_from_update = learner.resumed_from();
            },
        )?;
        if last_log.elapsed().as_secs_f64() >= cfg.log_every_s {
            last_log = Instant::now();
            tracing::info!(
                chunks = buffer.received(),
                lost = buffer.lost(),
                buffered = buffer.len(),
                updates = learner.updates(),
                loss = ?learner.last_loss(),
                update = %update_time.summary(),
                "running"
            );
        }
    }
    if let Some(e) = failure {
        return Err(e.into());
    }
    // A clean stop loses nothing already delivered: count the chunks still queued (they were
    // waiting while an update ran) and keep the updates made since the last publish on disk.
    ports.replay.for_each(|c| buffer.push(c))?;
    learner.save_on_stop()?;
    Ok(Summary {
        chunks_received: buffer.received(),
        chunks_lost: buffer.lost(),
        steps_received: buffer.steps_received(),
        exploration_fraction: buffer.exploration_fraction(),
        buffered_sequences: buffer.len(),
        session_updates: session,
        probe_step: learner.probe().map(|p| p.0),
        probe: learner.probe().map(|p| p.1),
        updates: learner.updates(),
        updates_refused: learner.refused,
        last_loss: learner.last_loss(),
        weights_published: learner.published(),
        resumed_from_update: learner.resumed_from(),
        update_time: update_time.summary(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use mtanet_ipc::node::{IpcConfig, create_node, remove_namespace_files};
    use mtanet_ipc::ports::Sender;

    /// A stop that comes while chunks wait in the queue (the trainer was busy with an update)
    /// still takes them in: what shared memory delivered is counted, not dropped.
    #[test]
    fn a_stop_takes_in_the_chunks_still_queued() {
        let ipc = IpcConfig {
            namespace: format!("trq{}", std::process::id()),
        };
        let node = create_node(&ipc, "trainer-test").unwrap();
        let ports = Ports::open(&node).unwrap();
        let sender: Sender<ReplayChunk> =
            Sender::open(&node, names::REPLAY, TopicShape::REPLAY).unwrap();
        for seq in 0..10 {
            sender
                .send_with(|c| {
                    c.seq = seq;
                    c.len = 20;
                })
                .unwrap();
        }
        let shutdown = Shutdown::manual();
        shutdown.request();
        let s = run(&ports, &TrainerConfig::default(), &shutdown).unwrap();
        assert_eq!((s.chunks_received, s.chunks_lost), (10, 0), "{s:?}");
        assert_eq!(s.steps_received, 200);
        drop((sender, ports, node));
        remove_namespace_files(&ipc.namespace);
    }
}
