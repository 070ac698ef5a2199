//! The predictor loop: block in a WaitSet on observations and weights; answer each observation
//! with a command for the same step.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use mtanet_ipc::latency::{LatencyStats, LatencySummary};
use mtanet_ipc::node::create_waitset;
use mtanet_ipc::ports::{Receiver, Sender, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::systemd::Watchdog;
use mtanet_ipc::weights_topic::WeightsReceiver;
use mtanet_ipc::{Command, CommandSource, Observation, names, stamp};
use serde::{Deserialize, Serialize};

use crate::config::PredictorConfig;
use crate::policy::Policy;
use crate::world_model::WorldModel;

pub struct Ports {
    pub observations: Receiver<Observation>,
    pub commands: Sender<Command>,
    pub weights: WeightsReceiver,
}

impl Ports {
    pub fn open(node: &Node<ipc::Service>) -> anyhow::Result<Self> {
        Ok(Self {
            observations: Receiver::open(node, names::OBSERVATION, TopicShape::STEP)?,
            commands: Sender::open(node, names::COMMAND, TopicShape::STEP)?,
            weights: WeightsReceiver::open(node)?,
        })
    }
}

/// What the predictor reports at exit.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Summary {
    pub observations: u64,
    pub commands_sent: u64,
    /// Observations whose step did not follow the previous one (lost or reordered).
    pub step_gaps: u64,
    pub weights_received: u64,
    /// Weights that failed to decode or did not fit; the previous model stayed in use.
    pub weights_rejected: u64,
    pub model_version: u64,
    /// Steps decided by active inference / by the reactive rule.
    pub active_inference_steps: u64,
    pub reactive_steps: u64,
    /// Recent next-frame MSE of the model and of copying the last frame (the bar to beat).
    pub model_mse: Option<f64>,
    pub copy_last_mse: Option<f64>,
    /// Observation published -> command decided (transport in + own compute).
    pub observation_age: LatencySummary,
    /// Own compute per step until the command is sent (policy only).
    pub compute: LatencySummary,
    /// World-model step done after the command was sent, when the policy did not need it.
    pub world_update: LatencySummary,
}

/// Per-step latencies the loop records.
#[derive(Default)]
struct StepStats {
    age: LatencyStats,
    compute: LatencyStats,
    world_update: LatencyStats,
}

pub fn run(ports: &Ports, cfg: &PredictorConfig, shutdown: &Shutdown) -> anyhow::Result<Summary> {
    let waitset = create_waitset()?;
    let obs_guard = waitset.attach_notification(ports.observations.listener())?;
    let weights_guard = waitset.attach_notification(ports.weights.listener())?;
    let mut policy = Policy::new(cfg);
    let mut summary = Summary::default();
    let mut stats = StepStats::default();
    let mut expected_step: Option<u64> = None;
    let mut watchdog = Watchdog::from_env();
    let mut last_log = Instant::now();
    let mut failure: Option<anyhow::Error> = None;

    while !shutdown.requested() && failure.is_none() {
        let mut on_event = |id: WaitSetAttachmentId<ipc::Service>| {
            let result = if id.has_event_from(&obs_guard) {
                answer_observations(
                    ports,
                    &mut policy,
                    &mut summary,
                    &mut expected_step,
                    &mut stats,
                )
            } else if id.has_event_from(&weights_guard) {
                receive_weights(ports, &mut policy, &mut summary)
            } else {
                Ok(())
            };
            match result {
                Ok(()) => CallbackProgression::Continue,
                Err(e) => {
                    failure = Some(e);
                    CallbackProgression::Stop
                }
            }
        };
        // The timeout bounds how long a signal waits to be noticed.
        waitset.wait_and_process_once_with_timeout(&mut on_event, Duration::from_millis(100))?;
        watchdog.pet();
        if last_log.elapsed().as_secs_f64() >= cfg.log_every_s {
            last_log = Instant::now();
            let (model_mse, copy_mse) = policy
                .world
                .as_ref()
                .map_or((None, None), |w| (w.model_mse.get(), w.copy_mse.get()));
            tracing::info!(
                answered = summary.commands_sent,
                active_inference = summary.active_inference_steps,
                model_mse = ?model_mse,
                copy_last_mse = ?copy_mse,
                compute = %stats.compute.summary(),
                world_update = %stats.world_update.summary(),
                "running"
            );
        }
    }
    if let Some(e) = failure {
        return Err(e);
    }
    if let Some(w) = &policy.world {
        summary.model_mse = w.model_mse.get();
        summary.copy_last_mse = w.copy_mse.get();
    }
    summary.observation_age = stats.age.summary();
    summary.compute = stats.compute.summary();
    summary.world_update = stats.world_update.summary();
    Ok(summary)
}

fn answer_observations(
    ports: &Ports,
    policy: &mut Policy,
    summary: &mut Summary,
    expected_step: &mut Option<u64>,
    stats: &mut StepStats,
) -> anyhow::Result<()> {
    ports.observations.drain_events()?;
    let mut pending = Vec::new();
    ports.observations.for_each(|o| pending.push(*o))?;
    for obs in pending {
        summary.observations += 1;
        if expected_step.is_some_and(|s| s != obs.step) {
            summary.step_gaps += 1;
        }
        *expected_step = Some(obs.step + 1);
        let t0 = Instant::now();
        let (wheels, source) = policy.act(&obs)?;
        match source {
            CommandSource::ActiveInference => summary.active_inference_steps += 1,
            _ => summary.reactive_steps += 1,
        }
        let compute_ns = t0.elapsed().as_nanos() as u64;
        ports.commands.send_with(|c| {
            c.step = obs.step;
            c.obs_stamp_ns = obs.stamp_ns;
            c.model_version = summary.model_version;
            c.wheel_velocity = wheels;
            c.source = source as u32;
            c.compute_ns = compute_ns.min(u64::from(u32::MAX)) as u32;
            c.stamp_ns = stamp::monotonic_ns();
        })?;
        summary.commands_sent += 1;
        stats.compute.record_ns(compute_ns);
        stats.age.record_ns(stamp::elapsed_ns(obs.stamp_ns));
        let t1 = Instant::now();
        if policy.after_command()? {
            stats.world_update.record_ns(t1.elapsed().as_nanos() as u64);
        }
    }
    Ok(())
}

fn receive_weights(
    ports: &Ports,
    policy: &mut Policy,
    summary: &mut Summary,
) -> anyhow::Result<()> {
    let outcome = ports.weights.latest(|h, bytes| {
        let result = match policy.world.as_mut() {
            Some(world) => world.update(bytes, h.version),
            None => WorldModel::from_bytes(bytes, h.version).map(|w| policy.world = Some(w)),
        };
        (h.version, h.train_step, bytes.len(), result)
    })?;
    if let Some((version, train_step, len, result)) = outcome {
        summary.weights_received += 1;
        match result {
            Ok(()) => {
                summary.model_version = version;
                tracing::info!(version, train_step, bytes = len, "weights loaded");
            }
            Err(e) => {
                // A damaged or mismatched checkpoint must not stop the car: keep what we had.
                summary.weights_rejected += 1;
                tracing::error!(
                    version,
                    bytes = len,
                    "rejected weights, keeping the previous model: {e}"
                );
            }
        }
    }
    Ok(())
}
