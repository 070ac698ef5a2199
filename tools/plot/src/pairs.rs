//! Two drivers per track in one plane: each track's baseline point and the driver compared with
//! it, joined by a grey line and named, so a reader sees per track which way the driver moved
//! (left: closer to the line; down: faster laps).

use std::path::Path;

use plotters::prelude::*;

use crate::legend::{self, Swatch};
use crate::ticks::{fmt_tick, padded};
use crate::{BLUE, GREEN, GREY, PlotError, colour, render, text};

/// One track: its name, the baseline's (x, y) and the compared driver's, where each has one.
pub struct Pair<'a> {
    pub name: &'a str,
    pub baseline: Option<(f64, f64)>,
    pub driver: Option<(f64, f64)>,
}

/// Draws `pairs` (baseline green, driver blue) with the legend naming them `names`.
pub fn pairs_chart(
    path: &Path,
    title: &str,
    (x_label, y_label): (&str, &str),
    names: (&str, &str),
    pairs: &[Pair],
) -> Result<(), PlotError> {
    let points = || {
        pairs
            .iter()
            .flat_map(|p| [p.baseline, p.driver])
            .flatten()
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    };
    let (x0, x1) = padded(points().map(|p| p.0));
    let (y0, y1) = padded(points().map(|p| p.1));
    render(path, (900 + legend::WIDTH, 600), |root| {
        root.fill(&WHITE)?;
        let (area, column) = legend::split(root);
        let mut chart = ChartBuilder::on(&area)
            .caption(title, text(20))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        chart
            .configure_mesh()
            .light_line_style(RGBColor(238, 238, 238))
            .x_label_formatter(&|v| fmt_tick(*v))
            .y_label_formatter(&|v| fmt_tick(*v))
            .x_desc(x_label)
            .y_desc(y_label)
            .label_style(text(14))
            .axis_desc_style(text(15))
            .draw()?;
        let finite = |p: &Option<(f64, f64)>| p.filter(|(x, y)| x.is_finite() && y.is_finite());
        for p in pairs {
            let (b, d) = (finite(&p.baseline), finite(&p.driver));
            if let (Some(b), Some(d)) = (b, d) {
                chart.draw_series(LineSeries::new(vec![b, d], colour(GREY).stroke_width(1)))?;
            }
            for (at, c) in [(b, GREEN), (d, BLUE)] {
                if let Some(at) = at {
                    chart.draw_series(std::iter::once(Circle::new(at, 6, colour(c).filled())))?;
                }
            }
            if let Some(at) = d.or(b) {
                let label = Text::new(p.name.to_string(), at, text(12));
                chart.draw_series(std::iter::once(label))?;
            }
        }
        let entries = [
            (names.0.to_string(), Swatch::Dot { colour: GREEN }),
            (names.1.to_string(), Swatch::Dot { colour: BLUE }),
        ];
        legend::draw(&column, 44, &entries)?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_png::{decode, near};

    #[test]
    fn draws_both_drivers_per_track() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("pairs.png");
        let pairs = [
            Pair {
                name: "oval",
                baseline: Some((1.6, 21.0)),
                driver: Some((1.4, 18.0)),
            },
            Pair {
                name: "square",
                baseline: Some((2.0, 17.5)),
                driver: None,
            },
        ];
        pairs_chart(&path, "t", ("x", "y"), ("rule", "learnt"), &pairs).unwrap();
        let (_, _, px) = decode(&path);
        // Two baseline dots against one driver dot (the legend draws one of each).
        let (green, blue) = (near(&px, GREEN), near(&px, BLUE));
        assert!(blue > 60, "the driver's dot: {blue} px");
        assert!(green > blue + 60, "two baseline dots: {green} px vs {blue}");
    }
}
