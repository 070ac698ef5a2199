//! Per-step timing as percentiles (p50/p99/p99.9/max), never means: tails are what a control
//! loop feels.

use hdrhistogram::Histogram;
pub use mtanet_summaries::latency::LatencySummary;

/// Records durations in nanoseconds, 1 us .. 60 s, 3 significant digits.
pub struct LatencyStats(Histogram<u64>);

impl Default for LatencyStats {
    fn default() -> Self {
        Self::new()
    }
}

impl LatencyStats {
    pub fn new() -> Self {
        Self(
            Histogram::new_with_bounds(1_000, 60_000_000_000, 3)
                .expect("constant histogram bounds are valid"),
        )
    }

    pub fn record_ns(&mut self, ns: u64) {
        self.0.saturating_record(ns.max(1_000));
    }

    /// Counts in logarithmic bins (10 per decade), as (upper bound in us, count), empty bins
    /// left out: enough to draw the distribution.
    pub fn histogram(&self) -> Vec<[f64; 2]> {
        let mut out: Vec<[f64; 2]> = Vec::new();
        for v in self.0.iter_recorded() {
            let us = v.value_iterated_to() as f64 / 1e3;
            let bin = 10f64.powf((us.max(1.0).log10() * 10.0).ceil() / 10.0);
            match out.last_mut() {
                Some(last) if last[0] == bin => last[1] += v.count_at_value() as f64,
                _ => out.push([bin, v.count_at_value() as f64]),
            }
        }
        out
    }

    pub fn summary(&self) -> LatencySummary {
        LatencySummary::of_ns(&self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_follow_the_data() {
        let mut s = LatencyStats::new();
        for i in 1..=1000u64 {
            s.record_ns(i * 1_000);
        }
        let sum = s.summary();
        assert_eq!(sum.count, 1000);
        assert!((sum.p50_us - 500.0).abs() < 2.0, "{sum}");
        assert!((sum.p99_us - 990.0).abs() < 3.0, "{sum}");
        assert!((sum.max_us - 1000.0).abs() < 2.0, "{sum}");
        assert_eq!(LatencyStats::new().summary().count, 0);
        let h = s.histogram();
        assert_eq!(h.iter().map(|b| b[1]).sum::<f64>(), 1000.0);
        assert!(
            h.windows(2).all(|w| w[0][0] < w[1][0]),
            "bins ascend: {h:?}"
        );
    }
}
