//! Linear read-outs, cross-validated the way time series must be: what a linear map from a
//! state can say about a target on stretches of the drive it was not fitted on.
//!
//! Ridge regression on standardised features. Samples are grouped (laps of the drive); each of
//! K folds holds every K-th group, and training drops the `gap` steps on either side of every
//! test sample, so a test lap is never predicted from the frames right next to it. The ridge
//! penalty is chosen per target inside the training folds only (leave one training fold out),
//! from a grid scaled with the number of training samples. R^2 pools the out-of-fold predictions
//! of all folds: 1 - sum (y - yhat)^2 / sum (y - mean y)^2; it is negative when the read-out does
//! worse than predicting the mean.

use serde::{Deserialize, Serialize};
use tch::{Kind, Tensor};

/// Penalties tried, times the number of training samples (features are standardised, so X'X is
/// about n times their correlation matrix).
const LAMBDAS: [f64; 9] = [1e-4, 1e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0, 10.0, 100.0];

/// Which fold each sample is tested in.
#[derive(Debug, Clone, PartialEq)]
pub struct Folds {
    pub fold: Vec<usize>,
    pub k: usize,
    /// Steps dropped from training on either side of a test sample.
    pub gap: usize,
}

impl Folds {
    /// Group g (a lap, numbered in drive order) goes to fold g mod k; `None` when there are
    /// fewer than `k` groups.
    pub fn by_group(groups: &[u32], k: usize, gap: usize) -> Option<Self> {
        let distinct = groups.iter().max().map_or(0, |m| *m as usize + 1);
        (k >= 2 && distinct >= k).then(|| Self {
            fold: groups.iter().map(|g| *g as usize % k).collect(),
            k,
            gap,
        })
    }

    /// Samples usable to train for testing on the folds in `test` (of those in `pool`).
    fn train_mask(&self, pool: &[bool], test: &[usize]) -> Vec<bool> {
        let n = self.fold.len();
        // Distance to the nearest test sample, both ways.
        let mut near = vec![usize::MAX; n];
        let mut last = None;
        for i in 0..n {
            if test.contains(&self.fold[i]) {
                last = Some(i);
            }
            if let Some(l) = last {
                near[i] = i - l;
            }
        }
        last = None;
        for i in (0..n).rev() {
            if test.contains(&self.fold[i]) {
                last = Some(i);
            }
            if let Some(l) = last {
                near[i] = near[i].min(l - i);
            }
        }
        (0..n).map(|i| pool[i] && near[i] > self.gap).collect()
    }
}

/// One target's read-out.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Readout {
    /// Pooled out-of-fold R^2.
    pub r2: f64,
    /// Each fold's own R^2 (its test samples, against their mean).
    pub fold_r2: Vec<f64>,
    /// The penalty chosen in each fold (times its training samples).
    pub lambda: Vec<f64>,
}

/// Cross-validated ridge read-outs of every column of `y` `[N, M]` from `x` `[N, D]`.
pub fn ridge_cv(x: &Tensor, y: &Tensor, folds: &Folds) -> Vec<Readout> {
    let (n, m) = (x.size()[0], y.size()[1]);
    assert_eq!(folds.fold.len() as i64, n, "one fold per sample");
    let x = x.to_kind(Kind::Double);
    let y = y.to_kind(Kind::Double);
    let all = vec![true; n as usize];
    let pred = Tensor::zeros([n, m], (Kind::Double, tch::Device::Cpu));
    let mut lambda = vec![Vec::new(); m as usize];
    for k in 0..folds.k {
        let train = folds.train_mask(&all, &[k]);
        // The penalty per target, from the training folds alone.
        let mut sse = vec![vec![0.0; LAMBDAS.len()]; m as usize];
        for j in (0..folds.k).filter(|j| *j != k) {
            let inner = folds.train_mask(&train, &[j]);
            let val: Vec<bool> = (0..n as usize).map(|i| folds.fold[i] == j).collect();
            let fit = Fit::new(&x, &y, &inner);
            for (li, l) in LAMBDAS.iter().enumerate() {
                let err = (fit.predict(&x, &val, *l) - rows(&y, &val))
                    .square()
                    .sum_dim_intlist([0i64].as_slice(), false, Kind::Double);
                for (t, e) in Vec::<f64>::try_from(err).unwrap().iter().enumerate() {
                    sse[t][li] += e;
                }
            }
        }
        let best: Vec<f64> = sse
            .iter()
            .map(|s| {
                let i = (0..s.len()).min_by(|a, b| s[*a].total_cmp(&s[*b])).unwrap();
                LAMBDAS[i]
            })
            .collect();
        let test: Vec<bool> = (0..n as usize).map(|i| folds.fold[i] == k).collect();
        let fit = Fit::new(&x, &y, &train);
        let idx = index(&test);
        for (t, l) in best.iter().enumerate() {
            let p = fit.predict(&x, &test, *l).select(1, t as i64);
            let _ = pred.select(1, t as i64).index_copy_(0, &idx, &p);
            lambda[t].push(*l);
        }
    }
    (0..m)
        .map(|t| {
            let (yt, pt) = (y.select(1, t), pred.select(1, t));
            let fold_r2 = (0..folds.k)
                .map(|k| {
                    let test: Vec<bool> = folds.fold.iter().map(|f| *f == k).collect();
                    let i = index(&test);
                    r2(&yt.index_select(0, &i), &pt.index_select(0, &i))
                })
                .collect();
            Readout {
                r2: r2(&yt, &pt),
                fold_r2,
                lambda: lambda[t as usize].clone(),
            }
        })
        .collect()
}

/// 1 - SSE / SST.
pub fn r2(y: &Tensor, pred: &Tensor) -> f64 {
    let sst = (y - y.mean(Kind::Double))
        .square()
        .sum(Kind::Double)
        .double_value(&[]);
    let sse = (y - pred).square().sum(Kind::Double).double_value(&[]);
    if sst > 0.0 { 1.0 - sse / sst } else { f64::NAN }
}

fn index(mask: &[bool]) -> Tensor {
    let i: Vec<i64> = (0..mask.len() as i64)
        .filter(|i| mask[*i as usize])
        .collect();
    Tensor::from_slice(&i)
}

fn rows(t: &Tensor, mask: &[bool]) -> Tensor {
    t.index_select(0, &index(mask))
}

/// Ridge fitted on some rows for every penalty at once: X'X = V S V' once, then
/// w(lambda) = V (S + lambda n)^-1 V' X'y.
struct Fit {
    mean: Tensor,
    std: Tensor,
    y_mean: Tensor,
    v: Tensor,
    s: Tensor,
    vt_xty: Tensor,
    n: f64,
}

impl Fit {
    fn new(x: &Tensor, y: &Tensor, mask: &[bool]) -> Self {
        let (x, y) = (rows(x, mask), rows(y, mask));
        let mean = x.mean_dim([0i64].as_slice(), true, Kind::Double);
        // Constant features get a unit scale: they are 0 after centring and drop out.
        let std = x.std_dim([0i64].as_slice(), false, true);
        let std = std.where_self(&std.gt(1e-9), &std.ones_like());
        let xs = (x - &mean) / &std;
        let y_mean = y.mean_dim([0i64].as_slice(), true, Kind::Double);
        let yc = y - &y_mean;
        let (s, v) = eigh(&xs.transpose(0, 1).matmul(&xs));
        let vt_xty = v.transpose(0, 1).matmul(&xs.transpose(0, 1).matmul(&yc));
        Self {
            n: xs.size()[0] as f64,
            mean,
            std,
            y_mean,
            v,
            s,
            vt_xty,
        }
    }

    fn predict(&self, x: &Tensor, mask: &[bool], lambda: f64) -> Tensor {
        let xs = (rows(x, mask) - &self.mean) / &self.std;
        let inv = (self.s.clamp_min(0.0) + lambda * self.n).reciprocal();
        let w = self.v.matmul(&(inv.unsqueeze(1) * &self.vt_xty));
        xs.matmul(&w) + &self.y_mean
    }
}

/// Eigenvalues and eigenvectors (columns) of a symmetric matrix, with faer.
fn eigh(a: &Tensor) -> (Tensor, Tensor) {
    let d = a.size()[0] as usize;
    let flat = Vec::<f64>::try_from(a.flatten(0, -1)).expect("a float64 matrix");
    let m = faer::Mat::<f64>::from_fn(d, d, |i, j| flat[i * d + j]);
    let evd = m
        .self_adjoint_eigen(faer::Side::Lower)
        .expect("a symmetric real matrix has an eigendecomposition");
    let s = evd.S().column_vector();
    let u = evd.U();
    let vals: Vec<f64> = (0..d).map(|i| s[i]).collect();
    let vecs: Vec<f64> = (0..d * d).map(|k| u[(k / d, k % d)]).collect();
    (
        Tensor::from_slice(&vals),
        Tensor::from_slice(&vecs).view([d as i64, d as i64]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn noise(rng: &mut ChaCha8Rng, n: usize) -> Vec<f64> {
        (0..n).map(|_| rng.random_range(-1.0..1.0)).collect()
    }

    /// 1200 samples in 12 "laps" of 100, 40 features; the target is a fixed mix of three of them
    /// plus noise of a third of its spread.
    fn planted(seed: u64) -> (Tensor, Tensor, Vec<u32>) {
        let (n, d) = (1200, 40);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let x = Tensor::from_slice(&noise(&mut rng, n * d)).view([n as i64, d as i64]);
        let signal = x.select(1, 3) * 2.0 - x.select(1, 17) + x.select(1, 30) * 0.5;
        let y = &signal + Tensor::from_slice(&noise(&mut rng, n)) * 0.45;
        let groups = (0..n).map(|i| (i / 100) as u32).collect();
        (x, y.unsqueeze(1), groups)
    }

    #[test]
    fn finds_a_planted_linear_signal() {
        let (x, y, groups) = planted(1);
        let folds = Folds::by_group(&groups, 5, 10).unwrap();
        let r = &ridge_cv(&x, &y, &folds)[0];
        // Signal variance 4 + 1 + 0.25 over 3 (uniform), noise 0.45^2 / 3: R^2 ~ 0.96.
        assert!(r.r2 > 0.9, "{r:?}");
        assert!(r.fold_r2.iter().all(|f| *f > 0.85), "{r:?}");
    }

    #[test]
    fn finds_nothing_in_shuffled_targets() {
        let (x, y, groups) = planted(2);
        let folds = Folds::by_group(&groups, 5, 10).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut order: Vec<i64> = (0..y.size()[0]).collect();
        for i in (1..order.len()).rev() {
            order.swap(i, rng.random_range(0..=i));
        }
        let shuffled = y.index_select(0, &Tensor::from_slice(&order));
        let r = &ridge_cv(&x, &shuffled, &folds)[0];
        assert!(r.r2 <= 0.05, "{r:?}");
    }

    #[test]
    fn training_never_sees_a_test_fold_or_its_neighbours() {
        let groups: Vec<u32> = (0..60).map(|i| i / 10).collect();
        let folds = Folds::by_group(&groups, 3, 2).unwrap();
        let train = folds.train_mask(&[true; 60], &[1]);
        for (i, t) in train.iter().enumerate() {
            let lap = i / 10;
            let after_test = lap > 0 && (lap - 1) % 3 == 1 && i % 10 < 2;
            let before_test = lap < 5 && (lap + 1) % 3 == 1 && i % 10 >= 8;
            let next_to_test = after_test || before_test;
            assert_eq!(*t, lap % 3 != 1 && !next_to_test, "sample {i}");
        }
        assert!(Folds::by_group(&[0, 0, 1], 3, 0).is_none());
    }
}
