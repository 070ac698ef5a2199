//! The paper's claim, measured on any run: per-layer timescales of R_l(t) and of the units'
//! states on held-out data. (`mta analyze` measures the same on a drive, with the context
//! read-outs, and draws the figure strip.)

use crate::data::Dataset;
use crate::model::{ModelError, MtaPredNet};
use serde::{Deserialize, Serialize};
use tch::Tensor;

use crate::timescale::{Timescale, TimescaleOptions, timescale};

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
