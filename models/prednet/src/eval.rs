//! Held-out metrics: next-frame error against the two trivial predictors and against the model
//! itself fed with the wrong actions.

use crate::data::Dataset;
use crate::model::{ModelError, MtaPredNet};
use serde::{Deserialize, Serialize};
use tch::{Kind, Tensor};

/// Mean squared next-frame errors over t >= 1 (t = 0 is predicted from the empty state).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalMetrics {
    /// The model's Xhat_0(t) against X_0(t).
    pub mse: f64,
    /// Predicting X_0(t-1), i.e. "nothing moves".
    pub copy_last_mse: f64,
    /// Predicting the data set's mean frame at every step (what a model that ignores its input
    /// converges to; the reference code's failure mode).
    pub mean_frame_mse: f64,
    /// The model with each sequence's actions taken from another sequence: above `mse` only if
    /// the model uses the action. `None` for a single sequence or when not asked for.
    pub mse_shuffled_actions: Option<f64>,
    /// `mse / copy_last_mse`.
    pub mse_over_copy_last: f64,
    /// The model's mse at each t (index 0 included for completeness).
    pub mse_per_step: Vec<f64>,
    pub sequences: i64,
    pub steps: i64,
}

/// Evaluates `model` on all of `data` in chunks of `batch` sequences, without gradients.
/// `shuffle_seed` picks the action shuffle; `None` skips that (second) pass.
pub fn evaluate(
    model: &MtaPredNet,
    data: &Dataset,
    batch: i64,
    shuffle_seed: Option<u64>,
) -> Result<EvalMetrics, ModelError> {
    let _g = tch::no_grad_guard();
    let (n, t) = (data.len(), data.steps());
    let per_step = |actions: &Tensor| -> Result<Tensor, ModelError> {
        let mut sums = Tensor::zeros([t], (Kind::Double, data.images.device()));
        for start in (0..n).step_by(batch.max(1) as usize) {
            let len = batch.min(n - start);
            let imgs = data.images.narrow(0, start, len);
            let state = model.zero_state(len);
            let out =
                model.f_forward_sequence_from(&state, &imgs, &actions.narrow(0, start, len))?;
            let se = (out.predictions.squeeze_dim(2) - &imgs).square();
            sums += se.sum_dim_intlist([0, 2, 3].as_slice(), false, Kind::Double);
        }
        let (h, w) = data.image_size();
        Ok(sums / (n * h * w) as f64)
    };
    let steps = per_step(&data.actions)?;
    let later = |s: &Tensor| s.narrow(0, 1, t - 1).mean(Kind::Double).double_value(&[]);
    let mse = later(&steps);
    let shuffled = match shuffle_seed {
        Some(seed) if n >= 2 => Some(later(&per_step(&data.shuffled_actions(seed))?)),
        _ => None,
    };
    let imgs = &data.images;
    let copy_last = (imgs.narrow(1, 1, t - 1) - imgs.narrow(1, 0, t - 1))
        .square()
        .mean(Kind::Double);
    let mean_frame = imgs.mean_dim([0, 1].as_slice(), true, Kind::Float);
    let mean_frame_mse = (imgs.narrow(1, 1, t - 1) - mean_frame)
        .square()
        .mean(Kind::Double);
    let copy_last_mse = copy_last.double_value(&[]);
    Ok(EvalMetrics {
        mse,
        copy_last_mse,
        mean_frame_mse: mean_frame_mse.double_value(&[]),
        mse_shuffled_actions: shuffled,
        mse_over_copy_last: mse / copy_last_mse,
        mse_per_step: Vec::<f64>::try_from(&steps).unwrap_or_default(),
        sequences: n,
        steps: t,
    })
}
