//! MTA-PredNet: Algorithm 1 of the paper (top-down pass, then bottom-up pass, once per step).
//!
//! Pure: no optimiser, no I/O, no global state. Inference callers should run under
//! `tch::no_grad_guard()` (or freeze the VarStore) so that state does not drag a growing graph.

use crate::config::{ConfigError, ModelConfig};
use crate::layer::{LayerWeights, PredLayer};
use crate::state::{LayerState, State, StepOutput};
use tch::{Kind, Tensor, nn};

mod sequence;

/// Inputs the network cannot take.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// A frame (or frame sequence) does not have the configured image shape.
    #[error("frames: expected {expected}, got {got:?}")]
    FrameShape { expected: String, got: Vec<i64> },
    /// An action tensor does not have the configured action size or layout.
    #[error("actions: expected {expected}, got {got:?}")]
    ActionShape { expected: String, got: Vec<i64> },
    /// State, frames and actions disagree on the batch size.
    #[error("batch mismatch: state {state}, frames/actions {input}")]
    Batch { state: i64, input: i64 },
    /// Frames or actions are not float32 (the weights' kind).
    #[error("{what}: expected float32, got {got:?}")]
    Kind { what: &'static str, got: Kind },
    /// The state was made for a different network (layer count or unit count).
    #[error("state does not fit this network: {0}")]
    State(String),
}

/// One layer's new unit states: (h, c), each `[B, G, C, H, W]`.
type UnitStates = (Tensor, Tensor);

/// Weights derived from the parameters for stepping (see `PredLayer::weights`). Build them once
/// per sequence, or once per weights version for inference ([`MtaPredNet::weights`]), and
/// again after the parameters change.
#[derive(Debug)]
pub struct StepWeights {
    layers: Vec<LayerWeights>,
}

#[derive(Debug)]
pub struct MtaPredNet {
    /// Bottom layer first, at `layer{l}`.
    pub layers: Vec<PredLayer>,
    cfg: ModelConfig,
}

impl MtaPredNet {
    /// Builds the network under `p`. Panics on an invalid config; see [`Self::f_new`].
    pub fn new(p: &nn::Path, cfg: &ModelConfig) -> Self {
        Self::f_new(p, cfg).unwrap_or_else(|e| panic!("invalid ModelConfig: {e}"))
    }

    /// Builds the network under `p` after validating `cfg`.
    pub fn f_new(p: &nn::Path, cfg: &ModelConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let layers = (0..cfg.layers())
            .map(|l| PredLayer::new(p, cfg, l))
            .collect();
        Ok(Self {
            layers,
            cfg: cfg.clone(),
        })
    }

    pub fn config(&self) -> &ModelConfig {
        &self.cfg
    }

    pub fn zero_state(&self, batch: i64) -> State {
        State {
            layers: self.layers.iter().map(|l| l.zero_state(batch)).collect(),
            imagined: false,
        }
    }

    /// The weights for stepping, from the current parameters.
    pub fn weights(&self) -> StepWeights {
        StepWeights {
            layers: self.layers.iter().map(PredLayer::weights).collect(),
        }
    }

    /// [`Self::weights`] for inference: the convolutions also packed for small batches
    /// (`packed_conv.rs`), several times faster at batch 1. Build once per weights version; they
    /// track no gradients (a step through them with inputs that do falls back to libtorch).
    pub fn inference_weights(&self) -> StepWeights {
        StepWeights {
            layers: self
                .layers
                .iter()
                .map(PredLayer::inference_weights)
                .collect(),
        }
    }

    /// The action weights of every layer for actions `[N, A]`: one `[N, G_l]` per layer.
    pub(crate) fn action_weights(&self, actions: &Tensor) -> Vec<Tensor> {
        self.layers
            .iter()
            .map(|l| l.action_weights(actions))
            .collect()
    }

    /// One step; panics on bad shapes (see [`Self::f_step`]).
    pub fn step(&self, state: &State, frame: &Tensor, action: &Tensor) -> (State, StepOutput) {
        self.f_step(state, frame, action)
            .unwrap_or_else(|e| panic!("MtaPredNet::step: {e}"))
    }

    /// One step of Algorithm 1. `frame` is X_0(t), `[B, 1, H, W]` or `[B, H, W]`; `action` is
    /// a(t) `[B, A]`, the action that moved the world from frame t-1 to t.
    pub fn f_step(
        &self,
        state: &State,
        frame: &Tensor,
        action: &Tensor,
    ) -> Result<(State, StepOutput), ModelError> {
        self.f_step_with(&self.weights(), state, frame, action)
    }

    /// [`Self::f_step`] with weights built once by [`Self::weights`].
    pub fn f_step_with(
        &self,
        w: &StepWeights,
        state: &State,
        frame: &Tensor,
        action: &Tensor,
    ) -> Result<(State, StepOutput), ModelError> {
        let b = self.check_state(state)?;
        let frame = self.check_frame(frame, b)?;
        self.check_action(action, b)?;
        Ok(self.step_inner(w, state, Some(frame), &self.action_weights(action)))
    }

    /// One step of imagination: predicts X_0(t) under `action` `[B, A]` and takes the prediction
    /// as if it had been observed (so E_0(t) = 0). Returns the new state and the prediction
    /// `[B, 1, H, W]`; one pass, where predicting and then stepping would run the top-down pass
    /// twice.
    pub fn f_imagine_step(
        &self,
        state: &State,
        action: &Tensor,
    ) -> Result<(State, Tensor), ModelError> {
        self.f_imagine_step_with(&self.weights(), state, action)
    }

    /// [`Self::f_imagine_step`] with weights built once by [`Self::weights`].
    pub fn f_imagine_step_with(
        &self,
        w: &StepWeights,
        state: &State,
        action: &Tensor,
    ) -> Result<(State, Tensor), ModelError> {
        let b = self.check_state(state)?;
        self.check_action(action, b)?;
        let (state, out) = self.step_inner(w, state, None, &self.action_weights(action));
        Ok((state, out.prediction))
    }

    /// Imagines K plans `actions` `[K, H, A]` from `start` (batch 1 or K): Xhat_0 of every
    /// step, `[K, H, 1, rows, cols]`, and the final states. From batch 1 the first step does the
    /// action-independent work once (as [`Self::f_predict_candidates`]); the action weights of
    /// all K x H steps come from one MLP call; every step after the first skips the zero
    /// E_0 columns and the constant X_1.
    pub fn f_rollout(
        &self,
        w: &StepWeights,
        start: &State,
        actions: &Tensor,
    ) -> Result<(Tensor, State), ModelError> {
        let done = self.f_rollout_until(w, start, actions, None)?;
        Ok(done.expect("a rollout without a deadline runs to the end"))
    }

    /// [`Self::f_rollout`], given up (`None`) when `deadline` has passed before an imagined
    /// step: a plan in real time stops its batch there instead of overrunning its segment.
    pub fn f_rollout_until(
        &self,
        w: &StepWeights,
        start: &State,
        actions: &Tensor,
        deadline: Option<std::time::Instant>,
    ) -> Result<Option<(Tensor, State)>, ModelError> {
        let b = self.check_state(start)?;
        let size = actions.size();
        let (k, h) = match size.as_slice() {
            [k, h, a] if *a == self.cfg.action_dim && (b == 1 || b == *k) => (*k, *h),
            _ => {
                return Err(ModelError::ActionShape {
                    expected: format!(
                        "[K, H, {}] with K = {b} or a batch-1 state",
                        self.cfg.action_dim
                    ),
                    got: size,
                });
            }
        };
        check_kind("actions", actions)?;
        let mixes = self.action_weights(&actions.reshape([k * h, -1]));
        let at = |s: i64| -> Vec<Tensor> {
            mixes
                .iter()
                .map(|m| m.view([k, h, -1]).select(1, s))
                .collect()
        };
        let mut state = start.shallow_clone();
        let mut predictions = Vec::with_capacity(h as usize);
        for s in 0..h {
            if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
                return Ok(None);
            }
            let mix = at(s);
            let (next, out) = if s == 0 && b == 1 && k > 1 {
                let (tops, rs) = self.top_down_candidates(w, &state, &mix);
                self.bottom_up(w, tops, rs, None)
            } else {
                self.step_inner(w, &state, None, &mix)
            };
            predictions.push(out.prediction);
            state = next;
        }
        Ok(Some((Tensor::stack(&predictions, 1), state)))
    }

    /// A step from checked inputs: `frame` None imagines (the prediction is taken as seen).
    pub(crate) fn step_inner(
        &self,
        w: &StepWeights,
        state: &State,
        frame: Option<Tensor>,
        mix: &[Tensor],
    ) -> (State, StepOutput) {
        let (tops, rs) = self.top_down(w, state, mix);
        self.bottom_up(w, tops, rs, frame)
    }

    /// Bottom-up half of a step from the top-down results: errors against `frame`, or against
    /// the prediction itself when `None` (imagination: E_0 = 0 and X_1 is a constant).
    fn bottom_up(
        &self,
        w: &StepWeights,
        tops: Vec<UnitStates>,
        rs: Vec<Tensor>,
        frame: Option<Tensor>,
    ) -> (State, StepOutput) {
        let imagined = frame.is_none();
        let mut layers = Vec::with_capacity(self.layers.len());
        let mut errors: Vec<Tensor> = Vec::with_capacity(self.layers.len());
        let mut prediction = None;
        let mut x = frame;
        for (l, ((layer, (h, c)), r)) in self.layers.iter().zip(tops).zip(rs).enumerate() {
            let xhat = layer.predict(&w.layers[l], &r);
            let e = if l == 0 && imagined {
                xhat.zeros_like().repeat([1, 2, 1, 1])
            } else {
                if l > 0 {
                    let below = (!(l == 1 && imagined)).then(|| &errors[l - 1]);
                    x = layer.target_from_below(&w.layers[l], below);
                }
                PredLayer::error(x.as_ref().expect("X_l of an observed step"), &xhat)
            };
            if l == 0 {
                prediction = Some(xhat);
            }
            errors.push(e.shallow_clone());
            layers.push(LayerState { h, c, r, e });
        }
        let prediction = prediction.expect("at least one layer");
        (
            State { layers, imagined },
            StepOutput { prediction, errors },
        )
    }

    /// Top-down pass for every layer: ((h, c) per layer, R per layer), bottom first.
    fn top_down(
        &self,
        w: &StepWeights,
        state: &State,
        mix: &[Tensor],
    ) -> (Vec<UnitStates>, Vec<Tensor>) {
        let n = self.layers.len();
        let mut tops = Vec::with_capacity(n);
        let mut rs: Vec<Tensor> = Vec::with_capacity(n);
        for l in (0..n).rev() {
            let e_zero = l == 0 && state.imagined;
            let (h, c, r) =
                self.layers[l].top_down(&w.layers[l], &state.layers[l], rs.last(), &mix[l], e_zero);
            tops.push((h, c));
            rs.push(r);
        }
        tops.reverse();
        rs.reverse();
        (tops, rs)
    }

    /// [`Self::top_down`] for K candidates' action weights from a batch-1 state; the top
    /// layer's h and c (batch 1: they do not depend on the action) are broadcast to K.
    fn top_down_candidates(
        &self,
        w: &StepWeights,
        state: &State,
        mix: &[Tensor],
    ) -> (Vec<UnitStates>, Vec<Tensor>) {
        let n = self.layers.len();
        let k = mix[0].size()[0];
        let mut tops = Vec::with_capacity(n);
        let mut rs: Vec<Tensor> = Vec::with_capacity(n);
        for l in (0..n).rev() {
            let e_zero = l == 0 && state.imagined;
            let (h, c, r) = self.layers[l].top_down_candidates(
                &w.layers[l],
                &state.layers[l],
                rs.last(),
                &mix[l],
                e_zero,
            );
            let wide = |t: Tensor| {
                let mut s = t.size();
                if s[0] == k {
                    return t;
                }
                s[0] = k;
                t.expand(s.as_slice(), false)
            };
            tops.push((wide(h), wide(c)));
            rs.push(r);
        }
        tops.reverse();
        rs.reverse();
        (tops, rs)
    }

    /// Xhat_0(t) for each of K candidate actions; panics on bad shapes (see
    /// [`Self::f_predict_candidates`]).
    pub fn predict_candidates(&self, state: &State, actions: &Tensor) -> Tensor {
        self.f_predict_candidates(state, actions)
            .unwrap_or_else(|e| panic!("MtaPredNet::predict_candidates: {e}"))
    }

    /// Xhat_0(t) `[K, 1, H, W]` for each row of `actions` `[K, A]` from one state (batch 1; a
    /// state of batch K is used row by row). Runs only the top-down pass and the layer-0 Xhat
    /// conv: the frame is not needed. From batch 1, the work that does not depend on the action
    /// is done once (see `PredLayer::top_down_candidates`); results equal K single steps up to
    /// float rounding (~1e-6).
    pub fn f_predict_candidates(
        &self,
        state: &State,
        actions: &Tensor,
    ) -> Result<Tensor, ModelError> {
        let b = self.check_state(state)?;
        let k = actions.size().first().copied().unwrap_or(0);
        self.check_action(actions, k)?;
        let w = self.weights();
        let mix = self.action_weights(actions);
        let (_, rs) = if b == k {
            self.top_down(&w, state, &mix)
        } else if b == 1 {
            self.top_down_candidates(&w, state, &mix)
        } else {
            return Err(ModelError::Batch { state: b, input: k });
        };
        Ok(self.layers[0].predict(&w.layers[0], &rs[0]))
    }

    pub(crate) fn check_state(&self, state: &State) -> Result<i64, ModelError> {
        if state.layers.len() != self.layers.len() {
            return Err(ModelError::State(format!(
                "{} layers, network has {}",
                state.layers.len(),
                self.layers.len()
            )));
        }
        for (l, (s, layer)) in state.layers.iter().zip(&self.layers).enumerate() {
            let g = layer.unit_count();
            if s.h.dim() != 5 || s.h.size()[1] != g || s.c.size() != s.h.size() {
                return Err(ModelError::State(format!(
                    "layer {l}: h {:?}, c {:?}; the network has {g} units",
                    s.h.size(),
                    s.c.size()
                )));
            }
        }
        Ok(state.batch())
    }

    fn check_frame(&self, frame: &Tensor, b: i64) -> Result<Tensor, ModelError> {
        let (h, w) = (self.cfg.image_height, self.cfg.image_width);
        let size = frame.size();
        let ok = match size.as_slice() {
            [bb, 1, hh, ww] | [bb, hh, ww] => (*hh, *ww) == (h, w) && *bb == b,
            _ => false,
        };
        if !ok {
            return Err(ModelError::FrameShape {
                expected: format!("[{b}, 1, {h}, {w}] or [{b}, {h}, {w}]"),
                got: size,
            });
        }
        check_kind("frame", frame)?;
        Ok(frame.reshape([b, 1, h, w]))
    }

    fn check_action(&self, action: &Tensor, b: i64) -> Result<(), ModelError> {
        let size = action.size();
        if size != [b, self.cfg.action_dim] {
            return Err(ModelError::ActionShape {
                expected: format!("[{b}, {}]", self.cfg.action_dim),
                got: size,
            });
        }
        check_kind("action", action)
    }
}

pub(crate) fn check_kind(what: &'static str, t: &Tensor) -> Result<(), ModelError> {
    match t.kind() {
        Kind::Float => Ok(()),
        got => Err(ModelError::Kind { what, got }),
    }
}
