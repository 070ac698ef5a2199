//! MTA-PredNet as a running agent's world model: built from checkpoint bytes, stepped once per
//! model step with the frame seen and the segment's mean command, and judged against the
//! copy-last-frame baseline so the agent trusts it only once it predicts better than "nothing
//! moves". [`Imagined`] is the same network rolling candidate plans out for the planner (a copy
//! of its own, so planning can run on another thread).

use std::time::Instant;

use mtanet_control::{AgentModel, Drive, Health, Imagination, Wheels};
use tch::{Kind, Tensor, nn::VarStore};

use crate::checkpoint::{self, Checkpoint, CheckpointError};
use crate::{ModelConfig, MtaPredNet, State, StepWeights};

/// Exponential moving average.
#[derive(Debug, Clone, Copy, Default)]
pub struct Ema {
    value: Option<f64>,
}

impl Ema {
    const ALPHA: f64 = 0.02; // ~50 model steps of memory

    /// A non-finite sample makes the average infinite (a model that predicted NaN is as bad
    /// as a model can be, and must not be averaged away); the next finite one starts afresh.
    pub fn push(&mut self, x: f64) {
        self.value = Some(match self.value {
            _ if !x.is_finite() => f64::INFINITY,
            Some(v) if v.is_finite() => v + Self::ALPHA * (x - v),
            _ => x,
        });
    }

    pub fn get(&self) -> Option<f64> {
        self.value
    }
}

pub struct LiveModel {
    vs: VarStore,
    model: MtaPredNet,
    /// Derived from the weights once per version, not per step.
    weights: StepWeights,
    state: State,
    last_frame: Option<Tensor>,
    /// Version of the weights (from the weights topic header).
    pub version: u64,
    /// Counterfactual probe of these weights, when their publisher measured it.
    pub probe: Option<f64>,
    /// Next-frame MSE of the model, and of copying the last frame, over recent model steps.
    pub model_mse: Ema,
    pub copy_mse: Ema,
    /// Model steps since the network was (re)built.
    pub steps: u64,
    /// The next prediction starts from an empty state and is not a fair sample of the model.
    fresh: bool,
}

/// Copy-last-frame error below which a step is not scored (the view barely changed).
const MIN_COPY_MSE: f64 = 1e-4;

fn frame_tensor(cfg: &ModelConfig, frame: &[f32]) -> Tensor {
    Tensor::from_slice(frame).view([1, 1, cfg.image_height, cfg.image_width])
}

impl LiveModel {
    /// Decodes and checks a checkpoint; nothing of a bad one is used.
    pub fn from_bytes(bytes: &[u8], version: u64) -> Result<Self, CheckpointError> {
        Self::from_checkpoint(&checkpoint::from_bytes(bytes)?, version)
    }

    /// From a checkpoint decoded once (the weights loader builds the planner's copy from the
    /// same one).
    pub fn from_checkpoint(ck: &Checkpoint, version: u64) -> Result<Self, CheckpointError> {
        let (mut vs, model) = ck.build()?;
        // Inference only: no gradients are kept for these weights.
        vs.freeze();
        let weights = model.inference_weights();
        let state = model.zero_state(1);
        Ok(Self {
            vs,
            model,
            weights,
            state,
            last_frame: None,
            version,
            probe: None,
            model_mse: Ema::default(),
            copy_mse: Ema::default(),
            steps: 0,
            fresh: true,
        })
    }

    /// The weights of `other`, decoded elsewhere (a loader thread), copied in place for the same
    /// network: the recurrent state and statistics carry on. The step weights `other` derived
    /// on its thread are taken, not derived again here: packing them costs milliseconds, and
    /// this runs on the control loop. False (nothing changed) for another network.
    pub fn take_weights(&mut self, other: &mut LiveModel) -> bool {
        if other.config() != self.config() || self.vs.copy(&other.vs).is_err() {
            return false;
        }
        std::mem::swap(&mut self.weights, &mut other.weights);
        self.version = other.version;
        true
    }

    pub fn model(&self) -> &MtaPredNet {
        &self.model
    }

    pub fn config(&self) -> &ModelConfig {
        self.model.config()
    }

    /// The state after the latest observation.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// One model step with `frame` and the mean command that led to it; returns the squared
    /// error of this frame's prediction (made before seeing it).
    pub fn observe_frame(
        &mut self,
        frame: &[f32],
        action: Wheels,
    ) -> Result<f64, crate::ModelError> {
        let _guard = tch::no_grad_guard();
        let frame = frame_tensor(self.model.config(), frame);
        let action = Tensor::from_slice(&action).view([1, 2]);
        let (state, out) = self
            .model
            .f_step_with(&self.weights, &self.state, &frame, &action)?;
        self.state = state;
        let mse = (&out.prediction - &frame)
            .square()
            .mean(Kind::Float)
            .double_value(&[]);
        // Scored against copying the last frame, on steps where the view changed: a still view
        // is trivially predicted by copying, and a few of them would swing the ratio for no
        // reason. t = 0 of a fresh state predicts from nothing and is not scored either.
        if let Some(last) = &self.last_frame {
            let copy = (last - &frame).square().mean(Kind::Float).double_value(&[]);
            if !self.fresh && copy >= MIN_COPY_MSE {
                self.model_mse.push(mse);
                self.copy_mse.push(copy);
            }
        }
        self.fresh = false;
        self.last_frame = Some(frame);
        self.steps += 1;
        Ok(mse)
    }

    /// A new episode: forget the recurrent state and the last frame.
    pub fn reset_state(&mut self) {
        self.state = self.model.zero_state(1);
        self.last_frame = None;
        self.fresh = true;
    }

    /// Recent model error over copy-last error.
    pub fn error_ratio(&self) -> Option<f64> {
        match (self.model_mse.get(), self.copy_mse.get()) {
            (Some(m), Some(c)) if c > 0.0 => Some(m / c),
            _ => None,
        }
    }
}

impl AgentModel for LiveModel {
    type Snapshot = State;

    fn frame_skip(&self) -> Option<usize> {
        Some(self.model.config().frame_skip.max(1) as usize)
    }

    fn observe(&mut self, frame: &[f32], action: Wheels) -> anyhow::Result<()> {
        self.observe_frame(frame, action)?;
        Ok(())
    }

    fn reset(&mut self) {
        self.reset_state();
    }

    fn snapshot(&mut self) -> anyhow::Result<State> {
        // A copy, not a handle: it may go to the planner's thread.
        Ok(self.state.deep_copy())
    }

    fn health(&self) -> Health {
        Health {
            model_over_copy: self.error_ratio(),
            model_steps: self.steps,
            probe: self.probe,
        }
    }
}

/// The network rolling plans out: each segment is one imagined model step under the held
/// command, the prediction taken as the next input. All candidates go in one batch.
pub struct Imagined {
    vs: VarStore,
    model: MtaPredNet,
    weights: StepWeights,
    start: Option<State>,
}

impl Imagined {
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, CheckpointError> {
        Self::from_checkpoint(&checkpoint::from_bytes(bytes)?)
    }

    pub fn from_checkpoint(ck: &Checkpoint) -> Result<Self, CheckpointError> {
        let (mut vs, model) = ck.build()?;
        vs.freeze();
        let weights = model.inference_weights();
        Ok(Self {
            vs,
            model,
            weights,
            start: None,
        })
    }

    /// [`LiveModel::take_weights`] for the planner's copy.
    pub fn take_weights(&mut self, other: &mut Imagined) -> bool {
        if other.model.config() != self.model.config() || self.vs.copy(&other.vs).is_err() {
            return false;
        }
        std::mem::swap(&mut self.weights, &mut other.weights);
        true
    }

    pub fn model(&self) -> &MtaPredNet {
        &self.model
    }

    /// Plans start from `from` itself (no committed segment to roll through).
    pub fn start_here(&mut self, from: State) {
        self.start = Some(from);
    }
}

impl Imagination for Imagined {
    type Start = State;

    fn start(&mut self, from: State, committed: Wheels) -> anyhow::Result<()> {
        let _guard = tch::no_grad_guard();
        let a = Tensor::from_slice(&committed).view([1, 2]);
        let (state, _) = self.model.f_imagine_step_with(&self.weights, &from, &a)?;
        self.start = Some(state);
        Ok(())
    }

    fn imagine(&mut self, plans: &[Vec<Drive>]) -> anyhow::Result<Vec<Vec<f32>>> {
        let done = self.rollout(plans, None)?;
        Ok(done.expect("a rollout without a deadline runs to the end"))
    }

    fn imagine_until(
        &mut self,
        plans: &[Vec<Drive>],
        deadline: Instant,
    ) -> anyhow::Result<Option<Vec<Vec<f32>>>> {
        self.rollout(plans, Some(deadline))
    }

    /// libtorch builds a convolution's work for each new input shape (tens of ms each here):
    /// done once per batch size from an empty state. The cache is the process's, so later
    /// weights and copies of the network find it.
    fn warm_up(&mut self, batch_sizes: &[usize], horizon: usize) -> anyhow::Result<()> {
        let kept = self.start.take();
        self.start(self.model.zero_state(1), [0.0; 2])?;
        for &k in batch_sizes {
            self.rollout(&vec![vec![Drive::new(0.0, 0.0); horizon]; k], None)?;
        }
        self.start = kept;
        Ok(())
    }
}

impl Imagined {
    /// All K plans in one batch, the first step's action-independent work done once; `None`
    /// when `deadline` passed between two imagined steps.
    fn rollout(
        &mut self,
        plans: &[Vec<Drive>],
        deadline: Option<Instant>,
    ) -> anyhow::Result<Option<Vec<Vec<f32>>>> {
        let _guard = tch::no_grad_guard();
        let start = self
            .start
            .as_ref()
            .ok_or_else(|| anyhow::anyhow!("imagine before start"))?;
        let (k, h) = (plans.len() as i64, plans.first().map_or(0, Vec::len) as i64);
        anyhow::ensure!(
            plans.iter().all(|p| p.len() as i64 == h),
            "plans of different lengths"
        );
        let flat: Vec<f32> = plans.iter().flatten().flat_map(|d| d.wheels()).collect();
        let actions = Tensor::from_slice(&flat).view([k, h, 2]);
        let Some((all, _)) =
            self.model
                .f_rollout_until(&self.weights, start, &actions, deadline)?
        else {
            return Ok(None);
        };
        // [K, H, 1, rows, cols] -> one row of H frames per plan.
        let all = all.contiguous().view([k, -1]);
        let values = Vec::<f32>::try_from(all.flatten(0, -1))?;
        let per = values.len() / k.max(1) as usize;
        Ok(Some(
            values.chunks(per.max(1)).map(<[f32]>::to_vec).collect(),
        ))
    }
}

#[cfg(test)]
mod tests;
