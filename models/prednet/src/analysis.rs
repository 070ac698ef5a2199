//! The paper's claims, measured on any run: per-layer timescales of R_l(t) and of the units'
//! states on held-out data, and the figure strip. (`mta analyze` measures the same on a drive,
//! with the context read-outs.)

use crate::data::Dataset;
use crate::eval::{EvalMetrics, evaluate};
use crate::model::{ModelError, MtaPredNet};
use serde::{Deserialize, Serialize};
use std::path::Path;
use tch::Tensor;

use crate::timescale::{Timescale, TimescaleOptions, timescale};

pub use crate::figure::{FigureError, FigureInfo, figure_strip};

/// How slowly one layer forgets, measured on two signals: R_l(t), the action-weighted output
/// (what the layer below and Xhat see), and each generative unit's own state h^d_l(t) (what tau
/// integrates). R also moves whenever the action changes the unit weights, so the two can
/// disagree.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerTimescales {
    pub layer: usize,
    pub tau: f64,
    /// R_l(t), the action-weighted mix of the units.
    pub r: Timescale,
    /// Each generative unit's own output h^d_l(t) (its leaky state), unit 0 first.
    pub units: Vec<Timescale>,
}

impl LayerTimescales {
    /// The units' mean e-folding time (steps); `None` if any unit has none.
    pub fn units_steps(&self) -> Option<f64> {
        let s: Vec<f64> = self.units.iter().map(|u| u.steps).collect::<Option<_>>()?;
        (!s.is_empty()).then(|| s.iter().sum::<f64>() / s.len() as f64)
    }
}

/// Why an analysis could not be computed.
#[derive(Debug, thiserror::Error)]
pub enum AnalysisError {
    /// The data does not fit the model.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// Too few steps after the transient to measure anything.
    #[error("need more than {skip} + 5 steps per sequence, have {steps}")]
    TooShort { skip: i64, steps: i64 },
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

/// Per layer: the timescales of R_l and of every unit's h, from [`collect_states`]'s output cut
/// to the steps measured (`[N, T, ..]` each).
pub fn layer_timescales(
    model: &MtaPredNet,
    states: &[(Tensor, Tensor)],
    o: &TimescaleOptions,
) -> Vec<LayerTimescales> {
    let cfg = model.config();
    (states.iter().enumerate())
        .map(|(l, (r, h))| {
            let (n, t) = (h.size()[0], h.size()[1]);
            let per_unit = h.view([n, t, cfg.gus[l], -1]);
            LayerTimescales {
                layer: l,
                tau: cfg.tau[l],
                r: timescale(r, o),
                units: (0..cfg.gus[l])
                    .map(|d| timescale(&per_unit.select(2, d), o))
                    .collect(),
            }
        })
        .collect()
}

/// Timescales of every layer over up to `max_sequences` sequences of `data`, after dropping the
/// first `skip` steps of each (the transient from the zero state). Each sequence is its own
/// bootstrap block.
pub fn timescales(
    model: &MtaPredNet,
    data: &Dataset,
    max_sequences: i64,
    skip: i64,
) -> Result<Vec<LayerTimescales>, AnalysisError> {
    if data.steps() <= skip + 5 {
        return Err(AnalysisError::TooShort {
            skip,
            steps: data.steps(),
        });
    }
    let states = collect_states(model, data, max_sequences)?;
    let cut = |x: &Tensor| x.narrow(1, skip, x.size()[1] - skip);
    let states: Vec<_> = states.iter().map(|(r, h)| (cut(r), cut(h))).collect();
    Ok(layer_timescales(
        model,
        &states,
        &TimescaleOptions::default(),
    ))
}

/// Everything a run is judged by, computed on held-out data from any model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AnalysisReport {
    /// mse, copy_last_mse, mean_frame_mse, mse_shuffled_actions, ...
    #[serde(flatten)]
    pub eval: EvalMetrics,
    /// Per layer, bottom first: e-folding times in model steps (`timescale.rs`).
    pub timescales: Vec<LayerTimescales>,
    /// The paper's claim, top layer vs bottom layer, judged on the units' mean e-folding time
    /// (the state tau integrates); `None` with one layer or when it was not measured.
    pub top_slower_than_bottom: Option<bool>,
    /// The same judged on R_l (which also follows the action's switches through the unit
    /// weights, so it can disagree).
    pub top_r_slower_than_bottom: Option<bool>,
    /// What figure.png shows; `None` if it could not be drawn (see `notes`).
    pub figure: Option<FigureInfo>,
    /// Parts that could not be computed, and why (the rest is still reported).
    pub notes: Vec<String>,
}

/// Evaluates `model` on `held` (with the action shuffle), measures the layers' timescales on up
/// to 64 sequences, and draws the strip of sequence `figure_sequence` at `frames` into `figure_path`.
/// Only the evaluation is fatal; a sequence too short for the timescales or the frames is noted.
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
    let timescales = timescales(model, held, 64, 5).unwrap_or_else(|e| {
        notes.push(format!("timescales not measured: {e}"));
        Vec::new()
    });
    let slower = |of: &dyn Fn(&LayerTimescales) -> Option<f64>| match timescales.as_slice() {
        [b, .., t] => Some(of(t)? > of(b)?),
        _ => None,
    };
    let top_slower_than_bottom = slower(&LayerTimescales::units_steps);
    let top_r_slower_than_bottom = slower(&|l| l.r.steps);
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
        timescales,
        top_slower_than_bottom,
        top_r_slower_than_bottom,
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
