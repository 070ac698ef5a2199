//! Per-step timing as percentiles (p50/p99/p99.9/max), never means: tails are what a control
//! loop feels.

use hdrhistogram::Histogram;
use serde::Serialize;

/// Records durations in nanoseconds, 1 us .. 60 s, 3 significant digits.
pub struct LatencyStats(Histogram<u64>);

/// What a report shows of one [`LatencyStats`], in microseconds.
#[derive(Debug, Clone, Copy, Default, Serialize, serde::Deserialize, PartialEq)]
pub struct LatencySummary {
    pub count: u64,
    pub p50_us: f64,
    #[serde(default)]
    pub p90_us: f64,
    pub p99_us: f64,
    pub p999_us: f64,
    pub max_us: f64,
}

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
        let h = &self.0;
        if h.is_empty() {
            return LatencySummary::default();
        }
        let us = |ns: u64| ns as f64 / 1e3;
        LatencySummary {
            count: h.len(),
            p50_us: us(h.value_at_quantile(0.5)),
            p90_us: us(h.value_at_quantile(0.9)),
            p99_us: us(h.value_at_quantile(0.99)),
            p999_us: us(h.value_at_quantile(0.999)),
            max_us: us(h.max()),
        }
    }
}

impl std::fmt::Display for LatencySummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "n={} p50={:.1}us p99={:.1}us p99.9={:.1}us max={:.1}us",
            self.count, self.p50_us, self.p99_us, self.p999_us, self.max_us
        )
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
