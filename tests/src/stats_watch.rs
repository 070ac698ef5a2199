//! What the processes of a namespace say about themselves on the stats topic (one
//! [`ProcessStats`] a second each), heard from a test: the event a test waits for instead of a
//! fixed sleep.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use mtanet_ipc::node::{IpcConfig, create_observer_node};
use mtanet_ipc::ports::Receiver;
use mtanet_ipc::{ProcessStats, names, stats};

pub struct StatsWatch {
    rx: Receiver<ProcessStats>,
    /// Declared after the receiver: the port goes before its node.
    _node: Node<ipc::Service>,
}

impl StatsWatch {
    /// An observer node in `ns` (it cleans no dead node of the namespace) listening to stats.
    pub fn open(ns: &str) -> Self {
        let cfg = IpcConfig {
            namespace: ns.into(),
        };
        let node = create_observer_node(&cfg, &format!("test-stats-{}", std::process::id()))
            .expect("an observer node");
        let rx = Receiver::open(&node, names::STATS, stats::SHAPE).expect("the stats topic");
        Self { rx, _node: node }
    }

    /// Waits until a message from the process of `role` ("simulator", "predictor", "trainer")
    /// satisfies `until`, and returns it; panics after `timeout` with the last one heard.
    pub fn wait_for(
        &self,
        role: &str,
        timeout: Duration,
        until: impl Fn(&ProcessStats) -> bool,
    ) -> ProcessStats {
        let deadline = Instant::now() + timeout;
        let mut last = None;
        loop {
            let mut hit = None;
            self.rx
                .for_each(|s| {
                    if s.role() == role {
                        last = Some(*s);
                        if hit.is_none() && until(s) {
                            hit = Some(*s);
                        }
                    }
                })
                .expect("reading the stats topic");
            if let Some(s) = hit {
                return s;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            assert!(
                !left.is_zero(),
                "{role} did not report what was awaited within {timeout:?}; last heard: {last:?}"
            );
            self.rx.wait(left).expect("waiting on the stats topic");
        }
    }
}
