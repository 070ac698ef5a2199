//! Everything a run is judged by on held-out data, from any model: the evaluation, the layers'
//! timescales and the figure strip (`mta train`, `mta figures`).

use std::path::Path;

use mtanet_models::analysis::{LayerTimescales, timescales};
use mtanet_models::data::Dataset;
use mtanet_models::eval::{EvalMetrics, evaluate};
use mtanet_models::{ModelError, MtaPredNet};
use serde::{Deserialize, Serialize};

use super::figure::{FigureError, FigureInfo, figure_strip};

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
