//! The predictor loop: block in a WaitSet on observations and weights; answer each observation
//! with a command for the same step.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use mtanet_ipc::incident::{self, IncidentKind};
use mtanet_ipc::latency::LatencyStats;
use mtanet_ipc::node::create_waitset;
use mtanet_ipc::ports::{Receiver, Sender, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::stats::{StatsPublisher, saturate};
use mtanet_ipc::systemd::Watchdog;
use mtanet_ipc::weights_topic::WeightsReceiver;

// A command carries the longest plan the planner makes.
const _: () = assert!(mtanet_control::MAX_HORIZON == mtanet_ipc::PLAN_SEGMENTS);
use mtanet_control::Decision;
use mtanet_ipc::{Command, Observation, names, stamp};

use crate::config::PredictorConfig;
use crate::intake::Intake;
use crate::policy::Policy;

/// What the predictor reports at exit (a plain data type of `mtanet-summaries`).
pub use mtanet_summaries::predictor::Summary;

pub struct Ports {
    pub observations: Receiver<Observation>,
    pub commands: Sender<Command>,
    pub weights: WeightsReceiver,
    pub stats: std::cell::RefCell<StatsPublisher>,
}

impl Ports {
    pub fn open(node: &Node<ipc::Service>) -> anyhow::Result<Self> {
        Ok(Self {
            observations: Receiver::open(node, names::OBSERVATION, TopicShape::STEP)?,
            commands: Sender::open(node, names::COMMAND, TopicShape::STEP)?,
            weights: WeightsReceiver::open(node)?,
            stats: StatsPublisher::open(node, "predictor")?.into(),
        })
    }
}

/// Per-step latencies the loop records.
#[derive(Default)]
struct StepStats {
    receive: LatencyStats,
    after: LatencyStats,
    age: LatencyStats,
    compute: LatencyStats,
    plan: LatencyStats,
    /// The source of the last command sent.
    source: u32,
}

pub fn run(ports: &Ports, cfg: &PredictorConfig, shutdown: &Shutdown) -> anyhow::Result<Summary> {
    run_with(ports, cfg, Policy::new(cfg), shutdown)
}

/// [`run`] with a policy made by the caller (e.g. with weights loaded from a file).
pub fn run_with(
    ports: &Ports,
    cfg: &PredictorConfig,
    mut policy: Policy,
    shutdown: &Shutdown,
) -> anyhow::Result<Summary> {
    let waitset = create_waitset()?;
    let obs_guard = waitset.attach_notification(ports.observations.listener())?;
    let _weights_guard = waitset.attach_notification(ports.weights.listener())?;
    let mut summary = Summary::default();
    let mut stats = StepStats::default();
    let mut expected_step: Option<u64> = None;
    let mut watchdog = Watchdog::from_env();
    let mut last_log = Instant::now();
    let mut failure: Option<anyhow::Error> = None;
    let mut intake = Intake::new(cfg.helpers_nice)?;
    // Ready only now: a simulator started on READY must find this loop answering its first step.
    mtanet_ipc::systemd::ready("predictor running");

    while !shutdown.requested() && failure.is_none() {
        let mut on_event = |id: WaitSetAttachmentId<ipc::Service>| {
            let result = if id.has_event_from(&obs_guard) {
                answer_observations(
                    ports,
                    &mut policy,
                    &mut intake,
                    &mut summary,
                    &mut expected_step,
                    &mut stats,
                )
            } else {
                // Weights are taken in after the wait: their event only wakes the loop.
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
        if failure.is_none() {
            // Also without an event: a notification sent before this listener existed (the
            // trainer serving a new subscriber) is lost, the weights are not.
            intake.receive(ports, &mut summary)?;
        }
        intake.install_due(None, &mut policy, &mut summary)?;
        watchdog.pet();
        publish_stats(ports, &policy, &summary, &stats)?;
        if last_log.elapsed().as_secs_f64() >= cfg.log_every_s {
            last_log = Instant::now();
            log_progress(&policy, &summary, &stats);
        }
    }
    match failure {
        Some(e) => Err(e),
        None => Ok(conclude(summary, &policy, &stats)),
    }
}

/// The process's stats sample, at most every stats period.
fn publish_stats(
    ports: &Ports,
    policy: &Policy,
    summary: &Summary,
    stats: &StepStats,
) -> anyhow::Result<()> {
    ports.stats.borrow_mut().tick(
        summary.commands_sent,
        || stats.compute.summary(),
        |s| {
            s.driver = stats.source;
            s.fallbacks = saturate(policy.stats().fallbacks);
            s.weights_installed = saturate(summary.weights_installed);
            s.weights_rejected = saturate(summary.weights_rejected);
            s.weights_held_back = saturate(summary.weights_held_back);
            s.model_version = summary.model_version;
            s.model_over_copy_last = policy
                .model()
                .and_then(|m| m.error_ratio())
                .map_or(f32::NAN, |r| r as f32);
        },
    )?;
    Ok(())
}

fn log_progress(policy: &Policy, summary: &Summary, stats: &StepStats) {
    let ratio = policy.model().and_then(|m| m.error_ratio());
    let c = policy.stats();
    tracing::info!(
        answered = summary.commands_sent,
        active_inference = c.active_inference_steps,
        fallbacks = c.fallbacks,
        late_plans = c.late_plans,
        model_over_copy_last = ?ratio,
        probe = ?policy.model().and_then(|m| m.probe),
        compute = %stats.compute.summary(),
        plan = %stats.plan.summary(),
        planning = %policy.planning(),
        "running"
    );
}

/// The summary at exit: the loop's counts with the policy's and the latencies'.
fn conclude(mut summary: Summary, policy: &Policy, stats: &StepStats) -> Summary {
    if let Some(m) = policy.model() {
        summary.model_mse = m.model_mse.get();
        summary.copy_last_mse = m.copy_mse.get();
        summary.probe = m.probe;
    }
    summary.control = policy.stats();
    summary.planning = policy.planning();
    summary.observation_age = stats.age.summary();
    summary.compute = stats.compute.summary();
    summary.plan = stats.plan.summary();
    summary.after_command = stats.after.summary();
    summary.compute_hist = stats.compute.histogram();
    summary.obs_to_predictor = stats.receive.summary();
    summary.obs_to_predictor_hist = stats.receive.histogram();
    summary
}

/// The command answering `obs`, with the plan it comes from and the model's health.
fn send_command(
    ports: &Ports,
    policy: &Policy,
    obs: &Observation,
    decision: &Decision,
    compute_ns: u64,
    summary: &mut Summary,
) -> anyhow::Result<()> {
    let (ratio, probe) = policy
        .model()
        .map_or((None, None), |m| (m.error_ratio(), m.probe));
    ports.commands.send_with(|c| {
        c.step = obs.step;
        c.obs_stamp_ns = obs.stamp_ns;
        c.model_version = summary.model_version;
        c.wheel_velocity = decision.wheels;
        c.source = decision.driver.source() as u32;
        c.compute_ns = compute_ns.min(u64::from(u32::MAX)) as u32;
        c.model_error_ratio = ratio.map_or(f32::NAN, |r| r as f32);
        c.probe = probe.map_or(f32::NAN, |p| p as f32);
        let ahead = &decision.ahead;
        c.set_plan(ahead.first_step, ahead.segment_steps, ahead.segments());
        c.stamp_ns = stamp::monotonic_ns();
    })?;
    summary.commands_sent += 1;
    Ok(())
}

fn answer_observations(
    ports: &Ports,
    policy: &mut Policy,
    intake: &mut Intake,
    summary: &mut Summary,
    expected_step: &mut Option<u64>,
    stats: &mut StepStats,
) -> anyhow::Result<()> {
    ports.observations.drain_events()?;
    let mut pending = Vec::new();
    ports.observations.for_each(|o| {
        stats.receive.record_ns(stamp::elapsed_ns(o.stamp_ns));
        pending.push(*o)
    })?;
    let newest = pending.last().map(|o| o.step);
    for obs in pending {
        summary.observations += 1;
        if expected_step.is_some_and(|s| s != obs.step) {
            summary.step_gaps += 1;
        }
        *expected_step = Some(obs.step + 1);
        // Weights sent before this observation and due at its step drive it.
        intake.receive(ports, summary)?;
        intake.install_due(Some(obs.step), policy, summary)?;
        let t0 = Instant::now();
        let decision = policy.act(&obs)?;
        if decision.late_plan {
            // Asked for a segment (frame_skip steps) before the one it was due for.
            let segment = policy.model().map_or(1, |m| m.config().frame_skip.max(1));
            let asked = obs
                .stamp_ns
                .saturating_sub((segment as f64 * mtanet_ipc::CONTROL_PERIOD_S * 1e9) as u64);
            incident::record(
                &mut summary.incidents,
                obs.step,
                IncidentKind::LatePlan,
                asked,
            );
        }
        let compute_ns = t0.elapsed().as_nanos() as u64;
        if Some(obs.step) == newest {
            send_command(ports, policy, &obs, &decision, compute_ns, summary)?;
        } else {
            // A newer observation waits (this process was paused): the simulator has moved
            // past this step and would drop its answer. The agent still took the frame in.
            summary.superseded += 1;
        }
        stats.source = decision.driver.source() as u32;
        stats.compute.record_ns(compute_ns);
        stats.age.record_ns(stamp::elapsed_ns(obs.stamp_ns));
        if let Some((_, plan)) = &decision.plan {
            stats.plan.record_ns(plan.as_nanos() as u64);
        }
        // The model step and the next plan's submission, now the car has its command.
        let t1 = Instant::now();
        policy.after_command()?;
        stats.after.record_ns(t1.elapsed().as_nanos() as u64);
    }
    Ok(())
}
