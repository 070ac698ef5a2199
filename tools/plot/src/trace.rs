//! The lap trace: the car's path over the track, in metres on equal axes (a circle stays round),
//! one colour per driver, the track's centre line underneath.

use std::path::Path;

use plotters::prelude::*;

use crate::legend::{self, Swatch};
use crate::ticks::{fmt_tick, padded};
use crate::{Area, PlotError, Rgb, colour, render, text};

/// Points in the plane drawn in one colour under one legend name.
pub struct Path2d<'a> {
    pub name: &'a str,
    pub colour: Rgb,
    pub points: Vec<(f64, f64)>,
}

/// The widest and tallest picture; the height shrinks to the track's aspect.
const SIZE: (u32, u32) = (900 + legend::WIDTH, 820);
const MIN_HEIGHT: u32 = 400;
const TRACK: Rgb = [200, 200, 200];

/// Draws the closed `track` polyline and `paths` over it into `path`, titled `title`; paths
/// without points stay out of the legend.
pub fn lap_trace(
    path: &Path,
    title: &str,
    track: &[[f64; 2]],
    paths: &[Path2d],
) -> Result<(), PlotError> {
    let xs = track
        .iter()
        .map(|p| p[0])
        .chain(paths.iter().flat_map(|p| p.points.iter().map(|q| q.0)));
    let ys = track
        .iter()
        .map(|p| p[1])
        .chain(paths.iter().flat_map(|p| p.points.iter().map(|q| q.1)));
    let (x, y) = (padded(xs), padded(ys));
    // The picture's height follows the track's shape, so a flat oval leaves no empty band.
    let plot_w = (SIZE.0 - legend::WIDTH - 2 * 12 - 60) as f64;
    let plot_h = plot_w * (y.1 - y.0) / (x.1 - x.0).max(1e-9);
    let height = (plot_h as u32 + 2 * 12 + 44 + 30).clamp(MIN_HEIGHT, SIZE.1);
    render(path, (SIZE.0, height), |root| {
        root.fill(&WHITE)?;
        let area = root.titled(title, text(20))?;
        let (area, column) = legend::split(&area);
        // The plotting area's size does not depend on the ranges: measure it, then widen the
        // range of the shorter side so that a metre is as many pixels across as up.
        let (w, h) = builder(&area)
            .build_cartesian_2d(0.0..1.0, 0.0..1.0)?
            .plotting_area()
            .dim_in_pixel();
        let (x, y) = equal_aspect(x, y, (w as f64, h as f64));
        let mut chart = builder(&area).build_cartesian_2d(x.0..x.1, y.0..y.1)?;
        chart
            .configure_mesh()
            .light_line_style(RGBColor(240, 240, 240))
            .max_light_lines(4)
            .x_desc("x (m)")
            .y_desc("y (m)")
            .x_label_formatter(&|v| fmt_tick(*v))
            .y_label_formatter(&|v| fmt_tick(*v))
            .label_style(text(14))
            .axis_desc_style(text(15))
            .draw()?;
        let mut line: Vec<(f64, f64)> = track.iter().map(|p| (p[0], p[1])).collect();
        line.extend(line.first().copied());
        chart.draw_series(LineSeries::new(line, colour(TRACK).stroke_width(6)))?;
        let mut entries = vec![(
            "track".to_string(),
            Swatch::Line {
                colour: TRACK,
                width: 6,
            },
        )];
        for p in paths.iter().filter(|p| !p.points.is_empty()) {
            let c = colour(p.colour);
            chart.draw_series(p.points.iter().map(|q| Circle::new(*q, 2, c.filled())))?;
            entries.push((p.name.to_string(), Swatch::Dot { colour: p.colour }));
        }
        legend::draw(&column, 20, &entries)?;
        Ok(())
    })
}

fn builder<'a, 'b>(area: &'a Area<'b>) -> ChartBuilder<'a, 'b, BitMapBackend<'b>> {
    let mut b = ChartBuilder::on(area);
    b.margin(12).x_label_area_size(44).y_label_area_size(60);
    b
}

/// Ranges around `x` and `y` whose units per pixel match on a `w` x `h` pixel area.
fn equal_aspect(x: (f64, f64), y: (f64, f64), (w, h): (f64, f64)) -> ((f64, f64), (f64, f64)) {
    let per_px = ((x.1 - x.0) / w).max((y.1 - y.0) / h);
    let grow = |r: (f64, f64), px: f64| {
        let half = per_px * px / 2.0;
        let mid = (r.0 + r.1) / 2.0;
        (mid - half, mid + half)
    };
    (grow(x, w), grow(y, h))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_png::{decode, near};
    use crate::{BLUE, ORANGE};

    #[test]
    fn draws_the_track_and_each_drivers_points() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("trace.png");
        let circle = |r: f64, k: usize| {
            let a = k as f64 * 0.05;
            (r * a.cos(), 0.5 * r * a.sin())
        };
        let track: Vec<[f64; 2]> = (0..126)
            .map(|k| circle(2.0, k))
            .map(|p| [p.0, p.1])
            .collect();
        let paths = [
            Path2d {
                name: "reactive",
                colour: ORANGE,
                points: (0..60).map(|k| circle(2.05, k)).collect(),
            },
            Path2d {
                name: "active inference",
                colour: BLUE,
                points: (60..126).map(|k| circle(2.05, k)).collect(),
            },
            Path2d {
                name: "teacher",
                colour: [140, 0, 160],
                points: vec![],
            },
        ];
        lap_trace(&path, "lap trace", &track, &paths).unwrap();
        let (w, h, px) = decode(&path);
        // The oval is twice as wide as tall: the picture is shorter than the tallest.
        assert_eq!(w, SIZE.0);
        assert!((MIN_HEIGHT..SIZE.1).contains(&h), "{h}");
        assert!(near(&px, BLUE) > 300 && near(&px, ORANGE) > 300);
        assert!(near(&px, [200, 200, 200]) > 1000, "the track");
    }

    #[test]
    fn equal_aspect_keeps_a_metre_the_same_size_both_ways() {
        let (x, y) = equal_aspect((0.0, 4.0), (0.0, 1.0), (800.0, 400.0));
        assert!(((x.1 - x.0) / 800.0 - (y.1 - y.0) / 400.0).abs() < 1e-12);
        assert!(
            x.0 <= 0.0 && x.1 >= 4.0 && y.0 <= 0.0 && y.1 >= 1.0,
            "{x:?} {y:?}"
        );
    }
}
