//! The predictor's decisions: the control agent ([`mtanet_control::Agent`]) with the newest
//! weights as its world model, planning on a thread of its own. Weights are checked whole and
//! against the wire contract before they replace anything; a bad blob leaves the car as it was.

use mtanet_control::{
    Agent, AgentStats, Blind, Decision, FrameShape, NoPlans, Planner, PlanningSummary, Threaded,
    Tick,
};
use mtanet_ipc::sched;
use mtanet_ipc::{CONTROL_PERIOD_S, Observation};
use mtanet_models::live::{Imagined, LiveModel};

use crate::config::PredictorConfig;
use crate::loader::{Prepared, prepare};

pub struct Policy {
    agent: Agent,
    cfg: PredictorConfig,
    model: Option<LiveModel>,
    planner: Option<Threaded<Imagined>>,
}

impl Policy {
    /// The model the agent plans through, once weights are installed (read-only: installing
    /// goes through [`Policy::install`]).
    pub fn model(&self) -> Option<&LiveModel> {
        self.model.as_ref()
    }

    pub fn new(cfg: &PredictorConfig) -> Self {
        Self {
            agent: Agent::new(
                &cfg.active_inference,
                &cfg.reactive,
                &cfg.exploration,
                FrameShape::CAR,
                CONTROL_PERIOD_S as f32,
            ),
            cfg: cfg.clone(),
            model: None,
            planner: None,
        }
    }

    pub fn stats(&self) -> AgentStats {
        self.agent.stats
    }

    /// What the plans taken up so far could afford.
    pub fn planning(&self) -> PlanningSummary {
        self.agent.planning.summary()
    }

    /// Decides the command for this observation.
    pub fn act(&mut self, obs: &Observation) -> anyhow::Result<Decision> {
        let tick = Tick {
            step: obs.step,
            episode: u32::from(obs.episode),
            frame: &obs.image,
            line: obs.line_sensors.map(|v| v != 0),
            applied: obs.command,
            measured: obs.wheel_velocity,
            lockstep: obs.lockstep != 0,
        };
        match (self.model.as_mut(), self.planner.as_mut()) {
            (Some(model), Some(planner)) => self.agent.tick(&tick, model, planner),
            _ => self.agent.tick(&tick, &mut Blind, &mut NoPlans),
        }
    }

    /// The step's model work the command did not wait for (see `Agent::after`); run it once
    /// the command is out.
    pub fn after_command(&mut self) -> anyhow::Result<()> {
        match (self.model.as_mut(), self.planner.as_mut()) {
            (Some(model), Some(planner)) => self.agent.after(model, planner),
            _ => self.agent.after(&mut Blind, &mut NoPlans),
        }
    }

    /// Weights from a checkpoint file (its recorded probe, if any, comes along).
    pub fn load_file(&mut self, path: &std::path::Path) -> anyhow::Result<()> {
        use anyhow::Context;
        let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        self.load_weights(&bytes, 0, f32::NAN)
            .map(drop)
            .with_context(|| format!("the checkpoint {}", path.display()))
    }

    /// New weights from the trainer (`probe`: its counterfactual probe, NaN if none), decoded
    /// here. Returns the error if they were refused; the previous model then keeps driving.
    pub fn load_weights(
        &mut self,
        bytes: &[u8],
        version: u64,
        probe: f32,
    ) -> anyhow::Result<Install> {
        self.install(prepare(bytes, version, probe)?)
    }

    /// Takes in weights [`prepare`]d on the loader's thread: for the same network a copy in place (well under
    /// a millisecond, the recurrent state carries on), otherwise a new model and planner. Weights
    /// whose probe failed are held back while the model in hand drives ([`Agent::admits`]).
    pub fn install(&mut self, p: Prepared) -> anyhow::Result<Install> {
        if self.model.is_some() && !self.agent.admits(p.probe) {
            return Ok(Install::HeldBack);
        }
        let Prepared {
            model: mut fresh,
            mut imagined,
            probe,
            ..
        } = p;
        let in_place = self.planner.is_some()
            && self
                .model
                .as_mut()
                .is_some_and(|m| m.take_weights(&mut fresh));
        match self.planner.as_ref() {
            Some(planner) if in_place => {
                planner.update(move |im| {
                    if !im.take_weights(&mut imagined) {
                        tracing::error!("the planner could not take the new weights");
                    }
                })?;
            }
            _ => {
                // First weights, or another network: a new model and planner.
                let planner = Planner::new(&self.cfg.active_inference.planner)?;
                let cfg = &self.cfg;
                let (threads, prio, nice) =
                    (cfg.torch_threads, cfg.planner_priority, cfg.helpers_nice);
                self.planner = Some(Threaded::spawn(planner, imagined, move || {
                    tch::set_num_threads(threads);
                    planner_priority(prio, nice);
                })?);
                self.model = Some(fresh);
            }
        }
        if let Some(m) = self.model.as_mut() {
            m.probe = probe;
        }
        Ok(Install::Installed)
    }
}

/// What became of weights offered to [`Policy::install`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Install {
    Installed,
    /// Their probe failed while the model in hand drives: that one goes on driving.
    HeldBack,
}

/// The planner's thread: SCHED_FIFO at `priority` when it was made by a real-time thread (the
/// control loop), kept below that thread's priority; otherwise, or if refused, the normal
/// scheduler at `nice` ([`background_priority`]).
pub fn planner_priority(priority: i32, nice: i32) {
    let inherited = sched::thread_fifo_priority();
    if let (true, Some(loop_priority)) = (priority > 0, inherited) {
        // Lowering a real-time priority needs no privilege.
        let p = priority.min(loop_priority - 1).max(1);
        if sched::set_thread_fifo(p) {
            tracing::info!(priority = p, "planner thread: SCHED_FIFO");
            return;
        }
    }
    if priority > 0 {
        tracing::info!(
            nice,
            "the control loop is not real-time: nor is the planner"
        );
    }
    background_priority(nice, "planner");
}

/// For a thread doing long work inside a real-time predictor (planner, weights loader): back to
/// SCHED_OTHER (it inherited SCHED_FIFO and would hold a core from the simulator and the
/// trainer), at `nice`.
pub fn background_priority(nice: i32, what: &str) {
    if !sched::set_thread_normal(nice) {
        tracing::warn!(nice, "could not lower the {what} thread's priority");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mtanet_control::Driver;
    use mtanet_models::{ModelConfig, TrainConfig, Trainer};

    pub(crate) fn small_checkpoint(seed: u64, cfg: ModelConfig) -> Vec<u8> {
        Trainer::new(
            &cfg,
            &TrainConfig {
                seed,
                ..Default::default()
            },
        )
        .checkpoint_bytes(None)
        .unwrap()
    }

    fn small() -> ModelConfig {
        ModelConfig {
            channels: vec![4, 4, 4],
            a_channels: vec![1, 4, 4],
            frame_skip: 2,
            ..Default::default()
        }
    }

    fn obs(line: [u8; 3], step: u64) -> Observation {
        let mut o: Observation = bytemuck::Zeroable::zeroed();
        o.line_sensors = line;
        o.step = step;
        o.lockstep = 1;
        o
    }

    /// The world model is conditioned on the command applied (what a plan chooses), never on the
    /// measured wheel speed.
    #[test]
    fn the_model_steps_with_the_applied_command_not_the_measured_speed() {
        let ck = small_checkpoint(3, small());
        let fingerprint = |vary: &dyn Fn(&mut Observation, u64)| -> f64 {
            let mut p = Policy::new(&PredictorConfig::default());
            p.load_weights(&ck, 1, f32::NAN).unwrap();
            for s in 0..8 {
                let mut o = obs([0, 1, 0], s);
                o.image = [0.3 + 0.05 * s as f32; 96];
                o.command = [6.0, 7.0];
                o.wheel_velocity = [5.0, 5.5];
                vary(&mut o, s);
                p.act(&o).unwrap();
                p.after_command().unwrap();
            }
            let m = p.model.as_ref().unwrap();
            m.state().layers[0]
                .r
                .abs()
                .sum(tch::Kind::Double)
                .double_value(&[])
        };
        let base = fingerprint(&|_, _| {});
        let other_speed = fingerprint(&|o, s| o.wheel_velocity = [s as f32, 9.0]);
        let other_command = fingerprint(&|o, s| o.command = [2.0 + s as f32, 11.0]);
        assert_eq!(base, other_speed, "the measured speed must not matter");
        assert_ne!(base, other_command, "the applied command must");
    }

    #[test]
    fn without_weights_the_reactive_rule_drives_and_bad_weights_change_nothing() {
        let mut p = Policy::new(&PredictorConfig::default());
        let d = p.act(&obs([0, 1, 0], 0)).unwrap();
        assert!(matches!(d.driver, Driver::Reactive | Driver::Exploration));
        let mut bad = small_checkpoint(1, small());
        bad.truncate(bad.len() / 2);
        assert!(p.load_weights(&bad, 1, f32::NAN).is_err());
        assert!(p.model.is_none());
        let wrong = small_checkpoint(
            1,
            ModelConfig {
                action_dim: 3,
                ..small()
            },
        );
        let e = p.load_weights(&wrong, 2, f32::NAN).unwrap_err().to_string();
        assert!(e.contains("action values"), "{e}");
        assert!(
            p.model.is_none(),
            "a checkpoint off the wire contract is refused"
        );
        p.load_weights(&small_checkpoint(1, small()), 3, 0.5)
            .unwrap();
        let m = p.model.as_ref().unwrap();
        assert_eq!((m.version, m.probe), (3, Some(0.5)));
        // The model steps every frame_skip (2) observations.
        for s in 1..=6 {
            p.act(&obs([0, 1, 0], s)).unwrap();
            p.after_command().unwrap();
        }
        assert_eq!(p.model.as_ref().unwrap().steps, 3);
        p.load_weights(&small_checkpoint(2, small()), 4, f32::NAN)
            .unwrap();
        let m = p.model.as_ref().unwrap();
        assert_eq!(
            (m.version, m.steps, m.probe),
            (4, 3, None),
            "same network: updated in place"
        );
        // Decoded on another thread (the weights loader), taken in by copying.
        let bytes = small_checkpoint(3, small());
        let theirs = bytes.clone();
        let prepared = std::thread::spawn(move || prepare(&theirs, 5, 0.5))
            .join()
            .unwrap()
            .unwrap();
        p.install(prepared).unwrap();
        let m = p.model.as_ref().unwrap();
        assert_eq!(
            (m.version, m.steps, m.probe),
            (5, 3, Some(0.5)),
            "in place, the state carried on"
        );
        let direct = LiveModel::from_bytes(&bytes, 5).unwrap();
        let w = |m: &LiveModel| m.model().layers[0].xhat.ws.shallow_clone();
        assert!(
            w(m).equal(&w(&direct)),
            "the installed weights are the checkpoint's"
        );
        let earlier = LiveModel::from_bytes(&small_checkpoint(2, small()), 4).unwrap();
        assert!(!w(m).equal(&w(&earlier)), "and not the previous ones");
    }
}
