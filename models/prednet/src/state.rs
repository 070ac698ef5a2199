//! The recurrent state carried between steps, and what a step or a sequence returns.

use tch::{Device, Tensor};

/// State of one layer after step t: what step t + 1 needs.
#[derive(Debug)]
pub struct LayerState {
    /// Each generative unit's own h (its R^d_l), `[B, G, channels_l, H_l, W_l]` (unit d at
    /// index d of dim 1). Never shared between units (the reference code aliased them, so its
    /// units collapsed into one).
    pub h: Tensor,
    /// Each generative unit's own ConvLSTM cell state, same shape as `h`.
    pub c: Tensor,
    /// R_l(t) = sum_d w_d(a(t)) h_d: the layer's representation (read by analysis, not by step).
    pub r: Tensor,
    /// E_l(t) = [relu(X - Xhat); relu(Xhat - X)], `[B, 2 a_channels_l, H_l, W_l]`.
    pub e: Tensor,
}

/// The whole network's state, bottom layer first.
#[derive(Debug)]
pub struct State {
    pub layers: Vec<LayerState>,
    /// The last step took its own prediction as observed, so E_0 = 0: the next step skips
    /// the convolution columns a zero input cannot change.
    pub imagined: bool,
}

impl LayerState {
    fn map(&self, f: &impl Fn(&Tensor) -> Tensor) -> LayerState {
        LayerState {
            h: f(&self.h),
            c: f(&self.c),
            r: f(&self.r),
            e: f(&self.e),
        }
    }
}

impl State {
    fn map(&self, f: impl Fn(&Tensor) -> Tensor) -> State {
        State {
            layers: self.layers.iter().map(|l| l.map(&f)).collect(),
            imagined: self.imagined,
        }
    }

    /// Batch size B.
    pub fn batch(&self) -> i64 {
        self.layers.first().map_or(0, |l| l.e.size()[0])
    }

    /// Cuts the autograd history (truncated BPTT; also keeps an online predictor's memory flat).
    pub fn detach(&self) -> State {
        self.map(|t| t.detach())
    }

    /// A handle to the same tensors (cheap; tch tensors are not `Clone`).
    pub fn shallow_clone(&self) -> State {
        self.map(|t| t.shallow_clone())
    }

    /// A copy that shares no storage with this one (safe to hand to another thread).
    pub fn deep_copy(&self) -> State {
        self.map(|t| t.copy())
    }

    /// Moves every tensor to `device`.
    pub fn to(&self, device: Device) -> State {
        self.map(|t| t.to_device(device))
    }

    /// K copies of each batch element, in order (`[b0 x K, b1 x K, ...]`). From batch 1 it is a
    /// broadcast view, no copy: that is the candidate-action case.
    pub fn expand(&self, k: i64) -> State {
        if self.batch() == 1 {
            self.map(|t| {
                let mut size = t.size();
                size[0] = k;
                t.expand(size.as_slice(), false)
            })
        } else {
            self.map(|t| t.repeat_interleave_self_int(k, 0, None))
        }
    }

    /// Rows `index` (a 1-d int64 tensor) of every tensor: e.g. to keep the chosen candidate.
    pub fn select(&self, index: &Tensor) -> State {
        self.map(|t| t.index_select(0, index))
    }
}

/// What one step of Algorithm 1 returns besides the new state.
#[derive(Debug)]
pub struct StepOutput {
    /// Xhat_0(t) `[B, 1, H, W]`: the frame predicted from the previous state and a(t), before
    /// seeing X_0(t).
    pub prediction: Tensor,
    /// E_l(t) per layer, bottom first.
    pub errors: Vec<Tensor>,
}

/// What a sequence run returns (training and evaluation).
#[derive(Debug)]
pub struct SequenceOutput {
    /// Xhat_0(t) for every t, `[B, T, 1, H, W]`.
    pub predictions: Tensor,
    /// Loss reduction (per `ModelConfig::error_loss`) of E_l(t) per sample: `[B, T, L]`.
    pub layer_errors: Tensor,
    /// The state after the last step (for truncated BPTT or to keep predicting).
    pub state: State,
}
