//! Expected free energy of a plan, as the planner scores it. The model is deterministic, so the
//! ambiguity term of expected free energy is left out and G is the risk plus prior preferences
//! over the car's own motion:
//!
//! G(plan) = mean_h risk(o_h) + progress(plan) + effort(plan) + smoothness(plan)
//!
//! - **risk**: precision-weighted distance of each imagined frame o_h to the preferred observation
//!   (see [`crate::preference`]): the Mahalanobis distance `d' P d / rows` of the rows' line
//!   positions from the preferred mean, with `P = (Cov + floor^2 I)^-1` (rows without the line
//!   are taken at the mean and cost instead), capped at and blended by the mean row visibility
//!   with the cost of a lost line `L` (that of the whole line shifted `lost_offset` half widths).
//!   It grows with lateral offset and heading error and is largest with the line out of view.
//! - **progress**: a prior preference for moving forward, `speed_weight * (relu(v* - v) / v*)^2`
//!   averaged over the segments (standing still costs `speed_weight`, as does spinning in place).
//! - **effort**: `turn_weight * (turn / max_turn)^2`, so spinning costs even where it sees well.
//! - **smoothness**: `smoothness * |a_h - a_{h-1}|^2 / max_turn^2` from the command in force.

use serde::{Deserialize, Serialize};

use crate::drive::Drive;
use crate::preference::{LineFeature, PreferredLine};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CostConfig {
    /// Preferred forward speed (mean wheel speed), rad/s.
    pub preferred_speed: f32,
    /// Cost of standing still, in units of a row's squared standard deviations of line position.
    pub speed_weight: f32,
    /// Cost of turning at `max_turn` for the whole plan.
    pub turn_weight: f32,
    /// Cost of a command change of `max_turn` between segments.
    pub smoothness: f32,
    /// Turn rate that normalises effort and smoothness, rad/s.
    pub max_turn: f32,
    /// A row without the line costs as much as a line this far off, in half image widths.
    pub lost_offset: f32,
    /// Standard deviation added to every row's preferred position (half widths), so a row seen
    /// at one position only is not infinitely precise.
    pub position_floor: f32,
    /// Weight of the later imagined frames relative to the first: frame h gets `discount^h`.
    pub discount: f32,
    /// The nearest image rows the risk looks at (0: all).
    pub rows: usize,
    /// Directions of the rows' positions the risk ignores: the centred frames' principal
    /// components, largest first. On the car the largest is the line's sideways swing in the
    /// near rows, which bends ahead make and the line sensors' reflex corrects step by step
    /// (`reflex.rs`); freed, the plans weigh the rest of the picture (on generated:101 with the
    /// oracle: 1.72 mm freed against 2.84 mm kept, most of it in bends of 5-7.5 1/m).
    pub free_modes: usize,
}

impl Default for CostConfig {
    fn default() -> Self {
        Self {
            preferred_speed: 8.0,
            speed_weight: 4.0,
            turn_weight: 0.5,
            smoothness: 0.5,
            max_turn: 8.0,
            lost_offset: 1.0,
            position_floor: 0.03,
            discount: 1.0,
            rows: 5,
            free_modes: 1,
        }
    }
}

/// faer parallelises through rayon's global pool by default, and the pool's threads inherit the
/// scheduling class of the thread that first uses it: the predictor's control loop, SCHED_FIFO.
/// Two rayon workers then ran (and spun for work) at the loop's own real-time priority, where
/// the loop could not preempt them; a 10-minute soak saw 4 commands dropped. An 8x8 eigen
/// decomposition has nothing to gain from threads: faer runs sequentially in every process that
/// plans, and no rayon pool is made.
fn sequential_faer() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| faer::set_global_parallelism(faer::Par::Seq));
}

/// The terms of G for one plan (lower is better).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Terms {
    pub risk: f32,
    pub progress: f32,
    pub effort: f32,
    pub smoothness: f32,
    pub total: f32,
}

/// G for plans, from a learnt preference and the prior weights.
#[derive(Debug, Clone)]
pub struct Cost {
    pub preferred: PreferredLine,
    pub cfg: CostConfig,
    /// Row-major precision of the rows' line positions, and the cost of a lost line.
    precision: Vec<f32>,
    lost: f32,
}

impl Cost {
    pub fn new(preferred: PreferredLine, cfg: CostConfig) -> Self {
        sequential_faer();
        let height = preferred.shape.height;
        let rows = Self::rows_of(&cfg, height);
        let first = height - rows;
        let floor = f64::from(cfg.position_floor).powi(2);
        let cov = faer::Mat::<f64>::from_fn(rows, rows, |i, j| {
            f64::from(preferred.position_cov[(first + i) * height + first + j])
                + if i == j { floor } else { 0.0 }
        });
        // Symmetric positive definite (a covariance plus floor^2 I): invert by eigenvalues.
        let precision = match cov.self_adjoint_eigen(faer::Side::Lower) {
            Ok(evd) => {
                let (s, u) = (evd.S().column_vector(), evd.U());
                // Eigenvalues ascend: the last `free_modes` are the largest.
                let kept = rows.saturating_sub(cfg.free_modes).max(1);
                (0..rows * rows)
                    .map(|ij| {
                        let (i, j) = (ij / rows, ij % rows);
                        (0..kept)
                            .map(|k| u[(i, k)] * u[(j, k)] / s[k].max(floor))
                            .sum::<f64>() as f32
                    })
                    .collect()
            }
            // Not expected for a floor > 0; fall back to the floor alone.
            Err(_) => (0..rows * rows)
                .map(|ij| {
                    if ij / rows == ij % rows {
                        (1.0 / floor) as f32
                    } else {
                        0.0
                    }
                })
                .collect(),
        };
        let mut cost = Self {
            preferred,
            cfg,
            precision,
            lost: 0.0,
        };
        let shift = vec![cost.cfg.lost_offset; rows];
        cost.lost = cost.mahalanobis(&shift);
        cost
    }

    fn rows_of(cfg: &CostConfig, height: usize) -> usize {
        if cfg.rows == 0 {
            height
        } else {
            cfg.rows.min(height)
        }
    }

    /// `d' P d / rows`.
    fn mahalanobis(&self, d: &[f32]) -> f32 {
        let rows = d.len();
        let mut sum = 0.0;
        for i in 0..rows {
            let row = &self.precision[i * rows..(i + 1) * rows];
            sum += d[i] * row.iter().zip(d).map(|(p, dj)| p * dj).sum::<f32>();
        }
        sum / rows as f32
    }

    /// The cost of a frame without the line (the most any frame costs).
    pub fn lost_cost(&self) -> f32 {
        self.lost
    }

    /// Risk of one frame: the Mahalanobis distance of its rows' line positions from the
    /// preferred ones, capped at and blended by visibility with the lost-line cost.
    pub fn risk(&self, frame: &[f32]) -> f32 {
        let p = &self.preferred;
        let feat = LineFeature::of(frame, p.shape, &p.contrast);
        let rows = Self::rows_of(&self.cfg, p.shape.height);
        let first = p.shape.height - rows;
        let mut d = vec![0.0; rows];
        let mut visible_sum = 0.0;
        for i in 0..rows {
            let r = first + i;
            // Fully visible with half the usual line mass (a line cut by the image edge or a
            // blurred prediction still counts); a row without the line sits at the mean.
            let visible = (feat.mass[r] / (0.5 * p.mass_mean[r]).max(0.25)).clamp(0.0, 1.0);
            d[i] = visible * (feat.position[r] - p.position_mean[r]);
            visible_sum += visible;
        }
        let visible = visible_sum / rows as f32;
        visible * self.mahalanobis(&d).min(self.lost) + (1.0 - visible) * self.lost
    }

    /// G of a plan whose imagined frames are `frames` (one per segment, concatenated), given the
    /// command in force before the plan (for smoothness).
    pub fn evaluate(&self, frames: &[f32], plan: &[Drive], before: Drive) -> Terms {
        let c = &self.cfg;
        let px = self.preferred.shape.pixels();
        let (mut risk, mut weights, mut w) = (0.0, 0.0, 1.0);
        for f in frames.chunks_exact(px) {
            risk += w * self.risk(f);
            weights += w;
            w *= c.discount;
        }
        let risk = if weights > 0.0 { risk / weights } else { 0.0 };
        let n = plan.len().max(1) as f32;
        let v_star = c.preferred_speed.max(1e-3);
        let progress = c.speed_weight
            * plan
                .iter()
                .map(|d| ((v_star - d.speed).max(0.0) / v_star).powi(2))
                .sum::<f32>()
            / n;
        let turn_scale = c.max_turn.max(1e-3);
        let effort = c.turn_weight
            * plan
                .iter()
                .map(|d| (d.turn / turn_scale).powi(2))
                .sum::<f32>()
            / n;
        let mut prev = before;
        let mut change = 0.0;
        for d in plan {
            change += (d.speed - prev.speed).powi(2) + (d.turn - prev.turn).powi(2);
            prev = *d;
        }
        let smoothness = c.smoothness * change / (turn_scale * turn_scale);
        Terms {
            risk,
            progress,
            effort,
            smoothness,
            total: risk + progress + effort + smoothness,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::preference::tests::{learnt, line_frame};

    /// Every mode and row weighed: the test preference varied only by a sideways shift, the
    /// mode the default frees (the reflex corrects it on the car).
    pub(crate) fn every_mode() -> CostConfig {
        CostConfig {
            free_modes: 0,
            ..CostConfig::default()
        }
    }

    #[test]
    fn risk_grows_with_offset_and_heading_and_is_worst_without_the_line() {
        let cost = Cost::new(learnt(), every_mode());
        let centred = cost.risk(&line_frame(6.0, 0.0));
        let mut last = centred;
        for off in [1.0, 2.0, 3.0, 4.0, 5.0] {
            let r = cost.risk(&line_frame(6.0 + off, 0.0));
            assert!(r > last, "offset {off}: {r} <= {last}");
            let l = cost.risk(&line_frame(6.0 - off, 0.0));
            assert!((l - r).abs() < 0.35 * r, "left and right alike: {l} vs {r}");
            last = r;
        }
        let lost = cost.risk(&[0.85; 96]);
        assert!(
            lost > last,
            "line out of view ({lost}) must cost most ({last})"
        );
        let mut last = centred;
        for slope in [0.3, 0.6, 0.9] {
            let r = cost.risk(&line_frame(6.0, slope));
            assert!(r > last, "heading {slope}: {r} <= {last}");
            last = r;
        }
    }

    #[test]
    fn the_default_frees_the_largest_mode_of_the_centred_frames() {
        // The centred frames varied by a sideways shift only: freed, an offset costs next to
        // nothing; kept, it costs.
        let off = line_frame(9.0, 0.0);
        let freed = Cost::new(learnt(), CostConfig::default()).risk(&off);
        let kept = Cost::new(learnt(), every_mode()).risk(&off);
        assert!(freed < 0.05 * kept, "freed {freed} vs kept {kept}");
        // A heading is another mode: still costed.
        let turned = Cost::new(learnt(), CostConfig::default()).risk(&line_frame(6.0, 0.9));
        assert!(turned > 3.0 * freed, "heading {turned} vs offset {freed}");
    }

    #[test]
    fn standing_still_and_spinning_cost() {
        let cost = Cost::new(learnt(), CostConfig::default());
        let f = line_frame(6.0, 0.0);
        let frames = [f.clone(), f].concat();
        let cruise = Drive::new(8.0, 0.0);
        let go = cost.evaluate(&frames, &[cruise; 2], cruise);
        let stop = cost.evaluate(&frames, &[Drive::STOP; 2], cruise);
        let spin = cost.evaluate(&frames, &[Drive::new(0.0, 8.0); 2], cruise);
        assert!(stop.total > go.total + 3.0, "{stop:?} vs {go:?}");
        assert!(spin.total > stop.total, "{spin:?} vs {stop:?}");
        assert_eq!(go.progress, 0.0);
        assert!(stop.smoothness > 0.0, "a sudden stop is a change");
    }
}
