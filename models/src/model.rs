//! MTA-PredNet: Algorithm 1 of the paper (top-down pass, then bottom-up pass, once per step).
//!
//! Pure: no optimiser, no I/O, no global state. Inference callers should run under
//! `tch::no_grad_guard()` (or freeze the VarStore) so that state does not drag a growing graph.

use crate::config::{ConfigError, ErrorLoss, ModelConfig};
use crate::layer::PredLayer;
use crate::state::{LayerState, SequenceOutput, State, StepOutput};
use tch::{Kind, Tensor, nn};

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

/// One layer's new unit states: (h per unit, c per unit).
type UnitStates = (Vec<Tensor>, Vec<Tensor>);

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
        }
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
        let b = self.check_state(state)?;
        let frame = self.check_frame(frame, b)?;
        self.check_action(action, b)?;
        let (tops, rs) = self.top_down(state, action);
        Ok(self.bottom_up(tops, rs, Some(frame)))
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
        let b = self.check_state(state)?;
        self.check_action(action, b)?;
        let (tops, rs) = self.top_down(state, action);
        let (state, out) = self.bottom_up(tops, rs, None);
        Ok((state, out.prediction))
    }

    /// Bottom-up half of a step from the top-down results: errors against `frame`, or against
    /// the prediction itself when `None` (imagination).
    fn bottom_up(
        &self,
        tops: Vec<UnitStates>,
        rs: Vec<Tensor>,
        frame: Option<Tensor>,
    ) -> (State, StepOutput) {
        let mut layers = Vec::with_capacity(self.layers.len());
        let mut errors: Vec<Tensor> = Vec::with_capacity(self.layers.len());
        let mut x = frame;
        let mut prediction = None;
        for (l, ((layer, (h, c)), r)) in self.layers.iter().zip(tops).zip(rs).enumerate() {
            if l > 0 {
                x = Some(
                    layer
                        .target_from_below(&errors[l - 1])
                        .expect("layers above 0 have an input conv"),
                );
            }
            let xhat = layer.predict(&r);
            let target = x.get_or_insert_with(|| xhat.shallow_clone());
            let e = PredLayer::error(target, &xhat);
            if l == 0 {
                prediction = Some(xhat);
            }
            errors.push(e.shallow_clone());
            layers.push(LayerState { h, c, r, e });
        }
        let prediction = prediction.expect("at least one layer");
        (State { layers }, StepOutput { prediction, errors })
    }

    /// Top-down pass for every layer: ((h, c) per layer, R per layer), bottom first.
    fn top_down(&self, state: &State, action: &Tensor) -> (Vec<UnitStates>, Vec<Tensor>) {
        let n = self.layers.len();
        let mut tops = Vec::with_capacity(n);
        let mut rs: Vec<Tensor> = Vec::with_capacity(n);
        for l in (0..n).rev() {
            let (h, c, r) = self.layers[l].top_down(&state.layers[l], rs.last(), action);
            tops.push((h, c));
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
        if b == k {
            let (_, rs) = self.top_down(state, actions);
            return Ok(self.layers[0].predict(&rs[0]));
        }
        if b != 1 {
            return Err(ModelError::Batch { state: b, input: k });
        }
        let mut r: Option<Tensor> = None;
        for (layer, ls) in self.layers.iter().zip(&state.layers).rev() {
            r = Some(layer.top_down_candidates(ls, r.as_ref(), actions));
        }
        let r0 = r.expect("at least one layer");
        Ok(self.layers[0].predict(&r0))
    }

    /// Runs a whole batch of sequences from the zero state (training, evaluation).
    pub fn forward_sequence(&self, frames: &Tensor, actions: &Tensor) -> SequenceOutput {
        let b = frames.size().first().copied().unwrap_or(0);
        self.f_forward_sequence_from(&self.zero_state(b), frames, actions)
            .unwrap_or_else(|e| panic!("MtaPredNet::forward_sequence: {e}"))
    }

    /// Runs `frames` `[B, T, 1, H, W]` or `[B, T, H, W]` with `actions` `[B, T, A]` from `state`.
    pub fn f_forward_sequence_from(
        &self,
        state: &State,
        frames: &Tensor,
        actions: &Tensor,
    ) -> Result<SequenceOutput, ModelError> {
        self.f_forward_sequence_imagining(state, frames, actions, i64::MAX)
    }

    /// [`Self::f_forward_sequence_from`] that observes only the first `observed` frames and
    /// imagines the rest: from step `observed` on, each step takes its own prediction as the
    /// input (as a planner's rollout does); predictions and errors are still scored against the
    /// real frames. Training through this teaches the model to predict several steps ahead.
    pub fn f_forward_sequence_imagining(
        &self,
        state: &State,
        frames: &Tensor,
        actions: &Tensor,
        observed: i64,
    ) -> Result<SequenceOutput, ModelError> {
        let size = frames.size();
        let (h, w) = (self.cfg.image_height, self.cfg.image_width);
        let frames = match size.as_slice() {
            [b, t, 1, hh, ww] if (*hh, *ww) == (h, w) => frames.shallow_clone(),
            [b, t, hh, ww] if (*hh, *ww) == (h, w) => frames.reshape([*b, *t, 1, h, w]),
            _ => {
                return Err(ModelError::FrameShape {
                    expected: format!("[B, T, (1,) {h}, {w}]"),
                    got: size,
                });
            }
        };
        let (b, t) = (size[0], size[1]);
        let asz = actions.size();
        if asz != [b, t, self.cfg.action_dim] {
            let expected = format!("[{b}, {t}, {}]", self.cfg.action_dim);
            return Err(ModelError::ActionShape { expected, got: asz });
        }
        let mut state = state.shallow_clone();
        let mut predictions = Vec::with_capacity(t as usize);
        let mut layer_errors = Vec::with_capacity(t as usize);
        for i in 0..t {
            let (next, out) = if i < observed {
                self.f_step(&state, &frames.select(1, i), &actions.select(1, i))?
            } else {
                let (next, prediction) = self.f_imagine_step(&state, &actions.select(1, i))?;
                // The loss still compares the prediction with what really came.
                let out = self.score(&prediction, &frames.select(1, i), &next)?;
                (next, out)
            };
            predictions.push(out.prediction);
            let reduced: Vec<Tensor> = out.errors.iter().map(|e| self.reduce_error(e)).collect();
            layer_errors.push(Tensor::stack(&reduced, 1)); // [B, L]
            state = next;
        }
        Ok(SequenceOutput {
            predictions: Tensor::stack(&predictions, 1),
            layer_errors: Tensor::stack(&layer_errors, 1),
            state,
        })
    }

    /// The errors an imagined step would have had against the real frame: layer 0 only (upper
    /// layers' targets come from errors the imagination never saw); the other layers score 0.
    fn score(
        &self,
        prediction: &Tensor,
        frame: &Tensor,
        next: &State,
    ) -> Result<StepOutput, ModelError> {
        let b = prediction.size()[0];
        let frame = self.check_frame(frame, b)?;
        let mut errors = vec![PredLayer::error(&frame, prediction)];
        errors.extend(next.layers.iter().skip(1).map(|l| l.e.zeros_like()));
        Ok(StepOutput {
            prediction: prediction.shallow_clone(),
            errors,
        })
    }

    /// Per-sample loss reduction of one E_l: `[B]`.
    fn reduce_error(&self, e: &Tensor) -> Tensor {
        let dims: &[i64] = &[1, 2, 3];
        match self.cfg.error_loss {
            ErrorLoss::L1 => e.mean_dim(dims, false, Kind::Float),
            // E's two halves are disjoint relus, so sum over channels of E^2 = (X - Xhat)^2 summed
            // over X's channels: times 2 makes this the plain MSE per element of X.
            ErrorLoss::L2 => e.square().mean_dim(dims, false, Kind::Float) * 2.0,
        }
    }

    fn check_state(&self, state: &State) -> Result<i64, ModelError> {
        if state.layers.len() != self.layers.len() {
            return Err(ModelError::State(format!(
                "{} layers, network has {}",
                state.layers.len(),
                self.layers.len()
            )));
        }
        for (l, (s, layer)) in state.layers.iter().zip(&self.layers).enumerate() {
            if s.h.len() != layer.gus.len() || s.c.len() != layer.gus.len() {
                return Err(ModelError::State(format!(
                    "layer {l}: {} units, network has {}",
                    s.h.len(),
                    layer.gus.len()
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

fn check_kind(what: &'static str, t: &Tensor) -> Result<(), ModelError> {
    match t.kind() {
        Kind::Float => Ok(()),
        got => Err(ModelError::Kind { what, got }),
    }
}
