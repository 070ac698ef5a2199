//! Small-sample statistics over seeds: the median, the interquartile range, and a seeded
//! percentile bootstrap of the difference of two groups' medians. With 2-5 seeds the bootstrap
//! is coarse (few distinct resamples); summary.md says how many seeds each figure rests on.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub use mtanet_summaries::quantile;

fn sorted(values: &[f64]) -> Vec<f64> {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    v
}

pub fn median(values: &[f64]) -> Option<f64> {
    quantile(&sorted(values), 0.5)
}

/// Median and the first and third quartiles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    pub median: f64,
    pub q1: f64,
    pub q3: f64,
    pub n: usize,
}

impl Spread {
    pub fn of(values: &[f64]) -> Option<Self> {
        let s = sorted(values);
        Some(Self {
            median: quantile(&s, 0.5)?,
            q1: quantile(&s, 0.25)?,
            q3: quantile(&s, 0.75)?,
            n: s.len(),
        })
    }

    pub fn iqr(&self) -> f64 {
        self.q3 - self.q1
    }
}

/// A percentile bootstrap interval of `median(a) - median(b)`: each resample draws `a` and `b`
/// with replacement, each at its own size; the interval holds the central `confidence` of the
/// resampled differences. `None` when either group has fewer than two values.
pub fn bootstrap_median_difference(
    a: &[f64],
    b: &[f64],
    resamples: usize,
    confidence: f64,
    seed: u64,
) -> Option<(f64, f64)> {
    if a.len() < 2 || b.len() < 2 || resamples == 0 {
        return None;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut draw = |x: &[f64], buf: &mut Vec<f64>| {
        buf.clear();
        buf.extend((0..x.len()).map(|_| x[rng.random_range(0..x.len())]));
        buf.sort_by(f64::total_cmp);
        quantile(buf, 0.5).expect("non-empty")
    };
    let (mut ba, mut bb) = (Vec::new(), Vec::new());
    let mut diffs: Vec<f64> = (0..resamples)
        .map(|_| draw(a, &mut ba) - draw(b, &mut bb))
        .collect();
    diffs.sort_by(f64::total_cmp);
    let tail = (1.0 - confidence) / 2.0;
    Some((quantile(&diffs, tail)?, quantile(&diffs, 1.0 - tail)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_quartiles_on_known_data() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median(&[]), None);
        // numpy: np.percentile([1, 2, 3, 4, 5, 6, 7, 8], [25, 50, 75]) = 2.75, 4.5, 6.25
        let s = Spread::of(&[8.0, 1.0, 7.0, 2.0, 6.0, 3.0, 5.0, 4.0]).unwrap();
        assert_eq!((s.q1, s.median, s.q3, s.n), (2.75, 4.5, 6.25, 8));
        assert_eq!(s.iqr(), 3.5);
        let one = Spread::of(&[7.0]).unwrap();
        assert_eq!((one.q1, one.median, one.q3), (7.0, 7.0, 7.0));
    }

    #[test]
    fn the_interval_of_two_identical_samples_contains_zero() {
        let x = [3.1, 0.4, 2.2, 5.0, 1.7];
        let (lo, hi) = bootstrap_median_difference(&x, &x, 2000, 0.95, 1).unwrap();
        assert!(lo < 0.0 && 0.0 < hi, "[{lo}, {hi}]");
        // The interval moves with the data: shifting one sample by 5 shifts it by 5 exactly
        // (same seed, same resamples), which no fixed interval does.
        let shifted: Vec<f64> = x.iter().map(|v| v + 5.0).collect();
        let (lo5, hi5) = bootstrap_median_difference(&shifted, &x, 2000, 0.95, 1).unwrap();
        assert!(
            (lo5 - lo - 5.0).abs() < 1e-9 && (hi5 - hi - 5.0).abs() < 1e-9,
            "[{lo}, {hi}] shifted by 5 gave [{lo5}, {hi5}]"
        );
    }

    #[test]
    fn a_clear_shift_is_found_and_resampling_is_seeded() {
        let b = [0.0, 1.0, 2.0, 3.0, 4.0];
        let a: Vec<f64> = b.iter().map(|v| v + 100.0).collect();
        let (lo, hi) = bootstrap_median_difference(&a, &b, 2000, 0.95, 1).unwrap();
        // Medians of resamples lie within the samples' ranges: the difference within 96..104.
        assert!(
            (96.0..=100.0).contains(&lo) && (100.0..=104.0).contains(&hi),
            "[{lo}, {hi}]"
        );
        assert!(lo < hi, "a spread sample gives an interval, not a point");
        assert_eq!(
            bootstrap_median_difference(&a, &b, 2000, 0.95, 1),
            Some((lo, hi)),
            "same seed, same interval"
        );
        // Constant groups: every resample differs by exactly 10.
        let c = bootstrap_median_difference(&[10.0; 4], &[0.0; 3], 500, 0.9, 0);
        assert_eq!(c, Some((10.0, 10.0)));
        assert_eq!(bootstrap_median_difference(&[1.0], &b, 500, 0.9, 0), None);
    }
}
