//! The run's pictures from its trace and summaries: `lap_trace.png` (the car's path over the
//! track, coloured by who drove) and the latency histograms (`latency.png`, `soak.png`).

use std::path::Path;

use anyhow::Context;
use mtanet_canvas::{BLACK, Canvas, GREY, Rgb};
use mtanet_summaries::predictor::Summary as PredictorSummary;
use mtanet_summaries::simulator::Summary as SimulatorSummary;

use crate::report::read_json;

fn colour(source: &str) -> Rgb {
    match source {
        "active_inference" => [0, 110, 220],
        "exploration" => [240, 150, 0],
        "fallback" => [220, 0, 0],
        "teacher" => [140, 0, 160],
        _ => [0, 160, 60],
    }
}

/// The car's path over the track, coloured by who drove.
pub(crate) fn lap_trace(dir: &Path, track: &Path) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(dir.join("trace.csv")).context("reading trace.csv")?;
    let pts: Vec<(f64, f64, String)> = text
        .lines()
        .skip(1)
        .filter_map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            Some((
                f.get(2)?.parse().ok()?,
                f.get(3)?.parse().ok()?,
                f.get(5)?.to_string(),
            ))
        })
        .collect();
    let track = mtanet_track::Track::load(track).context("loading the run's track")?;
    let line: Vec<[f64; 2]> = track.points().to_vec();
    let all = line
        .iter()
        .map(|p| (p[0], p[1]))
        .chain(pts.iter().map(|p| (p.0, p.1)));
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in all {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    let (w, h, m) = (900usize, 700usize, 50.0);
    let scale = ((w as f64 - 2.0 * m) / (x1 - x0).max(1e-3))
        .min((h as f64 - 2.0 * m - 40.0) / (y1 - y0).max(1e-3));
    let to = |x: f64, y: f64| {
        (
            (m + (x - x0) * scale) as i64,
            (h as f64 - m - (y - y0) * scale) as i64,
        )
    };
    let mut c = Canvas::new(w, h);
    for k in 0..line.len() {
        let (a, b) = (line[k], line[(k + 1) % line.len()]);
        c.line(to(a[0], a[1]), to(b[0], b[1]), GREY);
    }
    for (x, y, s) in &pts {
        let (px, py) = to(*x, *y);
        c.dot(px, py, 1, colour(s));
    }
    let mut x = 10;
    for s in [
        "reactive",
        "exploration",
        "active_inference",
        "fallback",
        "teacher",
    ] {
        c.rect((x, 12), (x + 12, 24), colour(s));
        c.text(x + 18, 12, s, 1, BLACK);
        x += 30 + 8 * s.len() as i64;
    }
    c.write(&dir.join("lap_trace.png"))
}

/// `latency.png` from the simulator's and the predictor's summaries in `dir`; false without a
/// simulator summary.
pub fn latency_from_summaries(dir: &Path) -> anyhow::Result<bool> {
    let Some(sim) = read_json::<SimulatorSummary>(&dir.join("mta-simulator.json"))? else {
        return Ok(false);
    };
    let pred: Option<PredictorSummary> = read_json(&dir.join("mta-predictor.json"))?;
    latency_from(dir, &sim, pred.as_ref())?;
    Ok(true)
}

/// `latency.png` in `dir` from summaries already read.
pub(crate) fn latency_from(
    dir: &Path,
    sim: &SimulatorSummary,
    pred: Option<&PredictorSummary>,
) -> anyhow::Result<()> {
    let empty = Vec::new();
    let pred_hist = pred.map_or(&empty, |p| &p.compute_hist);
    latency_picture(
        &dir.join("latency.png"),
        &[
            ("simulator step", &sim.step_time_hist),
            ("predictor compute", pred_hist),
        ],
    )
}

/// Log-x histograms, one row each.
pub fn latency_picture(path: &Path, series: &[(&str, &Vec<[f64; 2]>)]) -> anyhow::Result<()> {
    let (w, row_h, left) = (900usize, 200usize, 60i64);
    let mut c = Canvas::new(w, row_h * series.len() + 40);
    // 1 us .. 1 s over the width.
    let xs =
        |us: f64| left + ((us.max(1.0).log10() / 6.0) * (w as f64 - left as f64 - 20.0)) as i64;
    for (i, (name, hist)) in series.iter().enumerate() {
        let top = 10 + (i * row_h) as i64;
        let base = top + row_h as i64 - 40;
        c.text(left, top, name, 2, BLACK);
        c.line((left, base), (w as i64 - 20, base), BLACK);
        let peak = hist.iter().map(|b| b[1]).fold(0.0, f64::max).max(1.0);
        for b in hist.iter() {
            // Each bin is a tenth of a decade wide, ending at its upper bound.
            let lo = b[0] / 10f64.powf(0.1);
            let hgt = ((b[1] / peak).sqrt() * (row_h as f64 - 70.0)) as i64;
            c.rect(
                (xs(lo) + 1, base - hgt),
                (xs(b[0]).max(xs(lo) + 1), base),
                [0, 110, 220],
            );
        }
        for (k, lbl) in ["1us", "10us", "100us", "1ms", "10ms", "100ms", "1s"]
            .iter()
            .enumerate()
        {
            let x = xs(10f64.powi(k as i32));
            c.line((x, base), (x, base + 4), BLACK);
            c.text(x - 8, base + 8, lbl, 1, BLACK);
        }
    }
    c.text(
        left,
        (row_h * series.len()) as i64 + 10,
        "count (sqrt scale) per 1/10 decade",
        1,
        BLACK,
    );
    c.write(path)
}
