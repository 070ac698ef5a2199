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
use crate::schedule::Schedule;

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

/// Tells the simulator (pacing) how far training has come, and the predictor and simulator
/// when the next weights can be due.
fn publish_status(
    ports: &Ports,
    learner: &Learner,
    buffer: &ReplayBuffer,
    at: &Progress,
    training: bool,
) -> anyhow::Result<()> {
    let (schedule, session) = (&at.schedule, at.session);
    // The next update that publishes, counted in this process's updates.
    let step = learner.updates();
    let ahead = (1..).find(|d| learner.publishes_at(step + d)).unwrap_or(1);
    let next = schedule.next_install_step(session + ahead - 1, buffer.pace(), buffer);
    ports.status.send_with(|s| {
        s.published = schedule.published;
        s.last_install_step = schedule.last_install_step;
        s.next_install_step = next;
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

/// Where this process's run of updates stands.
struct Progress {
    /// Updates made by this process.
    session: u64,
    schedule: Schedule,
    curve: Option<Curve>,
    update_time: LatencyStats,
}

/// One update (at the schedule's horizon when there is one); sends the weights it publishes,
/// stamped with their install step.
fn update_once(
    ports: &Ports,
    learner: &mut Learner,
    buffer: &ReplayBuffer,
    at: &mut Progress,
) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let horizon = at.schedule.horizon(at.session, buffer.pace());
    let Some(Update { stats: u, publish }) = learner.train_once(buffer, horizon)? else {
        if horizon.is_some() {
            // No window before this horizon (or a refused update): the slot passes, so the
            // schedule moves on as it would anywhere.
            at.session += 1;
        }
        return Ok(());
    };
    if let Some(mut p) = publish {
        if let Some(h) = horizon {
            p.header.install_step = at.schedule.install_step(h, buffer);
            at.schedule.published += 1;
            at.schedule.last_install_step = p.header.install_step;
        }
        send(ports, p)?;
    }
    let took = t0.elapsed();
    at.update_time.record_ns(took.as_nanos() as u64);
    at.session += 1;
    if let Some(c) = at.curve.as_mut() {
        c.record(&CurvePoint {
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
        });
    }
    Ok(())
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
    let mut at = Progress {
        session: 0,
        schedule: Schedule::default(),
        curve: cfg.learning_log.as_deref().map(Curve::open).transpose()?,
        update_time: LatencyStats::new(),
    };
    publish_status(ports, &learner, &buffer, &at, false)?;
    tracing::info!(
        min_sequences = cfg.min_sequences,
        "model ready; waiting for replay chunks"
    );
    let mut watchdog = Watchdog::from_env();
    let mut last_log = Instant::now();
    let mut failure = None;
    while !shutdown.requested() && failure.is_none() {
        // With data to learn from, only look for new chunks and go on training; otherwise block
        // (also while ahead of a lockstep simulator's pace).
        let ready = learner.ready(&buffer);
        let rate = buffer.pace();
        let training = ready && at.schedule.may_update(at.session, rate, buffer.received());
        let timeout = if training {
            Duration::ZERO
        } else {
            Duration::from_millis(100)
        };
        let mut on_event = |id: WaitSetAttachmentId<ipc::Service>| {
            if id.has_event_from(&replay_guard) {
                // One chunk at a time: the schedule starts at the very chunk that made the
                // buffer ready, however many arrived together.
                let res = ports.replay.drain_events().and_then(|_| {
                    ports.replay.for_each(|c| {
                        buffer.push(c);
                        at.schedule.see(buffer.received(), learner.ready(&buffer));
                    })
                });
                if let Err(e) = res {
                    failure = Some(e);
                    return CallbackProgression::Stop;
                }
            }
            CallbackProgression::Continue
        };
        waitset.wait_and_process_once_with_timeout(&mut on_event, timeout)?;
        if training && failure.is_none() {
            update_once(ports, &mut learner, &buffer, &mut at)?;
            publish_status(ports, &learner, &buffer, &at, true)?;
        } else {
            // Also while filling the buffer or idle: a lockstep simulator waits on it (its
            // start, the schedule, the linger at exit), and iceoryx2 hands a late subscriber
            // the history only when the publisher sends.
            publish_status(ports, &learner, &buffer, &at, ready)?;
        }
        ports.weights.serve_new_subscribers()?;
        watchdog.pet();
        tick_stats(ports, &learner, &buffer, &at)?;
        if last_log.elapsed().as_secs_f64() >= cfg.log_every_s {
            last_log = Instant::now();
            log_running(&learner, &buffer, &at);
        }
    }
    if let Some(e) = failure {
        return Err(e.into());
    }
    finish(ports, learner, buffer, at)
}

/// This process's line on the stats topic (at most once a second).
fn tick_stats(
    ports: &Ports,
    learner: &Learner,
    buffer: &ReplayBuffer,
    at: &Progress,
) -> anyhow::Result<()> {
    ports.stats.borrow_mut().tick(
        learner.updates(),
        || at.update_time.summary(),
        |s| {
            s.replay_sequences = saturate(buffer.len() as u64);
            s.chunks_lost = saturate(buffer.lost());
            s.loss = learner.last_loss().map_or(f32::NAN, |l| l as f32);
            s.weights_published = saturate(learner.published());
            s.resumed_from_update = learner.resumed_from();
        },
    )?;
    Ok(())
}

/// The periodic progress line.
fn log_running(learner: &Learner, buffer: &ReplayBuffer, at: &Progress) {
    tracing::info!(
        chunks = buffer.received(),
        lost = buffer.lost(),
        buffered = buffer.len(),
        updates = learner.updates(),
        loss = ?learner.last_loss(),
        update = %at.update_time.summary(),
        "running"
    );
}

/// A clean stop loses nothing already delivered: the chunks still queued are counted (they
/// waited while an update ran), a lockstep run makes the updates its data is in for, and the
/// updates since the last publish are saved.
fn finish(
    ports: &Ports,
    mut learner: Learner,
    mut buffer: ReplayBuffer,
    mut at: Progress,
) -> anyhow::Result<Summary> {
    ports.replay.for_each(|c| {
        buffer.push(c);
        at.schedule.see(buffer.received(), learner.ready(&buffer));
    })?;
    // Lockstep learning: every update whose data is in is made, so a run learns the same
    // however soon after its last step the trainer is stopped.
    while at
        .schedule
        .horizon(at.session, buffer.pace())
        .is_some_and(|h| h <= buffer.received())
    {
        update_once(ports, &mut learner, &buffer, &mut at)?;
    }
    learner.save_on_stop()?;
    Ok(Summary {
        chunks_received: buffer.received(),
        chunks_lost: buffer.lost(),
        steps_received: buffer.steps_received(),
        exploration_fraction: buffer.exploration_fraction(),
        buffered_sequences: buffer.len(),
        session_updates: at.session,
        probe_step: learner.probe().map(|p| p.0),
        probe: learner.probe().map(|p| p.1),
        updates: learner.updates(),
        updates_refused: learner.refused,
        last_loss: learner.last_loss(),
        weights_published: learner.published(),
        resumed_from_update: learner.resumed_from(),
        update_time: at.update_time.summary(),
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
