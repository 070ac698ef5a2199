//! Whole sequences through the network (training and evaluation): the fused weights and every
//! step's action weights built once, observed steps then imagined ones, one loss reduction per
//! layer at the end.

use super::{ModelError, MtaPredNet, check_kind};
use crate::config::ErrorLoss;
use crate::layer::PredLayer;
use crate::state::{SequenceOutput, State, StepOutput};
use tch::{Kind, Tensor};

impl MtaPredNet {
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
        self.check_state(state)?;
        if state.batch() != b {
            return Err(ModelError::Batch {
                state: state.batch(),
                input: b,
            });
        }
        check_kind("frames", &frames)?;
        check_kind("actions", actions)?;
        // Once per sequence: the units' fused weights and every step's action weights.
        let w = self.weights();
        let mixes: Vec<Tensor> = self
            .action_weights(&actions.reshape([b * t, -1]))
            .into_iter()
            .map(|m| m.view([b, t, -1]))
            .collect();
        let mut state = state.shallow_clone();
        let mut predictions = Vec::with_capacity(t as usize);
        let mut errors: Vec<Vec<Tensor>> = (0..self.layers.len()).map(|_| Vec::new()).collect();
        for i in 0..t {
            let mix: Vec<Tensor> = mixes.iter().map(|m| m.select(1, i)).collect();
            let frame = frames.select(1, i);
            let (next, out) = if i < observed {
                self.step_inner(&w, &state, Some(frame), &mix)
            } else {
                let (next, out) = self.step_inner(&w, &state, None, &mix);
                // The loss still compares the prediction with what really came.
                (next, self.score(&out.prediction, &frame, &out.errors))
            };
            predictions.push(out.prediction);
            for (l, e) in out.errors.into_iter().enumerate() {
                errors[l].push(e);
            }
            state = next;
        }
        // One reduction per layer over all steps: [B, T, ...] -> [B, T].
        let reduced: Vec<Tensor> = errors
            .iter()
            .map(|es| self.reduce_error(&Tensor::stack(es, 1)))
            .collect();
        Ok(SequenceOutput {
            predictions: Tensor::stack(&predictions, 1),
            layer_errors: Tensor::stack(&reduced, 2),
            state,
        })
    }

    /// The errors an imagined step would have had against the real frame: layer 0 only (upper
    /// layers' targets come from errors the imagination never saw); the other layers score 0.
    fn score(&self, prediction: &Tensor, frame: &Tensor, imagined: &[Tensor]) -> StepOutput {
        let mut errors = vec![PredLayer::error(frame, prediction)];
        errors.extend(imagined.iter().skip(1).map(Tensor::zeros_like));
        StepOutput {
            prediction: prediction.shallow_clone(),
            errors,
        }
    }

    /// Per-sample, per-step loss reduction of E_l `[B, T, C, H, W]`: `[B, T]`.
    fn reduce_error(&self, e: &Tensor) -> Tensor {
        let dims: &[i64] = &[2, 3, 4];
        match self.cfg.error_loss {
            ErrorLoss::L1 => e.mean_dim(dims, false, Kind::Float),
            // E's two halves are disjoint relus, so sum over channels of E^2 = (X - Xhat)^2 summed
            // over X's channels: times 2 makes this the plain MSE per element of X.
            ErrorLoss::L2 => e.square().mean_dim(dims, false, Kind::Float) * 2.0,
        }
    }
}
