//! Training: Adam, truncated BPTT, PredNet's weighted error loss, gradient clipping and a guard
//! that refuses non-finite updates.

use crate::adam::Adam;
use crate::checkpoint::{self, CheckpointError, Meta};
use crate::config::{ConfigError, ModelConfig};
use crate::data::Dataset;
use crate::eval::{EvalMetrics, evaluate};
use crate::model::{ModelError, MtaPredNet};
use crate::state::State;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::ops::ControlFlow;
use tch::{Device, Kind, Tensor, nn};

/// Optimiser and schedule settings (serde, the `[train]` table of a run's TOML).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Adam learning rate.
    pub lr: f64,
    /// Maximum global L2 norm of the gradient; larger gradients are scaled down.
    pub clip_norm: f64,
    /// Sequences per update.
    pub batch_size: i64,
    /// Truncated-BPTT window: steps per update; the state is carried (detached) across windows.
    pub bptt: i64,
    /// Seed for initialisation, shuffling and the held-out split.
    pub seed: u64,
    /// Fraction of sequences held out for evaluation when no separate eval set is given.
    pub eval_fraction: f64,
    /// The last this many steps of each window are imagined: the model takes its own
    /// prediction as the input there (scored against the real frames), as a planner's rollout
    /// does. 0: every step observes its frame (one-step prediction only).
    pub imagined_steps: i64,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            lr: 4e-3,
            clip_norm: 1.0,
            batch_size: 16,
            bptt: 20,
            seed: 0,
            eval_fraction: 0.1,
            imagined_steps: 0,
        }
    }
}

/// Why an update was refused.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// The loss was NaN or infinite: no gradient was computed and no weight changed.
    #[error("update {step} refused: non-finite loss {loss}")]
    NonFiniteLoss { step: u64, loss: f64 },
    /// The gradient norm was NaN or infinite: gradients were dropped and no weight changed.
    #[error("update {step} refused: non-finite gradient norm {norm}")]
    NonFiniteGradient { step: u64, norm: f64 },
    /// Every time step of the window has loss weight 0 (e.g. a 1-step window at t = 0).
    #[error("window of {steps} steps starting at t = {t0} has no loss weight")]
    NoLossWeight { t0: usize, steps: i64 },
    /// The batch does not fit the network.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The model or training configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
}

/// What one accepted update did.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct UpdateStats {
    /// Updates accepted so far, this one included.
    pub step: u64,
    /// The weighted loss before the update.
    pub loss: f64,
    /// Global gradient L2 norm before clipping.
    pub grad_norm: f64,
    /// Whether clipping scaled the gradient down.
    pub clipped: bool,
}

/// Owns the weights, the model built on them and the optimiser.
pub struct Trainer {
    pub vs: nn::VarStore,
    pub model: MtaPredNet,
    /// Adam, with moments that go into the checkpoint's optimiser file.
    pub opt: Adam,
    pub cfg: ModelConfig,
    pub train_cfg: TrainConfig,
    /// The latest counterfactual probe of these weights' run: (step, rank correlation). Saved
    /// with checkpoints and restored on resume.
    pub probe: Option<(u64, f64)>,
    step: u64,
    refused: u64,
}

impl Trainer {
    /// Panics on an invalid configuration; see [`Self::f_new`].
    pub fn new(cfg: &ModelConfig, train_cfg: &TrainConfig) -> Self {
        Self::f_new(cfg, train_cfg).unwrap_or_else(|e| panic!("Trainer::new: {e}"))
    }

    /// Seeds libtorch with `train_cfg.seed`, builds the model on the CPU and Adam over it.
    pub fn f_new(cfg: &ModelConfig, train_cfg: &TrainConfig) -> Result<Self, TrainError> {
        // libtorch has one global generator: two trainers seeded and initialised at the same
        // time on two threads would draw from each other's sequence.
        static INIT: std::sync::Mutex<()> = std::sync::Mutex::new(());
        let _one_at_a_time = INIT.lock().unwrap_or_else(|p| p.into_inner());
        tch::manual_seed(train_cfg.seed as i64);
        let vs = nn::VarStore::new(Device::Cpu);
        let model = MtaPredNet::f_new(&vs.root(), cfg)?;
        let opt = Adam::new(&vs, train_cfg.lr);
        Ok(Self {
            vs,
            model,
            opt,
            cfg: cfg.clone(),
            train_cfg: train_cfg.clone(),
            probe: None,
            step: 0,
            refused: 0,
        })
    }

    /// Accepted updates so far.
    pub fn step(&self) -> u64 {
        self.step
    }

    /// Updates refused by the non-finite guard so far.
    pub fn refused(&self) -> u64 {
        self.refused
    }

    /// Sets the accepted-update counter (when resuming from a checkpoint's metadata).
    pub fn set_step(&mut self, step: u64) {
        self.step = step;
    }

    /// One update on a batch of windows that start at t = 0 from the zero state:
    /// `images` `[B, T, H, W]` (or `[B, T, 1, H, W]`), `actions` `[B, T, A]`.
    pub fn update(&mut self, images: &Tensor, actions: &Tensor) -> Result<UpdateStats, TrainError> {
        let state = self
            .model
            .zero_state(images.size().first().copied().unwrap_or(0));
        self.update_from(&state, images, actions, 0)
            .map(|(stats, _)| stats)
    }

    /// One truncated-BPTT update: runs the window from `state` (whose history is cut), with `t0`
    /// the window's first global time step (for the time weights), and returns the detached
    /// final state for the next window.
    pub fn update_from(
        &mut self,
        state: &State,
        images: &Tensor,
        actions: &Tensor,
        t0: usize,
    ) -> Result<(UpdateStats, State), TrainError> {
        let steps = images.size().get(1).copied().unwrap_or(0);
        let observed = (steps - self.train_cfg.imagined_steps.max(0)).max(1);
        let out =
            self.model
                .f_forward_sequence_imagining(&state.detach(), images, actions, observed)?;
        let steps = out.layer_errors.size()[1];
        let loss = weighted_loss(&self.cfg, &out.layer_errors, t0)
            .ok_or(TrainError::NoLossWeight { t0, steps })?;
        let loss_value = loss.double_value(&[]);
        if !loss_value.is_finite() {
            self.refused += 1;
            tracing::warn!(
                step = self.step,
                loss = loss_value,
                "refusing update: non-finite loss"
            );
            return Err(TrainError::NonFiniteLoss {
                step: self.step,
                loss: loss_value,
            });
        }
        self.opt.zero_grad(&self.vs);
        loss.backward();
        let grad_norm = self.grad_norm();
        if !grad_norm.is_finite() {
            self.opt.zero_grad(&self.vs);
            self.refused += 1;
            tracing::warn!(
                step = self.step,
                grad_norm,
                "refusing update: non-finite gradient"
            );
            return Err(TrainError::NonFiniteGradient {
                step: self.step,
                norm: grad_norm,
            });
        }
        let clipped = grad_norm > self.train_cfg.clip_norm;
        if clipped {
            let scale = self.train_cfg.clip_norm / (grad_norm + 1e-6);
            tch::no_grad(|| {
                for v in self.vs.trainable_variables() {
                    let mut g = v.grad();
                    if g.defined() {
                        let _ = g.g_mul_scalar_(scale);
                    }
                }
            });
        }
        self.step += 1;
        self.opt.step(&self.vs, self.step);
        let stats = UpdateStats {
            step: self.step,
            loss: loss_value,
            grad_norm,
            clipped,
        };
        Ok((stats, out.state.detach()))
    }

    /// Held-out metrics of the current weights (see [`crate::eval::evaluate`]).
    pub fn evaluate(&self, data: &Dataset) -> Result<EvalMetrics, ModelError> {
        evaluate(&self.model, data, 64, Some(self.train_cfg.seed))
    }

    /// The checkpoint of the current weights, as bytes (what the trainer ships to the predictor).
    pub fn checkpoint_bytes(&self, loss: Option<f64>) -> Result<Vec<u8>, CheckpointError> {
        checkpoint::to_bytes(
            &self.vs,
            &self.cfg,
            &Meta::new(self.step, loss).with_probe(self.probe),
        )
    }

    /// Saves the checkpoint atomically to `path`, then Adam's moments next to it
    /// ([`optimizer_path`]), so that [`Trainer::resume`] continues where this left off.
    pub fn save_checkpoint(
        &self,
        path: &std::path::Path,
        loss: Option<f64>,
    ) -> Result<(), CheckpointError> {
        self.save_checkpoint_bytes(path, &self.checkpoint_bytes(loss)?, loss)
    }

    /// [`Trainer::save_checkpoint`] with the checkpoint already serialised by
    /// [`Trainer::checkpoint_bytes`] with the same `loss` (a publication writes the bytes it
    /// sends).
    pub fn save_checkpoint_bytes(
        &self,
        path: &std::path::Path,
        bytes: &[u8],
        loss: Option<f64>,
    ) -> Result<(), CheckpointError> {
        mtanet_summaries::files::write_bytes(path, bytes)?;
        let meta = Meta::new(self.step, loss).with_probe(self.probe);
        let moments = self.opt.to_bytes(&self.cfg, &meta)?;
        Ok(mtanet_summaries::files::write_bytes(
            &optimizer_path(path),
            &moments,
        )?)
    }

    /// Loads weights and the step counter from a checkpoint made with the same configuration
    /// (an error leaves the trainer as it was), and Adam's moments from the file beside it when
    /// it belongs to that same step. Without them (absent, older, damaged) Adam restarts its
    /// statistics, which costs a few noisy updates but no learned weight: a warning, not an error.
    pub fn resume(&mut self, path: &std::path::Path) -> Result<Meta, CheckpointError> {
        let meta = checkpoint::load_into(path, &mut self.vs, &self.cfg)?;
        self.step = meta.step;
        self.probe = meta.probe_step.zip(meta.probe);
        let opt_path = optimizer_path(path);
        let restored = std::fs::read(&opt_path)
            .map_err(|source| CheckpointError::Io {
                path: opt_path.clone(),
                source,
            })
            .and_then(|bytes| {
                let mut opt = Adam::new(&self.vs, self.train_cfg.lr);
                let at = opt.load_bytes(&bytes, &self.cfg)?;
                if at.step != meta.step {
                    return Err(CheckpointError::NotCheckpoint(format!(
                        "moments of step {}, weights of step {}",
                        at.step, meta.step
                    )));
                }
                Ok(opt)
            });
        match restored {
            Ok(opt) => self.opt = opt,
            Err(e) => {
                self.opt = Adam::new(&self.vs, self.train_cfg.lr);
                tracing::warn!(path = %opt_path.display(), "Adam restarts its statistics: {e}");
            }
        }
        Ok(meta)
    }

    fn grad_norm(&self) -> f64 {
        tch::no_grad(|| {
            let sq: Vec<Tensor> = self
                .vs
                .trainable_variables()
                .iter()
                .map(|v| v.grad())
                .filter(|g| g.defined())
                .map(|g| g.square().sum(Kind::Float))
                .collect();
            if sq.is_empty() {
                return 0.0;
            }
            Tensor::stack(&sq, 0)
                .sum(Kind::Float)
                .sqrt()
                .double_value(&[])
        })
    }

    /// One pass over `data`: shuffled batches of `batch_size` sequences, each run through in
    /// `bptt`-step windows carrying the state. A refused update abandons the rest of that batch
    /// (its state may be poisoned) and is reported through `on_update` like the others.
    /// `on_update` returning `Break` ends the epoch right there (for an exact update budget).
    pub fn fit_epoch(
        &mut self,
        data: &Dataset,
        seed: u64,
        mut on_update: impl FnMut(&Result<UpdateStats, TrainError>) -> ControlFlow<()>,
    ) -> Result<(), TrainError> {
        let n = data.len();
        let mut order: Vec<i64> = (0..n).collect();
        order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
        let (t, bptt) = (data.steps(), self.train_cfg.bptt.max(1));
        for batch in order.chunks(self.train_cfg.batch_size.max(1) as usize) {
            let part = data.select(batch);
            let mut state = self.model.zero_state(batch.len() as i64);
            let mut t0 = 0;
            while t0 < t {
                let len = bptt.min(t - t0);
                let (imgs, acts) = (
                    part.images.narrow(1, t0, len),
                    part.actions.narrow(1, t0, len),
                );
                match self.update_from(&state, &imgs, &acts, t0 as usize) {
                    Ok((stats, next)) => {
                        state = next;
                        if on_update(&Ok(stats)).is_break() {
                            return Ok(());
                        }
                    }
                    Err(TrainError::NoLossWeight { .. }) => {
                        // Nothing to learn in this window, but the state still has to advance.
                        let _g = tch::no_grad_guard();
                        state = self
                            .model
                            .f_forward_sequence_from(&state, &imgs, &acts)?
                            .state;
                    }
                    Err(e @ (TrainError::Model(_) | TrainError::Config(_))) => return Err(e),
                    Err(e) => {
                        if on_update(&Err(e)).is_break() {
                            return Ok(());
                        }
                        break;
                    }
                }
                t0 += len;
            }
        }
        Ok(())
    }
}

/// PredNet's loss: sum over t and l of w_t * lambda_l * mean over the batch of the reduced E_l(t),
/// divided by the sum of the w_t. `None` when every w_t in the window is 0.
pub fn weighted_loss(cfg: &ModelConfig, layer_errors: &Tensor, t0: usize) -> Option<Tensor> {
    let t = layer_errors.size()[1] as usize;
    let tw: Vec<f32> = (t0..t0 + t).map(|i| cfg.time_weight(i) as f32).collect();
    let total: f32 = tw.iter().sum();
    if total <= 0.0 {
        return None;
    }
    let lw: Vec<f32> = cfg.layer_loss_weights.iter().map(|&w| w as f32).collect();
    let tw = Tensor::from_slice(&tw).view([1, -1, 1]);
    let lw = Tensor::from_slice(&lw).view([1, 1, -1]);
    let b = layer_errors.size()[0] as f64;
    Some((layer_errors * tw * lw).sum(Kind::Float) / (f64::from(total) * b))
}

/// Where [`Trainer::save_checkpoint`] keeps Adam's moments for `checkpoint`:
/// `latest.safetensors` -> `latest.optimizer.safetensors`.
pub fn optimizer_path(checkpoint: &std::path::Path) -> std::path::PathBuf {
    let stem = checkpoint
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    checkpoint.with_file_name(format!("{stem}.optimizer.safetensors"))
}
