//! `mta plot RUN_DIR`: the run's curves as PNGs, for a person who would rather look than read.
//!
//! - `learning.png`: the trainer's loss, gradient norm and update time per update, and the
//!   counterfactual probe (from `learning.jsonl`, one line per update);
//! - `model_error.png`: the live model's next-frame error over copy-last-frame and the probe
//!   the predictor holds, against simulated time, with who drove (from `progress.csv`);
//! - `latency.png`: the step-latency histograms (from the processes' summaries).
//!
//! `mta report` (the end of every `mta up`) draws them too; a missing input skips its picture.

use std::path::{Path, PathBuf};

use anyhow::Context;

use mtanet_canvas::{BLACK, Canvas, GREY, Rgb};

#[derive(Debug, clap::Args)]
pub struct PlotArgs {
    /// The run folder (`runs/<timestamp>/` of `./ops/run_local.sh`).
    pub dir: PathBuf,
}

const BLUE: Rgb = [0, 110, 220];
const RED: Rgb = [210, 40, 40];
const GREEN: Rgb = [20, 150, 60];

/// One panel of a chart: series of (x, y) points on shared axes.
pub struct Panel<'a> {
    pub title: &'a str,
    pub series: Vec<(&'a str, Rgb, Vec<(f64, f64)>)>,
    /// Horizontal reference lines (value, label).
    pub refs: Vec<(f64, &'a str)>,
    pub log_y: bool,
    /// Fixed y range; none: the data's.
    pub y_range: Option<(f64, f64)>,
}

fn fmt_tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.0e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 1.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.3}")
    }
}

/// Draws the panels one above the other, sharing the x axis labelled `x_label`.
pub fn chart(path: &Path, x_label: &str, panels: &[Panel]) -> anyhow::Result<()> {
    let (w, ph, left, right) = (900i64, 220i64, 80i64, 20i64);
    let mut c = Canvas::new(w as usize, (ph * panels.len() as i64 + 30) as usize);
    let all_x = panels
        .iter()
        .flat_map(|p| p.series.iter().flat_map(|s| s.2.iter().map(|q| q.0)));
    let (x0, x1) = bounds(all_x);
    let xs = |x: f64| left + ((x - x0) / (x1 - x0) * (w - left - right) as f64) as i64;
    for (i, p) in panels.iter().enumerate() {
        let top = i as i64 * ph + 24;
        let base = top + ph - 50;
        let ty = |v: f64| if p.log_y { v.max(1e-12).log10() } else { v };
        let (y0, y1) = p.y_range.unwrap_or_else(|| {
            bounds(
                p.series
                    .iter()
                    .flat_map(|s| s.2.iter().map(|q| q.1))
                    .chain(p.refs.iter().map(|r| r.0))
                    .filter(|v| v.is_finite() && (!p.log_y || *v > 0.0)),
            )
        });
        let (y0, y1) = if p.log_y { (ty(y0), ty(y1)) } else { (y0, y1) };
        let ys = |v: f64| base - ((ty(v) - y0) / (y1 - y0).max(1e-12) * (ph - 70) as f64) as i64;
        c.text(left, top - 18, p.title, 2, BLACK);
        c.line((left, base), (w - right, base), BLACK);
        c.line((left, base), (left, top), BLACK);
        for k in 0..=4 {
            let t = y0 + (y1 - y0) * k as f64 / 4.0;
            let v = if p.log_y { 10f64.powf(t) } else { t };
            let y = ys(v);
            c.line((left - 4, y), (left, y), BLACK);
            c.text(2, y - 4, &fmt_tick(v), 1, BLACK);
        }
        for (v, label) in &p.refs {
            let y = ys(*v);
            for x in (left..w - right).step_by(6) {
                c.line((x, y), (x + 2, y), GREY);
            }
            c.text(w - right - 8 * label.len() as i64, y - 10, label, 1, GREY);
        }
        let mut legend_x = left + 8 * p.title.len() as i64 * 2 + 24;
        for (name, colour, pts) in &p.series {
            let mut prev = None;
            for &(x, y) in pts.iter().filter(|q| q.1.is_finite()) {
                let here = (xs(x), ys(y).clamp(top, base));
                match prev {
                    Some(a) => c.line(a, here, *colour),
                    None => c.dot(here.0, here.1, 1, *colour),
                }
                prev = Some(here);
            }
            c.rect((legend_x, top - 14), (legend_x + 10, top - 6), *colour);
            c.text(legend_x + 14, top - 14, name, 1, BLACK);
            legend_x += 14 + 8 * name.len() as i64 + 16;
        }
        for k in 0..=5 {
            let x = x0 + (x1 - x0) * k as f64 / 5.0;
            c.line((xs(x), base), (xs(x), base + 4), BLACK);
            c.text(xs(x) - 12, base + 8, &fmt_tick(x), 1, BLACK);
        }
    }
    c.text(
        w / 2 - 4 * x_label.len() as i64,
        ph * panels.len() as i64 + 10,
        x_label,
        1,
        BLACK,
    );
    c.write(path)
}

/// Finite min and max, widened when they are equal (or absent).
fn bounds(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if !lo.is_finite() {
        (0.0, 1.0)
    } else if hi - lo < 1e-12 {
        (lo - 0.5 * lo.abs().max(1e-3), hi + 0.5 * hi.abs().max(1e-3))
    } else {
        (lo, hi)
    }
}

/// `learning.png` from `learning.jsonl`; false when the run has no learning log.
pub fn learning(dir: &Path) -> anyhow::Result<bool> {
    let log = dir.join("learning.jsonl");
    if !log.exists() {
        return Ok(false);
    }
    let (pts, bad) = mtanet_summaries::curve::read(&log)?;
    if bad > 0 {
        tracing::warn!(lines = bad, path = %log.display(), "unreadable lines skipped");
    }
    if pts.is_empty() {
        return Ok(false);
    }
    let xy = |f: &dyn Fn(&mtanet_summaries::curve::CurvePoint) -> Option<f64>| {
        pts.iter()
            .filter_map(|p| f(p).map(|y| (p.step as f64, y)))
            .collect::<Vec<_>>()
    };
    let smooth = |v: Vec<(f64, f64)>| moving_mean(&v, 25);
    let panels = [
        Panel {
            title: "loss (log)",
            series: vec![
                ("per update", GREY, xy(&|p| Some(p.loss))),
                ("mean of 25", BLUE, smooth(xy(&|p| Some(p.loss)))),
            ],
            refs: vec![],
            log_y: true,
            y_range: None,
        },
        Panel {
            title: "gradient norm (log)",
            series: vec![
                ("per update", GREY, xy(&|p| Some(p.grad_norm))),
                ("mean of 25", RED, smooth(xy(&|p| Some(p.grad_norm)))),
            ],
            refs: vec![(1.0, "clip")],
            log_y: true,
            y_range: None,
        },
        Panel {
            title: "counterfactual probe",
            series: vec![("rank correlation", GREEN, xy(&|p| p.probe))],
            refs: vec![(0.7, "min_probe 0.7")],
            log_y: false,
            y_range: Some((-0.2, 1.0)),
        },
        Panel {
            title: "update time, ms",
            series: vec![("mean of 25", BLUE, smooth(xy(&|p| Some(p.update_ms))))],
            refs: vec![],
            log_y: false,
            y_range: None,
        },
    ];
    chart(&dir.join("learning.png"), "training step", &panels)?;
    Ok(true)
}

fn moving_mean(v: &[(f64, f64)], n: usize) -> Vec<(f64, f64)> {
    (0..v.len())
        .map(|i| {
            let w = &v[i.saturating_sub(n - 1)..=i];
            (v[i].0, w.iter().map(|q| q.1).sum::<f64>() / w.len() as f64)
        })
        .collect()
}

/// `model_error.png` from `progress.csv`; false when the run has none.
pub fn model_error(dir: &Path) -> anyhow::Result<bool> {
    let path = dir.join("progress.csv");
    let Ok(text) = std::fs::read_to_string(&path) else {
        return Ok(false);
    };
    let mut header = None;
    let (mut ratio, mut probe, mut ai) = (vec![], vec![], vec![]);
    for line in text.lines() {
        let f: Vec<&str> = line.split(',').collect();
        let Some(h) = &header else {
            header = Some(f.iter().map(|s| s.to_string()).collect::<Vec<_>>());
            continue;
        };
        let col = |name: &str| h.iter().position(|c| c == name).and_then(|i| f.get(i));
        let num = |name: &str| col(name).and_then(|s| s.parse::<f64>().ok());
        let Some(t) = num("sim_s") else { continue };
        if let Some(r) = num("model_over_copy_last") {
            ratio.push((t, r));
        }
        if let Some(p) = num("probe") {
            probe.push((t, p));
        }
        let driving = col("driver").is_some_and(|d| *d == "active_inference");
        ai.push((t, if driving { 1.0 } else { 0.0 }));
    }
    if ratio.is_empty() && ai.is_empty() {
        return Ok(false);
    }
    let panels = [
        Panel {
            title: "live model error / copy-last (log)",
            series: vec![("model / copy-last", BLUE, ratio)],
            refs: vec![(1.0, "copy-last"), (0.8, "trust 0.8")],
            log_y: true,
            y_range: None,
        },
        Panel {
            title: "probe held by the predictor",
            series: vec![("rank correlation", GREEN, probe)],
            refs: vec![(0.7, "min_probe 0.7")],
            log_y: false,
            y_range: Some((-0.2, 1.0)),
        },
        Panel {
            title: "active inference drives (1) or not (0)",
            series: vec![("driver", RED, ai)],
            refs: vec![],
            log_y: false,
            y_range: Some((-0.1, 1.1)),
        },
    ];
    chart(&dir.join("model_error.png"), "simulated seconds", &panels)?;
    Ok(true)
}

pub fn run(args: PlotArgs) -> anyhow::Result<()> {
    let dir = &args.dir;
    anyhow::ensure!(dir.is_dir(), "{} is not a run folder", dir.display());
    let mut wrote = Vec::new();
    if learning(dir).context("drawing learning.png")? {
        wrote.push("learning.png");
    }
    if model_error(dir).context("drawing model_error.png")? {
        wrote.push("model_error.png");
    }
    if crate::pictures::latency_from_summaries(dir).context("drawing latency.png")? {
        wrote.push("latency.png");
    }
    anyhow::ensure!(
        !wrote.is_empty(),
        "{} has nothing to plot (no learning.jsonl, progress.csv or process summaries)",
        dir.display()
    );
    println!("wrote {} in {}", wrote.join(", "), dir.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixels(path: &Path, colour: Rgb) -> usize {
        let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut buf).unwrap();
        buf[..info.buffer_size()]
            .chunks(3)
            .filter(|p| *p == colour)
            .count()
    }

    #[test]
    fn draws_the_learning_curve_and_the_model_error_from_a_run_folder() {
        let dir = tempfile::tempdir().unwrap();
        let mut log = String::new();
        for s in 1..=300u64 {
            let probe = (s >= 250).then_some(0.75);
            log.push_str(&format!(
                "{{\"step\":{s},\"wall_s\":{},\"loss\":{},\"grad_norm\":0.9,\"clipped\":false,\"update_ms\":210.0,\"replay_sequences\":64,\"chunks_received\":70,\"chunks_lost\":0,\"steps_received\":1400,\"probe\":{}}}\n",
                s as f64 * 0.2,
                1.0 / s as f64,
                probe.map_or("null".into(), |p: f64| p.to_string())
            ));
        }
        log.push_str("{\"step\":301,\"wal"); // a torn last line
        std::fs::write(dir.path().join("learning.jsonl"), log).unwrap();
        std::fs::write(
            dir.path().join("progress.csv"),
            "wall_s,step,sim_s,laps,driver,model_over_copy_last,probe,predictor_ms\n\
             1.0,50,1.00,0,reactive,,,0.1\n2.0,100,2.00,0,reactive,1.2,,0.2\n\
             3.0,150,3.00,1,active_inference,0.5,0.8,0.9\n",
        )
        .unwrap();
        assert!(learning(dir.path()).unwrap());
        assert!(model_error(dir.path()).unwrap());
        // The curves are drawn, not just the axes: count the series' colours.
        assert!(pixels(&dir.path().join("learning.png"), BLUE) > 300);
        assert!(
            pixels(&dir.path().join("learning.png"), GREEN) > 30,
            "the probe"
        );
        assert!(
            pixels(&dir.path().join("model_error.png"), RED) > 30,
            "who drove"
        );
        // An empty folder draws nothing and says so.
        let empty = tempfile::tempdir().unwrap();
        let e = run(PlotArgs {
            dir: empty.path().into(),
        })
        .unwrap_err();
        assert!(format!("{e:#}").contains("nothing to plot"), "{e:#}");
    }

    #[test]
    fn moving_mean_averages_the_window_before_each_point() {
        let v: Vec<(f64, f64)> = (0..5).map(|i| (i as f64, i as f64)).collect();
        let m = moving_mean(&v, 2);
        assert_eq!(
            m,
            vec![(0.0, 0.0), (1.0, 0.5), (2.0, 1.5), (3.0, 2.5), (4.0, 3.5)]
        );
    }
}
