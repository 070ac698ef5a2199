//! Line charts: panels stacked on a shared x axis, each with its named series, dashed reference
//! lines and a legend (the learning curve, the model's error over a run).

use std::ops::Range;
use std::path::Path;

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

use crate::legend::{self, Swatch};
use crate::ticks::{LogAxis, decades, fmt_tick, padded};
use crate::{Area, DrawResult, GREY, PlotError, Rgb, colour, render, text};

/// One named line.
pub struct Series<'a> {
    pub name: &'a str,
    pub colour: Rgb,
    /// (x, y); non-finite y (and y <= 0 on a log axis) are left out.
    pub points: Vec<(f64, f64)>,
}

/// One panel: its series on shared axes.
pub struct Panel<'a> {
    pub title: &'a str,
    /// The y axis' label, with its unit.
    pub y_label: &'a str,
    pub series: Vec<Series<'a>>,
    /// Dashed horizontal reference lines: (value, legend label).
    pub refs: Vec<(f64, &'a str)>,
    pub log_y: bool,
    /// Fixed y range; none: the data's (whole decades on a log axis).
    pub y_range: Option<(f64, f64)>,
}

const WIDTH: u32 = 1000;
const PANEL_HEIGHT: u32 = 260;

/// Draws `panels` one above the other, sharing the x axis labelled `x_label`, into `path`.
pub fn lines_chart(path: &Path, x_label: &str, panels: &[Panel]) -> Result<(), PlotError> {
    let xs = panels
        .iter()
        .flat_map(|p| p.series.iter().flat_map(|s| s.points.iter().map(|q| q.0)));
    let x = XAxis {
        label: x_label,
        range: padded(xs),
        names: &[],
    };
    chart(path, &x, panels)
}

/// [`lines_chart`] over named categories: a series' point (i, y) is drawn above `categories[i]`.
pub fn category_chart(
    path: &Path,
    x_label: &str,
    categories: &[&str],
    panels: &[Panel],
) -> Result<(), PlotError> {
    let x = XAxis {
        label: x_label,
        range: (-0.5, categories.len() as f64 - 0.5),
        names: categories,
    };
    chart(path, &x, panels)
}

struct XAxis<'a> {
    label: &'a str,
    range: (f64, f64),
    /// Names at 0, 1, ...; empty: numeric ticks.
    names: &'a [&'a str],
}

impl XAxis<'_> {
    fn tick(&self, v: f64) -> String {
        if self.names.is_empty() {
            return fmt_tick(v);
        }
        let i = v.round();
        match self.names.get(i as usize) {
            Some(n) if (v - i).abs() < 1e-6 && i >= 0.0 => n.to_string(),
            _ => String::new(),
        }
    }
}

fn chart(path: &Path, x: &XAxis, panels: &[Panel]) -> Result<(), PlotError> {
    let (x0, x1) = x.range;
    let height = PANEL_HEIGHT * panels.len().max(1) as u32;
    render(path, (WIDTH, height), |root| {
        root.fill(&WHITE)?;
        let areas = root.split_evenly((panels.len().max(1), 1));
        for (p, area) in panels.iter().zip(&areas) {
            let (area, column) = legend::split(area);
            let y = y_range(p);
            if p.log_y {
                panel(&area, p, x0..x1, LogAxis::new(y.0, y.1), x)?;
            } else {
                panel(&area, p, x0..x1, y.0..y.1, x)?;
            }
            legend::draw(&column, 44, &entries(p))?;
        }
        Ok(())
    })
}

fn y_range(p: &Panel) -> (f64, f64) {
    let values = p
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|q| q.1))
        .chain(p.refs.iter().map(|r| r.0))
        .filter(|v| v.is_finite() && (!p.log_y || *v > 0.0));
    match (p.y_range, p.log_y) {
        (Some(r), _) => r,
        (None, false) => padded(values),
        (None, true) => {
            let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
            if lo.is_finite() {
                decades(lo, hi)
            } else {
                (0.1, 1.0)
            }
        }
    }
}

fn entries(p: &Panel) -> Vec<(String, Swatch)> {
    let lines = p.series.iter().map(|s| {
        let swatch = Swatch::Line {
            colour: s.colour,
            width: line_width(s.colour),
        };
        (s.name.to_string(), swatch)
    });
    let refs = p
        .refs
        .iter()
        .map(|r| (r.1.to_string(), Swatch::Dashed { colour: REF }));
    lines.chain(refs).collect()
}

/// Raw per-step series are drawn in grey and thin, under their smoothed mean.
fn line_width(c: Rgb) -> u32 {
    if c == GREY { 1 } else { 2 }
}

const REF: Rgb = [90, 90, 90];

fn panel<Y>(area: &Area, p: &Panel, x: Range<f64>, y: Y, axis: &XAxis) -> DrawResult
where
    Y: AsRangedCoord<Value = f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let mut chart = ChartBuilder::on(area)
        .caption(p.title, text(20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x, y)?;
    chart
        .configure_mesh()
        .light_line_style(RGBColor(238, 238, 238))
        .max_light_lines(4)
        .x_desc(axis.label)
        .y_desc(p.y_label)
        .x_labels(if axis.names.is_empty() {
            10
        } else {
            2 * axis.names.len() + 1
        })
        .x_label_formatter(&|v| axis.tick(*v))
        .y_label_formatter(&|v| fmt_tick(*v))
        .label_style(text(14))
        .axis_desc_style(text(15))
        .draw()?;
    let (xr, yr) = (chart.x_range(), chart.y_range());
    let inside = |q: &&(f64, f64)| q.1.is_finite() && (!p.log_y || q.1 > 0.0);
    for s in &p.series {
        let c = colour(s.colour);
        let width = line_width(s.colour);
        let pts: Vec<(f64, f64)> = s.points.iter().filter(inside).copied().collect();
        let style = c.stroke_width(width);
        if pts.len() == 1 {
            chart.draw_series(pts.iter().map(|q| Circle::new(*q, 3, c.filled())))?;
        } else {
            chart.draw_series(LineSeries::new(pts, style))?;
        }
    }
    for (v, _) in &p.refs {
        let c = colour(REF);
        let line = vec![(xr.start, *v), (xr.end, *v)];
        if *v < yr.start.min(yr.end) || *v > yr.start.max(yr.end) {
            continue;
        }
        chart.draw_series(DashedLineSeries::new(line, 6, 4, c.stroke_width(1)))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_png::{decode, near};
    use crate::{BLUE, GREEN};

    #[test]
    fn draws_stacked_panels_with_their_series() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lines.png");
        let loss: Vec<(f64, f64)> = (1..200).map(|s| (s as f64, 1.0 / s as f64)).collect();
        let probe: Vec<(f64, f64)> = (100..200).map(|s| (s as f64, 0.5)).collect();
        let panels = [
            Panel {
                title: "loss",
                y_label: "MSE (log)",
                series: vec![Series {
                    name: "loss",
                    colour: BLUE,
                    points: loss,
                }],
                refs: vec![],
                log_y: true,
                y_range: None,
            },
            Panel {
                title: "probe",
                y_label: "rank correlation",
                series: vec![Series {
                    name: "probe",
                    colour: GREEN,
                    points: probe,
                }],
                refs: vec![(0.7, "min_probe 0.7")],
                log_y: false,
                y_range: Some((-0.2, 1.0)),
            },
        ];
        lines_chart(&path, "training update", &panels).unwrap();
        let (w, h, px) = decode(&path);
        assert_eq!((w, h), (WIDTH, 2 * PANEL_HEIGHT));
        assert!(
            near(&px, REF) > 100,
            "the dashed reference line and its legend"
        );
        assert!(near(&px, BLUE) > 300, "the loss curve");
        assert!(near(&px, GREEN) > 200, "the probe");
    }

    #[test]
    fn names_categories_on_the_x_axis() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("categories.png");
        let panel = Panel {
            title: "R^2",
            y_label: "R^2",
            series: vec![Series {
                name: "curvature",
                colour: BLUE,
                points: vec![(0.0, 0.5), (1.0, 0.7), (2.0, 0.2)],
            }],
            refs: vec![(0.0, "mean")],
            log_y: false,
            y_range: None,
        };
        category_chart(&path, "read out from", &["R_0", "R_1", "frame"], &[panel]).unwrap();
        let (w, h, px) = decode(&path);
        assert_eq!((w, h), (WIDTH, PANEL_HEIGHT));
        assert!(near(&px, BLUE) > 200, "the series");
        let axis = XAxis {
            label: "",
            range: (-0.5, 2.5),
            names: &["a", "b", "c"],
        };
        assert_eq!(
            [
                axis.tick(0.0),
                axis.tick(0.5),
                axis.tick(2.0),
                axis.tick(3.0)
            ],
            ["a", "", "c", ""].map(String::from)
        );
    }
}
