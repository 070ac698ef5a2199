//! What the plans could afford over a run: iterations, candidates, how many a deadline cut, the
//! cost they reached and what a rollout cost. For reports (`report.json`, `soak.json`, logs).

pub use mtanet_summaries::PlanningSummary;

use super::Outcome;

/// Collects [`Outcome`]s in bounded counts (a run may last days); [`PlanStats::summary`] gives
/// the percentiles.
#[derive(Debug, Clone, Default)]
pub struct PlanStats {
    /// Plans by the iterations (candidates) they could afford: `[n]` counts the value n.
    iterations: Vec<u64>,
    candidates: Vec<u64>,
    costs: LogHistogram,
    unit_us: LogHistogram,
    cut: u64,
    unscored: u64,
}

impl PlanStats {
    pub fn record(&mut self, o: &Outcome) {
        count(&mut self.iterations, o.iterations);
        count(&mut self.candidates, o.candidates);
        self.cut += u64::from(o.cut);
        match o.terms {
            Some(t) => self.costs.record(f64::from(t.total)),
            None => self.unscored += 1,
        }
        if let Some(s) = o.rollout_s_per_candidate_segment {
            self.unit_us.record(s * 1e6);
        }
    }

    pub fn summary(&self) -> PlanningSummary {
        let plans: u64 = self.iterations.iter().sum();
        PlanningSummary {
            plans,
            cut: self.cut,
            cut_share: if plans > 0 {
                self.cut as f64 / plans as f64
            } else {
                0.0
            },
            unscored: self.unscored,
            iterations_p50: counted_quantile(&self.iterations, 0.5) as f64,
            iterations_min: counted_quantile(&self.iterations, 0.0) as u32,
            candidates_p50: counted_quantile(&self.candidates, 0.5) as f64,
            candidates_min: counted_quantile(&self.candidates, 0.0) as u32,
            cost_p50: self.costs.quantile(0.5),
            cost_p90: self.costs.quantile(0.9),
            rollout_us_per_candidate_segment_p50: self.unit_us.quantile(0.5),
        }
    }
}

fn count(counts: &mut Vec<u64>, value: usize) {
    if counts.len() <= value {
        counts.resize(value + 1, 0);
    }
    counts[value] += 1;
}

/// The value at quantile `q` (nearest rank; `q` = 0 is the minimum) of values counted by value.
fn counted_quantile(counts: &[u64], q: f64) -> usize {
    let n: u64 = counts.iter().sum();
    let rank = ((q * n as f64).ceil() as u64).clamp(1, n.max(1));
    let mut seen = 0;
    for (value, c) in counts.iter().enumerate() {
        seen += c;
        if seen >= rank {
            return value;
        }
    }
    0
}

/// Non-negative values in bins 1% apart from 1e-4 to 1e6 (values outside go to the ends).
#[derive(Debug, Clone)]
struct LogHistogram {
    bins: Vec<u64>,
}

const LOW: f64 = 1e-4;
const BINS_PER_DECADE: f64 = 231.0; // 10^(1/231) = 1.01
const DECADES: f64 = 10.0;

impl Default for LogHistogram {
    fn default() -> Self {
        Self {
            bins: vec![0; (BINS_PER_DECADE * DECADES) as usize + 1],
        }
    }
}

impl LogHistogram {
    fn record(&mut self, v: f64) {
        if !v.is_finite() {
            return;
        }
        let i = ((v.max(LOW) / LOW).log10() * BINS_PER_DECADE).round();
        let i = (i as usize).min(self.bins.len() - 1);
        self.bins[i] += 1;
    }

    /// The `q` quantile to within 1%; 0 without values.
    fn quantile(&self, q: f64) -> f64 {
        if self.bins.iter().all(|&c| c == 0) {
            return 0.0;
        }
        let i = counted_quantile(&self.bins, q);
        LOW * 10f64.powf(i as f64 / BINS_PER_DECADE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cost::Terms;
    use crate::drive::Drive;

    fn outcome(iterations: usize, candidates: usize, cut: bool, total: Option<f32>) -> Outcome {
        Outcome {
            plan: vec![Drive::new(8.0, 0.0)],
            terms: total.map(|total| Terms {
                total,
                ..Default::default()
            }),
            evaluations: 0,
            iterations,
            candidates,
            cut,
            rollout_s_per_candidate_segment: Some(50e-6),
        }
    }

    #[test]
    fn percentiles_minimum_and_cut_share() {
        let mut s = PlanStats::default();
        assert_eq!(s.summary(), PlanningSummary::default());
        s.record(&outcome(3, 32, false, Some(1.0)));
        s.record(&outcome(3, 32, false, Some(2.0)));
        s.record(&outcome(1, 16, true, Some(3.0)));
        s.record(&outcome(0, 0, true, None));
        let m = s.summary();
        assert_eq!((m.plans, m.cut, m.unscored), (4, 2, 1));
        assert_eq!(m.cut_share, 0.5);
        assert_eq!((m.iterations_p50, m.iterations_min), (1.0, 0));
        assert_eq!((m.candidates_p50, m.candidates_min), (16.0, 0));
        assert!((m.cost_p50 - 2.0).abs() < 0.01 * 2.0, "{m:?}");
        assert!((m.cost_p90 - 3.0).abs() < 0.01 * 3.0, "{m:?}");
        assert!((m.rollout_us_per_candidate_segment_p50 - 50.0).abs() < 0.5);
    }
}
