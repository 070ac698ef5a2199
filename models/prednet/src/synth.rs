//! Synthetic action-conditioned data set: a Gaussian dot whose motion is the action.
//!
//! Like the reference's moving dot, except that a(t) = (vx, vy) in [-1, 1]^2 (a stand-in for the
//! two wheel velocities) *is* the displacement from frame t-1 to frame t, times `speed` pixels.
//! Actions persist and change at random, so neither copying the last frame nor continuing the
//! last motion predicts well: only a model that reads a(t) can.

use crate::data::Dataset;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use tch::Tensor;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SynthConfig {
    pub sequences: i64,
    /// Steps per sequence. 150 covers the figure's default frames (1 .. 130).
    pub steps: i64,
    pub height: i64,
    pub width: i64,
    pub seed: u64,
    /// Dot radius (Gaussian sigma) in pixels.
    pub sigma: f64,
    /// Pixels moved per step at |a| = 1.
    pub speed: f64,
    /// Probability per step that a new action is drawn; otherwise the last one is kept.
    pub change_prob: f64,
}

impl Default for SynthConfig {
    fn default() -> Self {
        Self {
            sequences: 256,
            steps: 150,
            height: 8,
            width: 12,
            seed: 0,
            sigma: 1.0,
            speed: 1.0,
            change_prob: 0.3,
        }
    }
}

/// A synthetic configuration that cannot produce data.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// A size or rate is out of range.
    #[error("synth: `{key}` = {value} {why}")]
    OutOfRange {
        key: &'static str,
        value: f64,
        why: &'static str,
    },
}

/// Generates the data set (deterministic for a given config, seed included).
pub fn generate(cfg: &SynthConfig) -> Result<Dataset, SynthError> {
    let bad = |key, value: f64, why| Err(SynthError::OutOfRange { key, value, why });
    if cfg.sequences < 1 || cfg.steps < 2 {
        return bad(
            "sequences/steps",
            cfg.sequences.min(cfg.steps) as f64,
            "must be >= 1 / >= 2",
        );
    }
    if cfg.height < 3 || cfg.width < 3 {
        return bad(
            "height/width",
            cfg.height.min(cfg.width) as f64,
            "must be >= 3",
        );
    }
    if !(cfg.sigma > 0.0 && cfg.speed >= 0.0 && (0.0..=1.0).contains(&cfg.change_prob)) {
        return bad(
            "sigma/speed/change_prob",
            cfg.sigma,
            "need sigma > 0, speed >= 0, 0 <= change_prob <= 1",
        );
    }
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let (n, t, h, w) = (
        cfg.sequences as usize,
        cfg.steps as usize,
        cfg.height as usize,
        cfg.width as usize,
    );
    let mut images = vec![0f32; n * t * h * w];
    let mut actions = vec![0f32; n * t * 2];
    // Keep the dot's centre half a pixel inside the frame so it is always fully informative.
    let lim = [(0.5, h as f64 - 1.5), (0.5, w as f64 - 1.5)];
    for s in 0..n {
        let mut pos = [
            rng.random_range(lim[0].0..lim[0].1),
            rng.random_range(lim[1].0..lim[1].1),
        ];
        let mut a = [0f64; 2];
        for step in 0..t {
            if step == 0 || rng.random_bool(cfg.change_prob) {
                a = [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)];
            }
            // At a wall the action component is reversed (and recorded reversed), so the motion
            // is still exactly the recorded action.
            for axis in 0..2 {
                let next = pos[axis] + cfg.speed * a[axis];
                if next < lim[axis].0 || next > lim[axis].1 {
                    a[axis] = -a[axis];
                }
                pos[axis] = (pos[axis] + cfg.speed * a[axis]).clamp(lim[axis].0, lim[axis].1);
            }
            // a = (vx, vy): column motion first, like (left, right) wheels map to a heading.
            actions[(s * t + step) * 2] = a[1] as f32;
            actions[(s * t + step) * 2 + 1] = a[0] as f32;
            let frame = &mut images[(s * t + step) * h * w..][..h * w];
            render(frame, h, w, pos, cfg.sigma);
        }
    }
    let images =
        Tensor::from_slice(&images).view([cfg.sequences, cfg.steps, cfg.height, cfg.width]);
    let actions = Tensor::from_slice(&actions).view([cfg.sequences, cfg.steps, 2]);
    Ok(Dataset::new(images, actions).expect("the generator writes valid data"))
}

fn render(frame: &mut [f32], h: usize, w: usize, pos: [f64; 2], sigma: f64) {
    let k = -0.5 / (sigma * sigma);
    for y in 0..h {
        for x in 0..w {
            let d2 = (y as f64 - pos[0]).powi(2) + (x as f64 - pos[1]).powi(2);
            frame[y * w + x] = (d2 * k).exp() as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tch::Kind;

    /// Intensity-weighted centre of each frame, `[N, T, 2]` as (row, col).
    fn centroids(images: &Tensor) -> Tensor {
        let s = images.size();
        let ys = Tensor::arange(s[2], (Kind::Float, images.device())).view([1, 1, -1, 1]);
        let xs = Tensor::arange(s[3], (Kind::Float, images.device())).view([1, 1, 1, -1]);
        let mass = images.sum_dim_intlist([2, 3].as_slice(), false, Kind::Float);
        let cy = (images * ys).sum_dim_intlist([2, 3].as_slice(), false, Kind::Float) / &mass;
        let cx = (images * xs).sum_dim_intlist([2, 3].as_slice(), false, Kind::Float) / &mass;
        Tensor::stack(&[cy, cx], 2)
    }

    #[test]
    fn motion_follows_the_action_and_is_seeded() {
        let cfg = SynthConfig {
            sequences: 4,
            steps: 30,
            sigma: 0.7,
            ..Default::default()
        };
        let d = generate(&cfg).unwrap();
        assert_eq!(d.images.size(), [4, 30, 8, 12]);
        assert!(
            d.images.equal(&generate(&cfg).unwrap().images),
            "same seed, same data"
        );
        let other = generate(&SynthConfig {
            seed: 1,
            ..cfg.clone()
        })
        .unwrap();
        assert!(!d.images.equal(&other.images));
        // The centroid's displacement from t-1 to t is the action (x, y), up to the blob being
        // clipped by the border (a few hundredths of a pixel at sigma 0.7, half a pixel in).
        let c = centroids(&d.images);
        let moved = c.narrow(1, 1, 29) - c.narrow(1, 0, 29); // (dy, dx)
        let a = d.actions.narrow(1, 1, 29);
        let expect = Tensor::stack(&[a.select(2, 1), a.select(2, 0)], 2);
        let err = (moved - expect).abs().max().double_value(&[]);
        assert!(
            err < 0.15,
            "centroid motion differs from the action by {err}"
        );
        let mean_speed = d.actions.abs().mean(Kind::Float).double_value(&[]);
        assert!(mean_speed > 0.3, "actions must move the dot: {mean_speed}");
    }
}
