//! The trainer loop: copy replay chunks from shared memory into the replay buffer, and between
//! arrivals train one update at a time, publishing weights as they improve.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use mtanet_ipc::latency::{LatencyStats, LatencySummary};
use mtanet_ipc::node::create_waitset;
use mtanet_ipc::ports::{Receiver, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::systemd::Watchdog;
use mtanet_ipc::weights_topic::WeightsSender;
use mtanet_ipc::{ReplayChunk, names};
use serde::{Deserialize, Serialize};

use crate::config::TrainerConfig;
use crate::learner::Learner;
use crate::replay::ReplayBuffer;

pub struct Ports {
    pub replay: Receiver<ReplayChunk>,
    pub weights: WeightsSender,
}

impl Ports {
    pub fn open(node: &Node<ipc::Service>) -> anyhow::Result<Self> {
        Ok(Self {
            replay: Receiver::open(node, names::REPLAY, TopicShape::REPLAY)?,
            weights: WeightsSender::open(node)?,
        })
    }
}

/// What the trainer reports at exit.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Summary {
    pub chunks_received: u64,
    /// Chunks missing from the sequence numbers (overwritten before they were read).
    pub chunks_lost: u64,
    pub steps_received: u64,
    pub buffered_sequences: usize,
    /// Accepted training updates (including those of a resumed checkpoint).
    pub updates: u64,
    /// Updates refused by the non-finite guard.
    pub updates_refused: u64,
    pub last_loss: Option<f64>,
    pub weights_published: u64,
    /// Wall time of one training update.
    pub update_time: LatencySummary,
}

pub fn run(ports: &Ports, cfg: &TrainerConfig, shutdown: &Shutdown) -> anyhow::Result<Summary> {
    let waitset = create_waitset()?;
    let replay_guard = waitset.attach_notification(ports.replay.listener())?;
    let mut buffer = ReplayBuffer::new(cfg.replay_capacity);
    let mut learner = Learner::new(cfg)?;
    if learner.has_trained_weights() {
        learner.publish(&ports.weights)?;
    }
    tracing::info!(
        min_sequences = cfg.min_sequences,
        "model ready; waiting for replay chunks"
    );
    let mut update_time = LatencyStats::new();
    let mut watchdog = Watchdog::from_env();
    let mut last_log = Instant::now();
    let mut failure = None;
    while !shutdown.requested() && failure.is_none() {
        // With data to learn from, only look for new chunks and go on training; otherwise block.
        let training = learner.ready(&buffer);
        let timeout = if training {
            Duration::ZERO
        } else {
            Duration::from_millis(100)
        };
        let mut on_event = |id: WaitSetAttachmentId<ipc::Service>| {
            if id.has_event_from(&replay_guard) {
                let res = ports
                    .replay
                    .drain_events()
                    .and_then(|_| ports.replay.for_each(|c| buffer.push(c)));
                if let Err(e) = res {
                    failure = Some(e);
                    return CallbackProgression::Stop;
                }
            }
            CallbackProgression::Continue
        };
        waitset.wait_and_process_once_with_timeout(&mut on_event, timeout)?;
        if training && failure.is_none() {
            let t0 = Instant::now();
            learner.train_once(&buffer, &ports.weights)?;
            update_time.record_ns(t0.elapsed().as_nanos() as u64);
        }
        ports.weights.serve_new_subscribers()?;
        watchdog.pet();
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
        buffered_sequences: buffer.len(),
        updates: learner.updates(),
        updates_refused: learner.refused,
        last_loss: learner.last_loss(),
        weights_published: learner.published(),
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
