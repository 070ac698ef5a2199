//! The transport floor for `mta soak`: a raw iceoryx2 ping-pong between this process and a peer
//! process (`mta pingpong-peer`), with the stack's payloads (an `Observation` out, a `Command`
//! back) and its wake-up mechanism (event notification; the peer blocks in a WaitSet like the
//! predictor, this side waits on its listener like the simulator), paced at the control period.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use iceoryx2::prelude::*;
use mtanet_ipc::latency::LatencyStats;
use mtanet_ipc::node::{IpcConfig, create_node, create_waitset};
use mtanet_ipc::ports::{Receiver, Sender, TopicShape};
use mtanet_ipc::shutdown::Shutdown;
use mtanet_ipc::{Command, Observation, stamp};

const PING: &str = "mtanet-soak/ping";
const PONG: &str = "mtanet-soak/pong";

#[derive(Debug, clap::Args)]
pub struct PeerArgs {
    #[arg(long)]
    namespace: String,
    /// SCHED_FIFO priority, as the predictor's (the floor must be measured like the stack runs).
    #[arg(long)]
    priority: Option<i32>,
}

/// Puts the calling thread under SCHED_FIFO at `priority` (none: leaves it); false when refused.
pub fn realtime(priority: Option<i32>) -> bool {
    let Some(p) = priority else { return true };
    let ok = mtanet_ipc::sched::set_thread_fifo(p);
    if !ok {
        tracing::warn!(
            priority = p,
            "SCHED_FIFO refused; the ping-pong runs with the normal scheduler"
        );
    }
    ok
}

/// The peer: answers every ping with a pong until SIGTERM.
pub fn peer(args: PeerArgs) -> anyhow::Result<()> {
    let shutdown = Shutdown::install()?;
    realtime(args.priority);
    let node = create_node(
        &IpcConfig {
            namespace: args.namespace,
        },
        "pingpong-peer",
    )?;
    let ping = Receiver::<Observation>::open(&node, PING, TopicShape::STEP)?;
    let pong = Sender::<Command>::open(&node, PONG, TopicShape::STEP)?;
    let waitset = create_waitset()?;
    let guard = waitset.attach_notification(ping.listener())?;
    while !shutdown.requested() {
        let mut failure = None;
        let mut on_event = |id: WaitSetAttachmentId<ipc::Service>| {
            if id.has_event_from(&guard) {
                let r = ping.drain_events().and_then(|_| {
                    let mut seen = Vec::new();
                    ping.for_each(|o| seen.push((o.step, o.stamp_ns)))?;
                    for (step, obs_stamp_ns) in seen {
                        pong.send_with(|c| {
                            c.step = step;
                            c.obs_stamp_ns = obs_stamp_ns;
                            c.stamp_ns = stamp::monotonic_ns();
                        })?;
                    }
                    Ok(())
                });
                if let Err(e) = r {
                    failure = Some(e);
                    return CallbackProgression::Stop;
                }
            }
            CallbackProgression::Continue
        };
        waitset.wait_and_process_once_with_timeout(&mut on_event, Duration::from_millis(100))?;
        if let Some(e) = failure {
            return Err(e.into());
        }
    }
    Ok(())
}

/// Pings the peer every `period` for `duration` or until `stop`, at the simulator's `priority`; round trips that never came
/// back within the period count as lost.
pub fn measure(
    ns: &str,
    period: Duration,
    duration: Duration,
    stop: &AtomicBool,
    priority: Option<i32>,
) -> anyhow::Result<(LatencyStats, u64)> {
    realtime(priority);
    let node = create_node(
        &IpcConfig {
            namespace: ns.into(),
        },
        "pingpong",
    )?;
    let ping = Sender::<Observation>::open(&node, PING, TopicShape::STEP)?;
    let pong = Receiver::<Command>::open(&node, PONG, TopicShape::STEP)?;
    let t0 = Instant::now();
    while ping.subscribers() == 0 || pong.publishers() == 0 {
        anyhow::ensure!(
            t0.elapsed() < Duration::from_secs(20),
            "the ping-pong peer did not come up"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut stats = LatencyStats::new();
    let mut lost = 0;
    let start = Instant::now();
    let mut k = 0u64;
    while start.elapsed() < duration && !stop.load(Ordering::Relaxed) {
        // Stamped last before sending, as the simulator stamps its observations.
        let mut stamp0 = 0;
        ping.send_with(|o| {
            o.step = k;
            o.stamp_ns = stamp::monotonic_ns();
            stamp0 = o.stamp_ns;
        })?;
        let deadline = Instant::now() + period;
        let mut back = false;
        while !back && Instant::now() < deadline {
            pong.for_each(|c| back |= c.step == k)?;
            if back {
                stats.record_ns(stamp::elapsed_ns(stamp0));
            } else {
                pong.wait(deadline.saturating_duration_since(Instant::now()))?;
            }
        }
        lost += u64::from(!back);
        k += 1;
        let next = start + period * k as u32;
        std::thread::sleep(next.saturating_duration_since(Instant::now()));
    }
    Ok((stats, lost))
}

/// The transport floor through a soak: the peer process, the ping-pong alone on the machine
/// before the stack starts, then on a thread beside the stack until [`Floor::finish`].
pub struct Floor {
    peer: Kill,
    idle: LatencyStats,
    stop: Arc<AtomicBool>,
    beside: std::thread::JoinHandle<anyhow::Result<(LatencyStats, u64)>>,
}

/// The peer process, stopped (SIGTERM, reaped) when dropped.
struct Kill(std::process::Child);

impl Drop for Kill {
    fn drop(&mut self) {
        mtanet_ipc::child::terminate(&self.0);
        let _ = self.0.wait();
    }
}

/// The ping-pong's priorities: the pinging side the simulator's, the peer the predictor's.
#[derive(Debug, Clone, Copy, Default)]
pub struct Priorities {
    pub simulator: Option<i32>,
    pub predictor: Option<i32>,
}

impl Floor {
    /// Starts the peer (its log in `out`), measures `alone`, then keeps measuring beside
    /// whatever runs next.
    pub fn start(
        ns: &str,
        out: &std::path::Path,
        alone: Duration,
        prio: Priorities,
    ) -> anyhow::Result<Floor> {
        let peer = std::process::Command::new(mtanet_launch::stack::bin_dir().join("mta"))
            .args(["pingpong-peer", "--namespace", ns])
            .args(prio.predictor.map(|p| format!("--priority={p}")))
            .stderr(std::fs::File::create(out.join("pingpong-peer.log"))?)
            .spawn()
            .context("starting the ping-pong peer")?;
        let peer = Kill(peer);
        eprintln!(
            "[soak] raw iceoryx2 ping-pong alone for {:.0} s",
            alone.as_secs_f64()
        );
        let period = Duration::from_secs_f64(mtanet_ipc::CONTROL_PERIOD_S);
        // On a thread of its own: it takes the simulator's real-time class, which the processes
        // started from the calling thread would otherwise inherit.
        let idle = std::thread::scope(|s| {
            s.spawn(|| {
                let never = AtomicBool::new(false);
                measure(ns, period, alone, &never, prio.simulator)
            })
            .join()
            .map_err(|_| anyhow::anyhow!("the ping-pong thread panicked"))
        })??
        .0;
        let stop = Arc::new(AtomicBool::new(false));
        let beside = {
            let (ns, stop) = (ns.to_string(), Arc::clone(&stop));
            let day = Duration::from_secs(86_400);
            std::thread::spawn(move || measure(&ns, period, day, &stop, prio.simulator))
        };
        Ok(Floor {
            peer,
            idle,
            stop,
            beside,
        })
    }

    /// Stops measuring and the peer: the floor alone, the floor beside the stack, and the round
    /// trips lost beside it.
    pub fn finish(self) -> anyhow::Result<(LatencyStats, LatencyStats, u64)> {
        self.stop.store(true, Ordering::Relaxed);
        let (beside, lost) = self
            .beside
            .join()
            .map_err(|_| anyhow::anyhow!("the ping-pong thread panicked"))??;
        drop(self.peer);
        Ok((self.idle, beside, lost))
    }
}
