//! The experiments' dot plot: per metric, the variants side by side, every seed's value a dot
//! and the median a bar with its value, so a reader sees both the spread and the middle.

use std::ops::Range;
use std::path::Path;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::prelude::*;

use crate::legend::{self, Swatch};
use crate::ticks::{fmt_tick, padded};
use crate::{BLUE, GREEN, ORANGE, PURPLE, PlotError, RED, colour, render, text};

const HEIGHT: u32 = 480;
const PALETTE: [[u8; 3]; 5] = [BLUE, ORANGE, GREEN, PURPLE, RED];

/// `variants` left to right, each `(name, one value per seed)`; non-finite values are left out.
pub fn variants_dot_plot<S: AsRef<str>>(
    path: &Path,
    title: &str,
    y_label: &str,
    variants: &[(S, Vec<f64>)],
) -> Result<(), PlotError> {
    let n = variants.len();
    let (y0, y1) = padded(variants.iter().flat_map(|v| v.1.iter().copied()));
    let width = (160 * n as u32 + 160).max(600) + legend::WIDTH;
    render(path, (width, HEIGHT), |root| {
        root.fill(&WHITE)?;
        let (area, column) = legend::split(root);
        let mut chart = ChartBuilder::on(&area)
            .caption(title, text(20))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d(Categories(n), y0..y1)?;
        let name = |x: &f64| {
            let i = x.round() as usize;
            variants
                .get(i)
                .map_or(String::new(), |v| v.0.as_ref().to_string())
        };
        chart
            .configure_mesh()
            .disable_x_mesh()
            .light_line_style(RGBColor(238, 238, 238))
            .max_light_lines(4)
            .x_label_formatter(&name)
            .y_label_formatter(&|v| fmt_tick(*v))
            .x_desc("variant")
            .y_desc(y_label)
            .label_style(text(14))
            .axis_desc_style(text(15))
            .draw()?;
        for (i, (_, values)) in variants.iter().enumerate() {
            let c = colour(PALETTE[i % PALETTE.len()]);
            let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
            let dots = finite
                .iter()
                .enumerate()
                .map(|(j, v)| (i as f64 + jitter(j, finite.len()), *v));
            chart.draw_series(dots.map(|p| Circle::new(p, 5, c.filled())))?;
            let Some(m) = median(&finite) else { continue };
            let bar = vec![(i as f64 - 0.3, m), (i as f64 + 0.3, m)];
            chart.draw_series(LineSeries::new(bar, BLACK.stroke_width(3)))?;
            chart.draw_series(std::iter::once(Text::new(
                fmt_tick(m),
                (i as f64 + 0.32, m),
                text(14),
            )))?;
        }
        let entries = [
            ("one seed".to_string(), Swatch::Dot { colour: PALETTE[0] }),
            (
                "median".to_string(),
                Swatch::Line {
                    colour: [0, 0, 0],
                    width: 3,
                },
            ),
        ];
        legend::draw(&column, 44, &entries)?;
        Ok(())
    })
}

/// A seed's offset from its variant's centre: spread evenly, at most a quarter either way.
fn jitter(j: usize, n: usize) -> f64 {
    if n < 2 {
        return 0.0;
    }
    let step = (0.5 / (n - 1) as f64).min(0.08);
    (j as f64 - (n - 1) as f64 / 2.0) * step
}

fn median(v: &[f64]) -> Option<f64> {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let k = s.len();
    (k > 0).then(|| {
        if k % 2 == 1 {
            s[k / 2]
        } else {
            (s[k / 2 - 1] + s[k / 2]) / 2.0
        }
    })
}

/// `n` categories at 0, 1, .. n-1 with half a slot of room at either end; ticks only at the
/// categories, so each label names one variant.
struct Categories(usize);

impl Ranged for Categories {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, (lo, hi): (i32, i32)) -> i32 {
        let r = self.range();
        lo + ((v - r.start) / (r.end - r.start) * (hi - lo) as f64).round() as i32
    }

    fn key_points<H: KeyPointHint>(&self, _hint: H) -> Vec<f64> {
        (0..self.0).map(|i| i as f64).collect()
    }

    fn range(&self) -> Range<f64> {
        -0.5..self.0.max(1) as f64 - 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_png::{decode, near};

    #[test]
    fn draws_every_seed_and_the_median_per_variant() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("dots.png");
        let variants = vec![
            ("baseline".to_string(), vec![0.5, 0.6, 0.7]),
            ("wider".to_string(), vec![0.8, 0.85, f64::NAN, 0.9]),
            ("nothing".to_string(), vec![]),
        ];
        variants_dot_plot(&path, "probe by variant", "rank correlation", &variants).unwrap();
        let (w, h, px) = decode(&path);
        assert_eq!((w, h), (640 + legend::WIDTH, HEIGHT));
        assert!(
            near(&px, BLUE) > 100 && near(&px, ORANGE) > 100,
            "the seeds' dots"
        );
    }

    #[test]
    fn medians_and_jitter() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&[]), None);
        assert_eq!(jitter(0, 1), 0.0);
        let spread: Vec<f64> = (0..10).map(|j| jitter(j, 10)).collect();
        assert!(spread.iter().all(|d| d.abs() <= 0.25));
        assert!((spread[0] + spread[9]).abs() < 1e-12, "centred");
    }
}
