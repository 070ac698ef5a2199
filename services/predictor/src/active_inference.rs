//! Wheel control by active inference through the world model: among candidate wheel commands,
//! pick the one whose imagined future frames are closest to the preferred observation (the view
//! when the car sits centred on the line), with a small prior for smooth commands. This is the
//! "risk" term of expected free energy under a Gaussian preference; the ambiguity term is left out
//! (the model is deterministic).

use serde::{Deserialize, Serialize};
use tch::{Kind, Tensor};

use mtanet_ipc::{IMAGE_HEIGHT, IMAGE_PIXELS, IMAGE_WIDTH, Observation};

use crate::world_model::WorldModel;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ActiveInferenceConfig {
    /// Off by default: measured, it does not drive yet. With a model at 0.21 x copy-last on
    /// held-out teacher data, one-step planning took the car off the oval within 3 s (the next
    /// frame barely depends on the command, and the measured wheel speed lags it); longer
    /// horizons cost 15-30 ms per step. Turn on to experiment; the reactive rule drives otherwise.
    pub enabled: bool,
    /// Forward speeds of the candidates, rad/s.
    pub speeds: Vec<f32>,
    /// Turn rates of the candidates (right wheel minus left over two), rad/s.
    pub turns: Vec<f32>,
    /// Imagined steps per candidate (each 0.02 s). Longer horizons separate the candidates better
    /// but cost a batched model step each (benches/policy.rs: K=15 x 3 steps ~33 ms, far over the
    /// 10 ms a realtime step may wait); 1 fits.
    pub horizon: usize,
    /// Weight of the change from the previous command (per (rad/s)^2), against image error.
    pub smoothness: f32,
    /// Trust the model only when its next-frame error is below this x copy-last-frame error...
    pub trust_ratio: f64,
    /// ...over at least this many steps since the weights were loaded.
    pub trust_after_steps: u64,
    /// Frames averaged into the preferred observation before it is used.
    pub preference_frames: u64,
}

impl Default for ActiveInferenceConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            speeds: vec![5.0, 8.0, 11.0],
            turns: vec![-6.0, -3.0, 0.0, 3.0, 6.0],
            horizon: 1,
            smoothness: 0.002,
            trust_ratio: 0.7,
            trust_after_steps: 50,
            preference_frames: 50,
        }
    }
}

/// The preferred observation: the running mean of frames seen while only the middle line sensor
/// is on (the car centred on the line). Learnt from the car's own sensors, no ground truth.
#[derive(Debug, Clone)]
pub struct Preference {
    sum: Vec<f64>,
    count: u64,
}

impl Default for Preference {
    fn default() -> Self {
        Self {
            sum: vec![0.0; IMAGE_PIXELS],
            count: 0,
        }
    }
}

impl Preference {
    pub fn observe(&mut self, obs: &Observation) {
        if obs.line_sensors == [0, 1, 0] {
            for (s, p) in self.sum.iter_mut().zip(obs.image) {
                *s += f64::from(p);
            }
            self.count += 1;
        }
    }

    pub fn count(&self) -> u64 {
        self.count
    }

    /// `[1, 1, H, W]` mean frame, once `min` frames were seen.
    pub fn image(&self, min: u64) -> Option<Tensor> {
        (self.count >= min.max(1)).then(|| {
            let mean: Vec<f32> = self
                .sum
                .iter()
                .map(|s| (s / self.count as f64) as f32)
                .collect();
            Tensor::from_slice(&mean).view([1, 1, IMAGE_HEIGHT as i64, IMAGE_WIDTH as i64])
        })
    }
}

/// Candidate wheel commands `[K, 2]` (left, right) from the speed x turn grid.
pub fn candidates(cfg: &ActiveInferenceConfig) -> Vec<[f32; 2]> {
    cfg.speeds
        .iter()
        .flat_map(|&v| cfg.turns.iter().map(move |&w| [v - w, v + w]))
        .collect()
}

/// Expected cost of each candidate: mean squared distance of the imagined frames to the preferred
/// one over the horizon, plus the smoothness prior. Returns the best command and its cost.
pub fn choose(
    world: &WorldModel,
    cands: &[[f32; 2]],
    preferred: &Tensor,
    previous: [f32; 2],
    cfg: &ActiveInferenceConfig,
) -> Result<([f32; 2], f64), mtanet_models::ModelError> {
    let _guard = tch::no_grad_guard();
    let k = cands.len() as i64;
    let flat: Vec<f32> = cands.iter().flatten().copied().collect();
    let actions = Tensor::from_slice(&flat).view([k, 2]);
    let model = world.model();
    let horizon = cfg.horizon.max(1);
    // The first prediction runs from the batch-1 state, where the model shares the
    // action-independent work across candidates; later ones need one state per candidate.
    let mut state = world.state().shallow_clone();
    let mut risk = Tensor::zeros([k], (Kind::Float, tch::Device::Cpu));
    for h in 0..horizon {
        // Imagine: predict the next frame under each action, then take it as if observed.
        let predicted = model.f_predict_candidates(&state, &actions)?;
        risk +=
            (&predicted - preferred)
                .square()
                .mean_dim([1i64, 2, 3].as_slice(), false, Kind::Float);
        if h + 1 < horizon {
            let current = if h == 0 { state.expand(k) } else { state };
            state = model.f_step(&current, &predicted, &actions)?.0;
        }
    }
    let prev = Tensor::from_slice(&previous).view([1, 2]);
    let change = (&actions - prev)
        .square()
        .sum_dim_intlist([1i64].as_slice(), false, Kind::Float);
    let cost = risk / horizon as f64 + change * f64::from(cfg.smoothness);
    let best = cost.argmin(0, false).int64_value(&[]) as usize;
    Ok((cands[best], cost.double_value(&[best as i64])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preference_averages_only_centred_frames() {
        let mut p = Preference::default();
        let mut o: Observation = bytemuck::Zeroable::zeroed();
        o.image = [1.0; IMAGE_PIXELS];
        o.line_sensors = [1, 1, 0];
        p.observe(&o);
        assert_eq!(p.count(), 0);
        assert!(p.image(1).is_none());
        o.line_sensors = [0, 1, 0];
        p.observe(&o);
        o.image = [0.0; IMAGE_PIXELS];
        p.observe(&o);
        let img = p.image(2).unwrap();
        assert_eq!(img.size(), vec![1, 1, 8, 12]);
        assert!((img.mean(Kind::Float).double_value(&[]) - 0.5).abs() < 1e-6);
    }

    #[test]
    fn candidate_grid_is_speed_by_turn() {
        let cfg = ActiveInferenceConfig {
            speeds: vec![8.0],
            turns: vec![-2.0, 0.0, 2.0],
            ..Default::default()
        };
        assert_eq!(candidates(&cfg), vec![[10.0, 6.0], [8.0, 8.0], [6.0, 10.0]]);
    }
}
