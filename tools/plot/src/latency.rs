//! Latency histograms, one row per leg, on a shared log time axis with the leg's p50, p99 and
//! p99.9 marked: where the bulk sits and how far the tail reaches.

use std::path::Path;

use plotters::prelude::*;

use crate::legend::{self, Swatch};
use crate::ticks::{decades, fmt_tick, fmt_us, log_axis};
use crate::{BLUE, PlotError, colour, render, text};

const WIDTH: u32 = 1000;
const ROW_HEIGHT: u32 = 240;
/// Each bin is a tenth of a decade wide and named by its upper bound (`LatencyStats`).
const BIN_RATIO: f64 = 1.258_925_411_794_167_2; // 10^0.1

/// The count axis starts below 1 so that a bin of one sample (the tail that matters) shows as
/// a bar, not a hairline.
const FLOOR: f64 = 0.4;

/// Percentiles marked on each row, with their line colours.
const MARKS: [(f64, &str, [u8; 3]); 3] = [
    (0.5, "p50", [20, 150, 60]),
    (0.99, "p99", [240, 150, 0]),
    (0.999, "p99.9", [210, 40, 40]),
];

/// One row per `(name, bins)`; a bin is `[upper bound in µs, count]`.
pub fn latency_histograms(path: &Path, series: &[(&str, &[[f64; 2]])]) -> Result<(), PlotError> {
    let bins = || {
        series
            .iter()
            .flat_map(|s| s.1.iter())
            .filter(|b| b[1] > 0.0)
    };
    let lo = bins()
        .map(|b| b[0] / BIN_RATIO)
        .fold(f64::INFINITY, f64::min);
    let hi = bins().map(|b| b[0]).fold(0.0, f64::max);
    let (x0, x1) = if lo.is_finite() {
        decades(lo.min(10.0), hi.max(1e4))
    } else {
        (1.0, 1e6)
    };
    let rows = series.len().max(1);
    render(path, (WIDTH, ROW_HEIGHT * rows as u32), |root| {
        root.fill(&WHITE)?;
        for ((name, bins), area) in series.iter().zip(root.split_evenly((rows, 1))) {
            let (area, column) = legend::split(&area);
            let n: f64 = bins.iter().map(|b| b[1]).sum();
            let peak = bins.iter().map(|b| b[1]).fold(1.0, f64::max);
            let title = format!("{name}  ({} samples)", n as u64);
            let mut chart = ChartBuilder::on(&area)
                .caption(title, text(18))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(70)
                .build_cartesian_2d(
                    (x0..x1).log_scale(),
                    log_axis(FLOOR, decades(1.0, peak).1).log_scale(),
                )?;
            chart
                .configure_mesh()
                .x_labels(8)
                .light_line_style(RGBColor(242, 242, 242))
                .max_light_lines(4)
                .y_labels(6)
                .x_label_formatter(&|v| fmt_us(*v))
                .y_label_formatter(&|v| fmt_tick(*v))
                .x_desc("latency (log scale)")
                .y_desc("count per 1/10 decade (log)")
                .label_style(text(14))
                .axis_desc_style(text(15))
                .draw()?;
            chart.draw_series(bins.iter().filter(|b| b[1] > 0.0).map(|b| {
                Rectangle::new(
                    [(b[0] / BIN_RATIO, FLOOR), (b[0], b[1])],
                    colour(BLUE).filled(),
                )
            }))?;
            let mut entries = vec![("count".to_string(), Swatch::Block { colour: BLUE })];
            for (q, label, c) in MARKS {
                let Some(at) = percentile(bins, q) else {
                    continue;
                };
                let line = [(at, FLOOR), (at, peak * 1.5)];
                chart.draw_series(DashedLineSeries::new(line, 6, 4, colour(c).stroke_width(2)))?;
                entries.push((
                    format!("{label} ≤ {}", fmt_us(at)),
                    Swatch::Line {
                        colour: c,
                        width: 2,
                    },
                ));
            }
            legend::draw(&column, 40, &entries)?;
        }
        Ok(())
    })
}

/// The upper bound of the bin holding quantile `q` (what the histogram can say of it).
fn percentile(bins: &[[f64; 2]], q: f64) -> Option<f64> {
    let n: f64 = bins.iter().map(|b| b[1]).sum();
    let mut seen = 0.0;
    bins.iter().find_map(|b| {
        seen += b[1];
        (n > 0.0 && seen >= q * n).then_some(b[0])
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_png::{decode, near};

    #[test]
    fn draws_one_row_per_leg_with_its_bars() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("latency.png");
        let step: Vec<[f64; 2]> = (10..40)
            .map(|k| [10f64.powf(k as f64 / 10.0), 50.0])
            .collect();
        let empty: Vec<[f64; 2]> = vec![];
        latency_histograms(&path, &[("step", &step), ("nothing yet", &empty)]).unwrap();
        let (w, h, px) = decode(&path);
        assert_eq!((w, h), (WIDTH, 2 * ROW_HEIGHT));
        assert!(near(&px, BLUE) > 2000, "the bars");
        assert!(near(&px, MARKS[0].2) > 100, "the median's line");
    }

    #[test]
    fn percentiles_name_the_bin_that_holds_them() {
        let bins = [[10.0, 50.0], [20.0, 49.0], [1000.0, 1.0]];
        assert_eq!(percentile(&bins, 0.5), Some(10.0));
        assert_eq!(percentile(&bins, 0.99), Some(20.0));
        assert_eq!(percentile(&bins, 0.999), Some(1000.0));
        assert_eq!(percentile(&[], 0.5), None);
    }
}
