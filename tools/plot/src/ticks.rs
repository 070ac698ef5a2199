//! Axis ranges and tick labels. plotters places linear ticks at 1-2-5 steps itself; these keep
//! the labels short (no `0.30000000000000004`) and log axes on whole decades, where plotters
//! would otherwise find no tick inside a range narrower than a decade.

use plotters::coord::combinators::{IntoLogRange, LogCoord};
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};

/// A tick value as a person writes it: at most 3 significant digits, no trailing zeros,
/// powers of ten for the very small or large.
pub fn fmt_tick(v: f64) -> String {
    let a = v.abs();
    if a < 1e-12 {
        return "0".into();
    }
    if !(1e-3..1e6).contains(&a) {
        let s = format!("{v:.1e}");
        return s.replace(".0e", "e");
    }
    // Decimals enough for 3 significant digits, then trimmed.
    let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// A log axis' range: `lo..hi` widened to whole decades (positive values only).
pub fn decades(lo: f64, hi: f64) -> (f64, f64) {
    let lo = lo.max(1e-12);
    let (a, b) = (lo.log10().floor(), hi.max(lo).log10().ceil());
    (10f64.powf(a), 10f64.powf(if b > a { b } else { a + 1.0 }))
}

/// A log axis over `lo..hi` (whole decades) for plotters, which puts a tick at a decade only
/// when it computes it to lie inside: `log10(0.01)` comes out a hair above -2 and the bottom
/// tick would be lost, so the range is widened by a millionth.
pub fn log_axis(lo: f64, hi: f64) -> std::ops::Range<f64> {
    lo * (1.0 - 1e-6)..hi * (1.0 + 1e-6)
}

/// A log axis labelled at 1-2-5 inside short ranges (up to two decades) and at the decades
/// otherwise: plotters' own log axis labels either the decades alone or every 1..9.
pub struct LogAxis(LogCoord<f64>);

impl LogAxis {
    /// Over whole decades from `lo` to `hi` (see [`decades`], [`log_axis`]).
    pub fn new(lo: f64, hi: f64) -> Self {
        let (lo, hi) = decades(lo, hi);
        Self(log_axis(lo, hi).log_scale().into())
    }
}

impl Ranged for LogAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        self.0.map(v, limit)
    }

    fn key_points<H: KeyPointHint>(&self, _hint: H) -> Vec<f64> {
        let r = self.0.range();
        let span = (r.end / r.start).log10();
        let steps: &[f64] = if span <= 2.01 {
            &[1.0, 2.0, 5.0]
        } else {
            &[1.0]
        };
        let first = r.start.log10().round() as i32;
        let last = r.end.log10().round() as i32;
        (first..=last)
            .flat_map(|e| steps.iter().map(move |m| m * 10f64.powi(e)))
            .filter(|v| (r.start..=r.end).contains(v))
            .collect()
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.0.range()
    }
}

/// Finite min and max of `v`, widened a little (and when equal or absent) so nothing sits on
/// the frame.
pub fn padded(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if !lo.is_finite() {
        (0.0, 1.0)
    } else if hi - lo < 1e-12 {
        let d = 0.5 * lo.abs().max(1e-3);
        (lo - d, hi + d)
    } else {
        let d = 0.04 * (hi - lo);
        (lo - d, hi + d)
    }
}

/// A duration in microseconds with its unit: `1 µs`, `250 µs`, `10 ms`, `1 s`.
pub fn fmt_us(us: f64) -> String {
    if us >= 1e6 {
        format!("{} s", fmt_tick(us / 1e6))
    } else if us >= 1e3 {
        format!("{} ms", fmt_tick(us / 1e3))
    } else {
        format!("{} µs", fmt_tick(us))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_short_and_round() {
        assert_eq!(fmt_tick(0.1 + 0.2), "0.3");
        assert_eq!(fmt_tick(0.0), "0");
        assert_eq!(fmt_tick(-0.25), "-0.25");
        assert_eq!(fmt_tick(2500.0), "2500");
        assert_eq!(fmt_tick(12.5), "12.5");
        assert_eq!(fmt_tick(1.0), "1");
        assert_eq!(fmt_tick(0.0012345), "0.00123");
        assert_eq!(fmt_tick(1e-5), "1e-5");
        assert_eq!(fmt_tick(3e7), "3e7");
    }

    #[test]
    fn log_ranges_span_whole_decades() {
        assert_eq!(decades(0.013, 0.4), (0.01, 1.0));
        assert_eq!(decades(2.0, 2.0), (1.0, 10.0));
        let (lo, hi) = decades(3e-4, 70.0);
        assert!((lo - 1e-4).abs() < 1e-18 && (hi - 100.0).abs() < 1e-9);
    }

    #[test]
    fn log_axes_tick_both_end_decades() {
        let (lo, hi) = decades(0.013, 0.4);
        let axis: LogCoord<f64> = log_axis(lo, hi).log_scale().into();
        let ticks: Vec<String> = axis.key_points(5).iter().map(|v| fmt_tick(*v)).collect();
        assert_eq!(ticks, ["0.01", "0.1", "1"]);
    }

    #[test]
    fn short_log_axes_tick_at_one_two_five() {
        let ticks = |lo, hi| -> Vec<String> {
            let axis = LogAxis::new(lo, hi);
            axis.key_points(10).iter().map(|v| fmt_tick(*v)).collect()
        };
        assert_eq!(ticks(0.12, 0.9), ["0.1", "0.2", "0.5", "1"]);
        assert_eq!(
            ticks(0.013, 0.4),
            ["0.01", "0.02", "0.05", "0.1", "0.2", "0.5", "1"]
        );
        assert_eq!(
            ticks(2.0, 3e4),
            ["1", "10", "100", "1000", "10000", "100000"]
        );
    }

    #[test]
    fn padded_ranges_contain_the_data_and_never_collapse() {
        let (lo, hi) = padded([1.0, 3.0, f64::NAN].into_iter());
        assert!(lo < 1.0 && hi > 3.0 && hi - lo < 2.5);
        let (lo, hi) = padded([5.0].into_iter());
        assert!(lo < 5.0 && hi > 5.0);
        assert_eq!(padded(std::iter::empty()), (0.0, 1.0));
    }

    #[test]
    fn durations_carry_their_unit() {
        assert_eq!(fmt_us(1.0), "1 µs");
        assert_eq!(fmt_us(250.0), "250 µs");
        assert_eq!(fmt_us(10_000.0), "10 ms");
        assert_eq!(fmt_us(1e6), "1 s");
    }
}
