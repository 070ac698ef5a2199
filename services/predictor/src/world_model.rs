//! The predictor's copy of MTA-PredNet: built from the checkpoint bytes the trainer publishes,
//! stepped once per observation, and judged against the copy-last-frame baseline so the policy
//! only trusts it once it predicts better than "nothing moves".

use mtanet_ipc::{IMAGE_HEIGHT, IMAGE_WIDTH, Observation};
use mtanet_models::checkpoint::{self, CheckpointError};
use mtanet_models::{MtaPredNet, State};
use tch::{Tensor, nn::VarStore};

/// Exponential moving average.
#[derive(Debug, Clone, Copy, Default)]
pub struct Ema {
    value: Option<f64>,
}

impl Ema {
    const ALPHA: f64 = 0.02; // ~50-step memory: one second of driving

    pub fn push(&mut self, x: f64) {
        self.value = Some(match self.value {
            Some(v) => v + Self::ALPHA * (x - v),
            None => x,
        });
    }

    pub fn get(&self) -> Option<f64> {
        self.value
    }
}

pub struct WorldModel {
    vs: VarStore,
    model: MtaPredNet,
    state: State,
    last_frame: Option<Tensor>,
    /// Version of the weights (from the weights topic header).
    pub version: u64,
    /// Next-frame MSE of the model, and of copying the last frame, over recent steps.
    pub model_mse: Ema,
    pub copy_mse: Ema,
    /// Steps observed since the model was (re)built.
    pub steps: u64,
    /// The next prediction starts from an empty state and is not a fair sample of the model.
    fresh: bool,
}

/// An observation's image as `[1, 1, H, W]`.
pub fn frame_tensor(obs: &Observation) -> Tensor {
    Tensor::from_slice(&obs.image).view([1, 1, IMAGE_HEIGHT as i64, IMAGE_WIDTH as i64])
}

impl WorldModel {
    /// Decodes and checks a checkpoint; nothing of a bad one is used.
    pub fn from_bytes(bytes: &[u8], version: u64) -> Result<Self, CheckpointError> {
        let (vs, model) = checkpoint::from_bytes(bytes)?.build()?;
        let state = model.zero_state(1);
        Ok(Self {
            vs,
            model,
            state,
            last_frame: None,
            version,
            model_mse: Ema::default(),
            copy_mse: Ema::default(),
            steps: 0,
            fresh: true,
        })
    }

    /// New weights for the same network: copied in place, the recurrent state and statistics
    /// carry on. A different network (config changed) is rebuilt from scratch.
    pub fn update(&mut self, bytes: &[u8], version: u64) -> Result<(), CheckpointError> {
        let ck = checkpoint::from_bytes(bytes)?;
        if ck.config == *self.model.config() {
            ck.apply(&mut self.vs, &ck.config)?;
            self.version = version;
            Ok(())
        } else {
            *self = Self::from_bytes(bytes, version)?;
            Ok(())
        }
    }

    pub fn model(&self) -> &MtaPredNet {
        &self.model
    }

    /// The state after the latest observation.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// One step with the observed frame and the wheel velocities that led to it; returns the
    /// model's squared error of this frame's prediction (made before seeing it).
    pub fn observe(&mut self, obs: &Observation) -> Result<f64, mtanet_models::ModelError> {
        let _guard = tch::no_grad_guard();
        let frame = frame_tensor(obs);
        let action = Tensor::from_slice(&obs.wheel_velocity).view([1, 2]);
        let (state, out) = self.model.f_step(&self.state, &frame, &action)?;
        self.state = state;
        let mse = (&out.prediction - &frame)
            .square()
            .mean(tch::Kind::Float)
            .double_value(&[]);
        // t = 0 of a fresh state predicts from nothing: not a fair sample of the model.
        if !self.fresh {
            self.model_mse.push(mse);
        }
        self.fresh = false;
        if let Some(last) = &self.last_frame {
            self.copy_mse.push(
                (last - &frame)
                    .square()
                    .mean(tch::Kind::Float)
                    .double_value(&[]),
            );
        }
        self.last_frame = Some(frame);
        self.steps += 1;
        Ok(mse)
    }

    /// A new episode (the car was put back): forget the recurrent state and the last frame.
    pub fn reset_state(&mut self) {
        self.state = self.model.zero_state(1);
        self.last_frame = None;
        self.fresh = true;
    }

    /// True once the model has seen `min_steps` frames and predicts them better than
    /// `ratio` x the copy-last-frame error.
    pub fn trusted(&self, ratio: f64, min_steps: u64) -> bool {
        match (self.model_mse.get(), self.copy_mse.get()) {
            (Some(m), Some(c)) => self.steps >= min_steps && m <= ratio * c,
            _ => false,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use mtanet_models::{ModelConfig, TrainConfig, Trainer};

    /// A tiny untrained network's checkpoint (also used by the policy's tests).
    pub(crate) fn small_checkpoint(seed: u64) -> Vec<u8> {
        let cfg = ModelConfig {
            channels: vec![4, 4, 4],
            a_channels: vec![1, 4, 4],
            ..Default::default()
        };
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

    fn obs(v: f32) -> Observation {
        let mut o: Observation = bytemuck::Zeroable::zeroed();
        o.image = [v; mtanet_ipc::IMAGE_PIXELS];
        o.wheel_velocity = [8.0, 8.0];
        o
    }

    #[test]
    fn steps_judges_and_updates_in_place() {
        let mut w = WorldModel::from_bytes(&small_checkpoint(1), 1).unwrap();
        assert!(!w.trusted(10.0, 1), "no statistics yet");
        for i in 0..5 {
            let mse = w.observe(&obs(0.2 + 0.1 * i as f32)).unwrap();
            assert!(mse.is_finite());
        }
        assert!(w.model_mse.get().is_some() && w.copy_mse.get().is_some());
        assert_eq!(w.steps, 5);
        w.update(&small_checkpoint(2), 2).unwrap();
        assert_eq!(
            (w.version, w.steps),
            (2, 5),
            "same network: weights swapped, state kept"
        );
        let mut bad = small_checkpoint(3);
        bad.truncate(bad.len() / 2);
        assert!(w.update(&bad, 3).is_err());
        assert_eq!(
            w.version, 2,
            "a damaged checkpoint leaves the model as it was"
        );
    }

    #[test]
    fn planning_picks_a_candidate_deterministically() {
        use crate::active_inference::{ActiveInferenceConfig, candidates, choose};
        let mut w = WorldModel::from_bytes(&small_checkpoint(1), 1).unwrap();
        w.observe(&obs(0.5)).unwrap();
        let cfg = ActiveInferenceConfig::default();
        let cands = candidates(&cfg);
        let preferred = Tensor::full([1, 1, 8, 12], 0.8, (tch::Kind::Float, tch::Device::Cpu));
        let (a, cost_a) = choose(&w, &cands, &preferred, [8.0, 8.0], &cfg).unwrap();
        let (b, cost_b) = choose(&w, &cands, &preferred, [8.0, 8.0], &cfg).unwrap();
        assert!(cands.contains(&a) && a == b && cost_a == cost_b && cost_a.is_finite());
        // A strong smoothness prior makes keeping the previous command win.
        let sticky = ActiveInferenceConfig {
            smoothness: 100.0,
            ..cfg.clone()
        };
        let (c, _) = choose(&w, &cands, &preferred, [8.0, 8.0], &sticky).unwrap();
        assert_eq!(c, [8.0, 8.0]);
    }

    #[test]
    fn a_reset_forgets_the_past_episode() {
        let ckpt = small_checkpoint(1);
        let run = |reset: bool| {
            let mut w = WorldModel::from_bytes(&ckpt, 1).unwrap();
            for i in 0..5 {
                w.observe(&obs(0.1 * i as f32)).unwrap();
            }
            let ema = w.model_mse.get();
            if reset {
                w.reset_state();
            }
            (w.observe(&obs(0.7)).unwrap(), ema, w.model_mse.get())
        };
        let first = WorldModel::from_bytes(&ckpt, 1)
            .unwrap()
            .observe(&obs(0.7))
            .unwrap();
        let (kept, _, _) = run(false);
        assert_ne!(
            kept, first,
            "the past shapes the prediction without a reset"
        );
        let (after_reset, ema_before, ema_after) = run(true);
        assert_eq!(
            after_reset, first,
            "same prediction as a model that never ran"
        );
        assert_eq!(ema_after, ema_before, "a blind first guess is not scored");
    }
}
