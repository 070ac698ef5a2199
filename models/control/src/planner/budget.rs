//! What a batched rollout costs on this machine, measured while planning: the planner sizes its
//! batches from it so that a plan fits its deadline on any CPU, however slow or busy.

use std::time::Duration;

/// Wall time of a batched rollout as `fixed + per_unit x units` (units: candidates x segments),
/// fitted by least squares over recent batches with exponentially fading weights, so that it
/// follows a machine whose speed changes (another program, a frequency change).
#[derive(Debug, Clone, Default)]
pub struct RolloutCost {
    w: f64,
    x: f64,
    y: f64,
    xx: f64,
    xy: f64,
}

/// Weight kept by the past at each new batch: ~20 batches (two or three plans) of memory.
const FADE: f64 = 0.95;

impl RolloutCost {
    pub fn observe(&mut self, units: usize, took: Duration) {
        let (x, y) = (units as f64, took.as_secs_f64());
        self.w = FADE * self.w + 1.0;
        self.x = FADE * self.x + x;
        self.y = FADE * self.y + y;
        self.xx = FADE * self.xx + x * x;
        self.xy = FADE * self.xy + x * y;
    }

    /// (fixed seconds, seconds per unit); `None` before the first batch.
    fn line(&self) -> Option<(f64, f64)> {
        if self.w <= 0.0 || self.x <= 0.0 {
            return None;
        }
        let var = self.xx * self.w - self.x * self.x;
        if var > 1e-9 * self.xx * self.w {
            let slope = (self.xy * self.w - self.x * self.y) / var;
            let fixed = (self.y - slope * self.x) / self.w;
            if slope > 0.0 && fixed >= 0.0 {
                return Some((fixed, slope));
            }
        }
        // One batch size seen so far (or a fit that makes no physical sense): all of the time
        // per unit, which overestimates larger batches (the safe side).
        Some((0.0, self.y / self.x))
    }

    /// Predicted wall time of a batch of `units`.
    pub fn predict(&self, units: usize) -> Option<Duration> {
        self.line()
            .map(|(a, b)| Duration::from_secs_f64(a + b * units as f64))
    }

    /// Seconds per candidate-segment, for reports.
    pub fn per_unit(&self) -> Option<f64> {
        self.line().map(|(_, b)| b)
    }

    /// The most candidates in `min..=max` (a multiple of `step` above `min`) whose rollout of
    /// `segments` is predicted to take at most `within` (with a margin for noise); `None` if
    /// not even `min` fits. Without a measurement yet: `max`.
    pub fn affordable(
        &self,
        within: Duration,
        segments: usize,
        min: usize,
        max: usize,
        step: usize,
    ) -> Option<usize> {
        let Some((a, b)) = self.line() else {
            return Some(max);
        };
        let budget = within.as_secs_f64() / MARGIN - a;
        let fit = (budget / (b * segments.max(1) as f64)).floor();
        if !fit.is_finite() || fit < min as f64 {
            return None;
        }
        let k = (fit as usize).min(max);
        // Few distinct batch sizes: libtorch's convolution back ends build (and cache) work per
        // input shape, and a new shape costs milliseconds the first time.
        Some(if k == max {
            max
        } else {
            min + (k - min) / step.max(1) * step.max(1)
        })
    }
}

/// A predicted rollout must fit its time this many times over (timing noise, preemption).
const MARGIN: f64 = 1.25;

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: f64) -> Duration {
        Duration::from_secs_f64(v / 1e3)
    }

    #[test]
    fn learns_the_fixed_and_per_unit_cost_and_follows_a_slower_machine() {
        let mut c = RolloutCost::default();
        assert_eq!(c.predict(10), None);
        assert_eq!(
            c.affordable(ms(1.0), 4, 8, 32, 8),
            Some(32),
            "no measurement yet"
        );
        // 1 ms + 0.05 ms per candidate-segment.
        for _ in 0..5 {
            c.observe(24, ms(1.0 + 0.05 * 24.0));
            c.observe(128, ms(1.0 + 0.05 * 128.0));
        }
        let p = c.predict(64).unwrap().as_secs_f64() * 1e3;
        assert!((p - 4.2).abs() < 1e-6, "{p}");
        assert!((c.per_unit().unwrap() * 1e3 - 0.05).abs() < 1e-9);
        // 20 ms for 4 segments: (20 / 1.25 - 1) / 0.2 = 75 candidates, capped at 32.
        assert_eq!(c.affordable(ms(20.0), 4, 8, 32, 8), Some(32));
        // 5 ms: (4 - 1) / 0.2 = 15 -> the multiple of 8 above 8 below it: 8.
        assert_eq!(c.affordable(ms(5.0), 4, 8, 32, 8), Some(8));
        // 6.5 ms: (5.2 - 1) / 0.2 = 21 -> 16.
        assert_eq!(c.affordable(ms(6.5), 4, 8, 32, 8), Some(16));
        assert_eq!(c.affordable(ms(2.0), 4, 8, 32, 8), None, "not even 8 fit");
        // The machine becomes three times slower: within a few plans the estimate follows.
        for _ in 0..40 {
            c.observe(24, ms(3.0 * (1.0 + 0.05 * 24.0)));
            c.observe(128, ms(3.0 * (1.0 + 0.05 * 128.0)));
        }
        let p = c.predict(64).unwrap().as_secs_f64() * 1e3;
        assert!((p - 12.6).abs() < 0.3, "{p}");
    }

    #[test]
    fn one_batch_size_alone_is_charged_per_unit() {
        let mut c = RolloutCost::default();
        c.observe(24, ms(2.4));
        let p = c.predict(48).unwrap().as_secs_f64() * 1e3;
        assert!((p - 4.8).abs() < 1e-9, "{p}");
    }
}
