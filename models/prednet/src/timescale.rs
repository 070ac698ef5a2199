//! How slowly a signal forgets: the e-folding time of its autocorrelation.
//!
//! The signal is a `[T, D]` series (T model steps of D features: a layer's channels x positions),
//! or `[N, T, D]`: N sequences of it (held-out data), whose lags never cross from one sequence
//! into the next. Each feature is standardised over all steps, the autocorrelation at lag k is
//! averaged over features and time, and the e-folding time is the lag at which it first falls
//! below 1/e (linear between the two lags around the crossing). An AR(1) process
//! x(t) = phi x(t-1) + noise has autocorrelation phi^k, so its e-folding time is -1/ln(phi)
//! steps: the time constant a leaky unit of tau steps would have if it only integrated noise.
//!
//! The interval is a block bootstrap: each sequence is cut into blocks much longer than the
//! timescale, blocks are resampled with replacement, and the autocorrelation is recomputed from
//! the resampled blocks' lag sums. Resampling features instead would pretend neighbouring
//! channels are independent; resampling single steps would break the very correlation measured.

use mtanet_summaries::quantile;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use tch::{Kind, Tensor};

/// How the estimate is made.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TimescaleOptions {
    /// Longest lag considered (steps); a signal still above 1/e there has no estimate.
    pub max_lag: usize,
    /// Block length of the bootstrap (steps): several times the longest timescale expected. A
    /// sequence shorter than this is one block.
    pub block: usize,
    /// Bootstrap resamples.
    pub resamples: usize,
    pub seed: u64,
}

impl Default for TimescaleOptions {
    fn default() -> Self {
        Self {
            max_lag: 100,
            block: 200,
            resamples: 400,
            seed: 0,
        }
    }
}

/// One signal's timescale, in model steps.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Timescale {
    /// E-folding time (steps); `None`: the autocorrelation stays above 1/e up to `max_lag`, or
    /// the signal does not vary.
    pub steps: Option<f64>,
    /// 95% block-bootstrap interval (2.5th and 97.5th percentiles, steps); resamples with no
    /// crossing count as `max_lag`.
    pub interval: Option<[f64; 2]>,
    /// Features that vary (a dead ReLU channel is constant and left out) of all.
    pub features_used: usize,
    pub features: usize,
    /// The mean autocorrelation at lags 0..=max_lag, for plots.
    pub autocorrelation: Vec<f64>,
}

/// Timescale of `x`: `[T, D]` (one series) or `[N, T, D]` (N sequences of T steps).
pub fn timescale(x: &Tensor, o: &TimescaleOptions) -> Timescale {
    let x = match x.dim() {
        2 => x.unsqueeze(0),
        _ => x.shallow_clone(),
    };
    let (t, d) = (x.size()[1], x.size()[2]);
    let x = x.to_kind(Kind::Double);
    let mean = x.mean_dim([0i64, 1].as_slice(), true, Kind::Double);
    let std = x.flatten(0, 1).std_dim([0i64].as_slice(), false, true);
    let varies: Vec<bool> = Vec::<f64>::try_from(std.flatten(0, -1))
        .unwrap_or_default()
        .iter()
        .map(|s| *s > 1e-9)
        .collect();
    let used: Vec<i64> = (0..d).filter(|i| varies[*i as usize]).collect();
    let max_lag = o.max_lag.min((t as usize).saturating_sub(2) / 2);
    let empty = Timescale {
        steps: None,
        interval: None,
        features_used: used.len(),
        features: d as usize,
        autocorrelation: Vec::new(),
    };
    if used.is_empty() || max_lag < 2 {
        return empty;
    }
    let idx = Tensor::from_slice(&used);
    let z = ((x - mean) / std.clamp_min(1e-12)).index_select(2, &idx);
    let sums = LagSums::of(&z, max_lag, o.block.max(max_lag + 1));
    let acf = sums.autocorrelation(&(0..sums.blocks).collect::<Vec<_>>());
    let steps = e_folding(&acf);
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed);
    let mut boot: Vec<f64> = (0..o.resamples)
        .map(|_| {
            let pick: Vec<usize> = (0..sums.blocks)
                .map(|_| rng.random_range(0..sums.blocks))
                .collect();
            e_folding(&sums.autocorrelation(&pick)).unwrap_or(max_lag as f64)
        })
        .collect();
    boot.sort_by(f64::total_cmp);
    let interval = match (quantile(&boot, 0.025), quantile(&boot, 0.975)) {
        (Some(lo), Some(hi)) if sums.blocks >= 2 => Some([lo, hi]),
        _ => None,
    };
    Timescale {
        steps,
        interval,
        autocorrelation: acf,
        ..empty
    }
}

/// The first lag where `acf` falls below 1/e, linear between the lags around it.
pub fn e_folding(acf: &[f64]) -> Option<f64> {
    let target = (-1.0f64).exp();
    let k = acf.iter().position(|a| *a < target)?;
    if k == 0 {
        return Some(0.0);
    }
    let (a, b) = (acf[k - 1], acf[k]);
    Some((k - 1) as f64 + (a - target) / (a - b))
}

/// Per block b and lag k: the sum over t in b of mean_features z(t) z(t+k), and how many t.
/// Blocks are numbered sequence by sequence; a lag never reaches past its sequence's end.
struct LagSums {
    blocks: usize,
    sums: Vec<Vec<f64>>,
    counts: Vec<Vec<f64>>,
}

impl LagSums {
    fn of(z: &Tensor, max_lag: usize, block: usize) -> Self {
        let (n, t) = (z.size()[0] as usize, z.size()[1] as usize);
        let per_seq = t.div_ceil(block);
        let blocks = n * per_seq;
        let mut sums = vec![vec![0.0; max_lag + 1]; blocks];
        let mut counts = vec![vec![0.0; max_lag + 1]; blocks];
        for k in 0..=max_lag {
            let len = (t - k) as i64;
            let prod = (z.narrow(1, 0, len) * z.narrow(1, k as i64, len)).mean_dim(
                [2i64].as_slice(),
                false,
                Kind::Double,
            );
            let prod = Vec::<f64>::try_from(prod.flatten(0, -1)).unwrap_or_default();
            for (i, p) in prod.iter().enumerate() {
                let b = (i / len as usize) * per_seq + (i % len as usize) / block;
                sums[b][k] += p;
                counts[b][k] += 1.0;
            }
        }
        Self {
            blocks,
            sums,
            counts,
        }
    }

    /// The autocorrelation over the picked blocks (repeats allowed), normalised at lag 0.
    fn autocorrelation(&self, picked: &[usize]) -> Vec<f64> {
        let lags = self.sums.first().map_or(0, Vec::len);
        let raw: Vec<f64> = (0..lags)
            .map(|k| {
                let s: f64 = picked.iter().map(|b| self.sums[*b][k]).sum();
                let n: f64 = picked.iter().map(|b| self.counts[*b][k]).sum();
                if n > 0.0 { s / n } else { f64::NAN }
            })
            .collect();
        let zero = raw.first().copied().unwrap_or(1.0);
        raw.iter().map(|r| r / zero).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `d` independent AR(1) series of `t` steps with e-folding time `tau` steps.
    fn ar1(t: usize, d: usize, tau: f64, seed: u64) -> Tensor {
        let phi = (-1.0 / tau).exp();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut x = vec![0.0f64; t * d];
        for j in 0..d {
            let mut v = 0.0;
            for i in 0..t {
                // Uniform noise is enough: the autocorrelation of AR(1) does not depend on it.
                v = phi * v + rng.random_range(-1.0..1.0);
                x[i * d + j] = v;
            }
        }
        Tensor::from_slice(&x).view([t as i64, d as i64])
    }

    #[test]
    fn recovers_the_time_constant_of_ar1_to_ten_percent() {
        for tau in [2.0, 5.0, 14.0] {
            let got = timescale(&ar1(4000, 32, tau, 7), &TimescaleOptions::default());
            let steps = got.steps.expect("a crossing");
            assert!((steps / tau - 1.0).abs() < 0.1, "tau {tau}: {steps}");
            let [lo, hi] = got.interval.expect("an interval");
            assert!(
                lo <= steps && steps <= hi && hi - lo < tau,
                "{lo} {steps} {hi}"
            );
            assert_eq!(got.features_used, 32);
        }
    }

    #[test]
    fn a_slower_signal_has_the_longer_timescale_and_constant_features_are_left_out() {
        let fast = timescale(&ar1(3000, 8, 3.0, 1), &TimescaleOptions::default());
        let slow = ar1(3000, 8, 9.0, 2);
        let with_dead = Tensor::cat(&[slow, Tensor::zeros([3000, 4], tch::kind::FLOAT_CPU)], 1);
        let slow = timescale(&with_dead, &TimescaleOptions::default());
        assert!(slow.steps.unwrap() > 2.0 * fast.steps.unwrap());
        assert_eq!((slow.features_used, slow.features), (8, 12));
    }

    #[test]
    fn sequences_each_one_block_recover_the_time_constant() {
        // Held-out data: 40 short sequences of tau 4, lags up to (60 - 2) / 2 within each.
        let seqs = ar1(2400, 16, 4.0, 5).view([40, 60, 16]);
        let got = timescale(&seqs, &TimescaleOptions::default());
        let steps = got.steps.expect("a crossing");
        assert!((steps / 4.0 - 1.0).abs() < 0.15, "{steps}");
        let [lo, hi] = got.interval.expect("an interval: one block per sequence");
        assert!(lo <= steps && steps <= hi, "{lo} {steps} {hi}");
        assert_eq!(got.autocorrelation.len(), 30);
    }

    #[test]
    fn white_noise_forgets_at_once_and_a_constant_has_no_timescale() {
        let noise = timescale(&ar1(3000, 8, 1e-9, 3), &TimescaleOptions::default());
        assert!(noise.steps.unwrap() < 1.0);
        let flat = timescale(
            &Tensor::ones([500, 3], tch::kind::DOUBLE_CPU),
            &Default::default(),
        );
        assert_eq!((flat.steps, flat.features_used), (None, 0));
    }
}
