//! The paper's claims, measured on any run: per-layer slowness of R_l(t), and the figure strip.

use crate::data::Dataset;
use crate::eval::{EvalMetrics, evaluate};
use crate::model::{ModelError, MtaPredNet};
use serde::{Deserialize, Serialize};
use std::path::Path;
use tch::{Kind, Tensor};

pub use crate::figure::{FigureError, FigureInfo, figure_strip};

/// Slowness of one layer, measured on two signals: R_l(t), the action-weighted output (what the
/// layer below and Xhat see), and the units' own states h^d_l(t) (what tau integrates). R also
/// moves whenever the action changes the unit weights, so the two can disagree.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerSlowness {
    pub layer: usize,
    pub tau: f64,
    /// Measured on R_l(t).
    pub r: SlownessIndex,
    /// Measured on the generative units' h, concatenated.
    pub units: SlownessIndex,
}

/// How slowly one signal x(t) (a vector per step) changes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SlownessIndex {
    /// sum_units E[(x(t) - x(t-1))^2] / (2 sum_units Var x) = 1 - variance-weighted lag-1
    /// autocorrelation. 0 = frozen, 1 = white noise; lower is slower.
    pub delta_ratio: f64,
    /// Integrated autocorrelation time (steps) of the leading principal components,
    /// 1 + 2 sum_k rho(k) up to the first non-positive rho, averaged with the components'
    /// variances as weights. Higher is slower.
    pub pc_autocorr_time: f64,
    /// Principal components used (enough for 90 % of the variance, at most 8).
    pub components: usize,
    /// Fraction of the variance those components hold.
    pub explained: f64,
}

/// Why an analysis could not be computed.
#[derive(Debug, thiserror::Error)]
pub enum AnalysisError {
    /// The data does not fit the model.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// Too few steps after the transient to measure anything.
    #[error("need more than {skip} + 2 steps per sequence, have {steps}")]
    TooShort { skip: i64, steps: i64 },
    /// The eigendecomposition did not converge.
    #[error("eigendecomposition of layer {layer}'s covariance failed: {detail}")]
    Eigen { layer: usize, detail: String },
}

/// Per layer, R_l(t) and the units' concatenated h over up to `max_sequences` sequences:
/// `([N, T, D_l], [N, T, G_l D_l])`.
pub fn collect_states(
    model: &MtaPredNet,
    data: &Dataset,
    max_sequences: i64,
) -> Result<Vec<(Tensor, Tensor)>, ModelError> {
    let _g = tch::no_grad_guard();
    let n = data.len().min(max_sequences.max(1));
    let (imgs, acts) = (data.images.narrow(0, 0, n), data.actions.narrow(0, 0, n));
    let mut state = model.zero_state(n);
    let layers = model.layers.len();
    let mut rs: Vec<Vec<Tensor>> = (0..layers).map(|_| Vec::new()).collect();
    let mut hs: Vec<Vec<Tensor>> = (0..layers).map(|_| Vec::new()).collect();
    let w = model.inference_weights();
    for t in 0..data.steps() {
        let (next, _) = model.f_step_with(&w, &state, &imgs.select(1, t), &acts.select(1, t))?;
        for (l, ls) in next.layers.iter().enumerate() {
            rs[l].push(ls.r.reshape([n, -1]));
            hs[l].push(ls.h.reshape([n, -1]));
        }
        state = next;
    }
    Ok(rs
        .iter()
        .zip(&hs)
        .map(|(r, h)| (Tensor::stack(r, 1), Tensor::stack(h, 1)))
        .collect())
}

/// Slowness of every layer, measured on `data` after dropping the first `skip` steps (the
/// transient from the zero state).
pub fn slowness(
    model: &MtaPredNet,
    data: &Dataset,
    max_sequences: i64,
    skip: i64,
) -> Result<Vec<LayerSlowness>, AnalysisError> {
    if data.steps() <= skip + 2 {
        return Err(AnalysisError::TooShort {
            skip,
            steps: data.steps(),
        });
    }
    let states = collect_states(model, data, max_sequences)?;
    let cut = |x: &Tensor| x.narrow(1, skip, x.size()[1] - skip).to_kind(Kind::Double);
    states
        .iter()
        .enumerate()
        .map(|(l, (r, h))| {
            Ok(LayerSlowness {
                layer: l,
                tau: model.config().tau[l],
                r: slowness_index(l, &cut(r))?,
                units: slowness_index(l, &cut(h))?,
            })
        })
        .collect()
}

/// Slowness of `r` `[N, T, D]` (float64); `layer` only labels errors.
pub fn slowness_index(layer: usize, r: &Tensor) -> Result<SlownessIndex, AnalysisError> {
    let (n, t, d) = (r.size()[0], r.size()[1], r.size()[2]);
    let centered = r - r.mean_dim([0, 1].as_slice(), true, Kind::Double);
    let var = centered
        .square()
        .mean(Kind::Double)
        .double_value(&[])
        .max(1e-30);
    let dr = r.narrow(1, 1, t - 1) - r.narrow(1, 0, t - 1);
    let delta_ratio = dr.square().mean(Kind::Double).double_value(&[]) / (2.0 * var);
    // Covariance (D x D) with libtorch's BLAS, eigendecomposition with faer.
    let x = centered.reshape([n * t, d]);
    let cov = x.transpose(0, 1).matmul(&x) / (n * t) as f64;
    let cov_v = Vec::<f64>::try_from(cov.flatten(0, -1)).map_err(|e| eigen_err(layer, e))?;
    let du = d as usize;
    let m = faer::Mat::<f64>::from_fn(du, du, |i, j| cov_v[i * du + j]);
    let evd = m
        .self_adjoint_eigen(faer::Side::Lower)
        .map_err(|e| eigen_err(layer, format!("{e:?}")))?;
    let s = evd.S().column_vector();
    let u = evd.U();
    let total: f64 = (0..du).map(|i| s[i].max(0.0)).sum::<f64>().max(1e-30);
    // Eigenvalues come in nondecreasing order: the leading ones are at the end.
    let (mut picked, mut explained) = (Vec::new(), 0.0);
    for i in (0..du).rev() {
        if picked.len() >= 8 || explained >= 0.9 {
            break;
        }
        explained += s[i].max(0.0) / total;
        picked.push(i);
    }
    let mut weighted = 0.0;
    let mut weights = 0.0;
    for &i in &picked {
        let dir: Vec<f64> = (0..du).map(|k| u[(k, i)]).collect();
        let y = x
            .matmul(&Tensor::from_slice(&dir).view([d, 1]))
            .view([n, t]);
        weighted += s[i] * autocorr_time(&y);
        weights += s[i];
    }
    let pc_autocorr_time = if weights > 0.0 {
        weighted / weights
    } else {
        1.0
    };
    Ok(SlownessIndex {
        delta_ratio,
        pc_autocorr_time,
        components: picked.len(),
        explained,
    })
}

fn eigen_err(layer: usize, e: impl ToString) -> AnalysisError {
    AnalysisError::Eigen {
        layer,
        detail: e.to_string(),
    }
}

/// Integrated autocorrelation time of `y` `[N, T]` (one series per row, pooled over rows).
fn autocorr_time(y: &Tensor) -> f64 {
    let t = y.size()[1];
    let y = y - y.mean(Kind::Double);
    let var = y.square().mean(Kind::Double).double_value(&[]);
    if var <= 0.0 {
        return 1.0;
    }
    let mut tau = 1.0;
    for lag in 1..t / 2 {
        let rho = (y.narrow(1, lag, t - lag) * y.narrow(1, 0, t - lag))
            .mean(Kind::Double)
            .double_value(&[])
            / var;
        if rho <= 0.0 {
            break;
        }
        tau += 2.0 * rho;
    }
    tau
}

/// Everything a run is judged by, computed on held-out data from any model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AnalysisReport {
    /// mse, copy_last_mse, mean_frame_mse, mse_shuffled_actions, ...
    #[serde(flatten)]
    pub eval: EvalMetrics,
    /// Per layer, bottom first.
    pub slowness: Vec<LayerSlowness>,
    /// The paper's claim, top layer vs bottom layer, judged on the units' delta ratio (the
    /// quantity tau integrates); `None` with one layer or when slowness was not measured.
    pub top_slower_than_bottom: Option<bool>,
    /// The same comparison under each index, since they can disagree (R also follows the
    /// action's switches through the unit weights).
    pub top_slower_than_bottom_by: Option<SlownessComparison>,
    /// What figure.png shows; `None` if it could not be drawn (see `notes`).
    pub figure: Option<FigureInfo>,
    /// Parts that could not be computed, and why (the rest is still reported).
    pub notes: Vec<String>,
}

/// Is the top layer slower than the bottom one, per index (true = slower)?
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SlownessComparison {
    pub units_delta_ratio: bool,
    pub units_pc_autocorr_time: bool,
    pub r_delta_ratio: bool,
    pub r_pc_autocorr_time: bool,
}

/// Evaluates `model` on `held` (with the action shuffle), measures slowness on up to 64
/// sequences, and draws the strip of sequence `figure_sequence` at `frames` into `figure_path`.
/// Only the evaluation is fatal; a sequence too short for the slowness or the frames is noted.
pub fn analyse(
    model: &MtaPredNet,
    held: &Dataset,
    frames: &[usize],
    figure_sequence: i64,
    figure_path: &Path,
    seed: u64,
) -> Result<AnalysisReport, ModelError> {
    let eval = evaluate(model, held, 64, Some(seed))?;
    let mut notes = Vec::new();
    let slowness = slowness(model, held, 64, 5).unwrap_or_else(|e| {
        notes.push(format!("slowness not measured: {e}"));
        Vec::new()
    });
    let by = match (slowness.first(), slowness.last()) {
        (Some(b), Some(t)) if slowness.len() > 1 => Some(SlownessComparison {
            units_delta_ratio: t.units.delta_ratio < b.units.delta_ratio,
            units_pc_autocorr_time: t.units.pc_autocorr_time > b.units.pc_autocorr_time,
            r_delta_ratio: t.r.delta_ratio < b.r.delta_ratio,
            r_pc_autocorr_time: t.r.pc_autocorr_time > b.r.pc_autocorr_time,
        }),
        _ => None,
    };
    let seq = figure_sequence.clamp(0, held.len() - 1);
    let figure = match figure_strip(
        model,
        &held.images.get(seq),
        &held.actions.get(seq),
        frames,
        figure_path,
    ) {
        Ok(info) => {
            if !info.frames_missing.is_empty() {
                notes.push(format!(
                    "figure: frames {:?} do not exist in a {}-step sequence and were left out",
                    info.frames_missing,
                    held.steps()
                ));
            }
            Some(info)
        }
        Err(e) => {
            notes.push(format!("figure not drawn: {e}"));
            None
        }
    };
    Ok(AnalysisReport {
        eval,
        slowness,
        top_slower_than_bottom: by.as_ref().map(|c| c.units_delta_ratio),
        top_slower_than_bottom_by: by,
        figure,
        notes,
    })
}

/// Writes the default figure (first sequence of `data`) into `path`; convenience for callers
/// that have a data set rather than one sequence.
pub fn figure_from_dataset(
    model: &MtaPredNet,
    data: &Dataset,
    frames: &[usize],
    path: &Path,
) -> Result<FigureInfo, FigureError> {
    figure_strip(
        model,
        &data.images.get(0),
        &data.actions.get(0),
        frames,
        path,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn autocorr_time_orders_processes() {
        // AR(1) with coefficient phi has integrated time (1 + phi) / (1 - phi).
        let mut rng = 1u64;
        let mut noise = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let series = |phi: f64, noise: &mut dyn FnMut() -> f64| {
            let mut x = 0.0;
            let v: Vec<f64> = (0..4000)
                .map(|_| {
                    x = phi * x + noise();
                    x
                })
                .collect();
            Tensor::from_slice(&v).view([4, 1000])
        };
        let fast = autocorr_time(&series(0.0, &mut noise));
        let slow = autocorr_time(&series(0.8, &mut noise));
        assert!(fast < 1.5, "white noise: {fast}");
        assert!((slow - 9.0).abs() < 3.0, "AR(0.8) should be ~9: {slow}");
    }
}
