//! Weights from the trainer into the policy: each checkpoint is copied out of shared memory and
//! decoded on the loader's thread, then installed between two steps. Weights that carry an
//! install step (lockstep learning, see the trainer's `schedule.rs`) wait for the observation of
//! that step, and that observation waits for them: the same weights drive from the same step
//! on any machine. Others are installed as soon as they are decoded.

use std::time::Instant;

use crate::loader::{Decoded, Loader};
use crate::policy::{Install, Policy};
use crate::service::{Ports, Summary};

pub struct Intake {
    loader: Loader,
    /// Submitted to the loader, not back yet: (version, install step).
    in_flight: Vec<(u64, u64)>,
    /// Decoded, waiting for their install step.
    waiting: Vec<Decoded>,
    /// The last version received with an install step: the next one must follow it.
    last_scheduled: Option<u64>,
}

impl Intake {
    pub fn new(loader_nice: i32) -> anyhow::Result<Self> {
        Ok(Self {
            loader: Loader::spawn(loader_nice)?,
            in_flight: Vec::new(),
            waiting: Vec::new(),
            last_scheduled: None,
        })
    }

    /// Hands the pending checkpoints, oldest first, to the loader (decoding them here would stall
    /// the control loop for several ms): every lockstep version, since each drives from its own
    /// step (one overwritten before it was taken is counted and logged), and in real time the
    /// newest.
    pub fn receive(&mut self, ports: &Ports, summary: &mut Summary) -> anyhow::Result<()> {
        let loader = &self.loader;
        let got = ports.weights.pending(|h, bytes| {
            loader
                .submit(bytes, h.version, h.probe, h.install_step)
                .map(|()| (h.version, h.install_step))
        })?;
        for r in got {
            let (version, install_step) = r?;
            if install_step != 0 {
                follows(&mut self.last_scheduled, version, summary);
            }
            self.in_flight.push((version, install_step));
            summary.weights_received += 1;
        }
        Ok(())
    }

    /// Installs what is due: before answering observation `step`, every checkpoint whose
    /// install step has come (waiting for the loader if one is still being decoded); between
    /// steps (`None`), those without an install step.
    pub fn install_due(
        &mut self,
        step: Option<u64>,
        policy: &mut Policy,
        summary: &mut Summary,
    ) -> anyhow::Result<()> {
        let due = |install: u64| install == 0 || step.is_some_and(|s| install <= s);
        while let Some(d) = self.loader.try_take() {
            self.took(d);
        }
        while self.in_flight.iter().any(|&(_, at)| at != 0 && due(at)) {
            let d = self.loader.take()?;
            self.took(d);
        }
        let (now, later): (Vec<_>, Vec<_>) = std::mem::take(&mut self.waiting)
            .into_iter()
            .partition(|(_, at, _)| due(*at));
        self.waiting = later;
        for (version, _, prepared) in now {
            install(version, prepared, policy, summary);
        }
        Ok(())
    }

    fn took(&mut self, d: Decoded) {
        self.in_flight.retain(|&(v, _)| v != d.0);
        self.waiting.push(d);
    }
}

/// Counts the lockstep versions between the last one taken and `version` that never arrived.
fn follows(last: &mut Option<u64>, version: u64, summary: &mut Summary) {
    if let Some(l) = *last
        && version > l + 1
    {
        summary.weights_lost += version - l - 1;
        tracing::error!(
            "lockstep weights {}..={} were overwritten before this predictor took them: \
             this run will not replay bit for bit",
            l + 1,
            version - 1
        );
    }
    *last = Some(version);
}

/// A copy in place between two steps (or a refusal that keeps the model in hand).
fn install(
    version: u64,
    prepared: anyhow::Result<crate::loader::Prepared>,
    policy: &mut Policy,
    summary: &mut Summary,
) {
    let t0 = Instant::now();
    let outcome = prepared.and_then(|p| {
        let (decode_ms, probe) = (p.decode_ms, p.probe);
        policy.install(p).map(|i| (i, decode_ms, probe))
    });
    match outcome {
        Ok((Install::HeldBack, _, probe)) => {
            summary.weights_held_back += 1;
            tracing::info!(
                version,
                ?probe,
                "weights held back: their probe failed while the model in hand drives"
            );
        }
        Ok((Install::Installed, decode_ms, _)) => {
            summary.weights_installed += 1;
            summary.model_version = version;
            let install_ms = t0.elapsed().as_secs_f64() * 1e3;
            let probe = policy.model().and_then(|m| m.probe);
            tracing::info!(version, ?probe, decode_ms, install_ms, "weights loaded");
        }
        Err(e) => {
            // A damaged or mismatched checkpoint must not stop the car: keep what we had.
            summary.weights_rejected += 1;
            tracing::error!(
                version,
                "rejected weights, keeping the previous model: {e:#}"
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lockstep_version_that_never_arrived_is_counted() {
        let (mut last, mut summary) = (None, Summary::default());
        for v in [1, 2, 3] {
            follows(&mut last, v, &mut summary);
        }
        assert_eq!(summary.weights_lost, 0);
        follows(&mut last, 6, &mut summary);
        assert_eq!(summary.weights_lost, 2, "versions 4 and 5");
        // A restarted trainer counts from its checkpoint again: not a loss.
        follows(&mut last, 2, &mut summary);
        follows(&mut last, 3, &mut summary);
        assert_eq!(summary.weights_lost, 2);
    }
}
