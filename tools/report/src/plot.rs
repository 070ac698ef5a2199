//! `mta plot RUN_DIR`: the run's curves as PNGs, for a person who would rather look than read.
//!
//! - `learning.png`: the trainer's loss, gradient norm and update time per update, and the
//!   counterfactual probe (from `learning.jsonl`, one line per update);
//! - `model_error.png`: the live model's next-frame error over copy-last-frame and the probe
//!   the predictor holds, against simulated time, with who drove (from `progress.csv`);
//! - `latency.png`: the step-latency histograms (from the processes' summaries).
//!
//! `mta report` (the end of every `mta up`) draws them too; a missing input skips its picture.

use mtanet_summaries::rows::{self, ProgressRow};
use mtanet_summaries::{CommandSource, run_folder};
use std::path::{Path, PathBuf};

use anyhow::Context;

use mtanet_plot::{BLUE, GREEN, GREY, Panel, RED, Series};

#[derive(Debug, clap::Args)]
pub struct PlotArgs {
    /// The run folder (`runs/<timestamp>/` of `./ops/run_local.sh`).
    pub dir: PathBuf,
}

/// `learning.png` from `learning.jsonl`; false when the run has no learning log.
pub fn learning(dir: &Path) -> anyhow::Result<bool> {
    let gate = Gate::of(dir);
    let probe_ref = format!("min_probe {}", gate.min_probe);
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
            title: "Training loss",
            y_label: "loss (log scale)",
            series: vec![
                series("per update", GREY, xy(&|p| Some(p.loss))),
                series("mean of 25", BLUE, smooth(xy(&|p| Some(p.loss)))),
            ],
            refs: vec![],
            log_y: true,
            y_range: None,
        },
        Panel {
            title: "Gradient norm before clipping",
            y_label: "L2 norm (log scale)",
            series: vec![
                series("per update", GREY, xy(&|p| Some(p.grad_norm))),
                series("mean of 25", RED, smooth(xy(&|p| Some(p.grad_norm)))),
            ],
            refs: vec![(1.0, "clipped above 1")],
            log_y: true,
            y_range: None,
        },
        Panel {
            title: "Counterfactual probe of the weights",
            y_label: "rank correlation",
            series: vec![series("probe", GREEN, xy(&|p| p.probe))],
            refs: vec![(gate.min_probe, &probe_ref)],
            log_y: false,
            y_range: Some((-0.2, 1.0)),
        },
        Panel {
            title: "Time per training update",
            y_label: "ms",
            series: vec![series(
                "mean of 25",
                BLUE,
                smooth(xy(&|p| Some(p.update_ms))),
            )],
            refs: vec![],
            log_y: false,
            y_range: None,
        },
    ];
    mtanet_plot::lines_chart(&dir.join("learning.png"), "training update", &panels)?;
    Ok(true)
}

/// The trust thresholds the run was made with (its `stack.toml`), else the shipped defaults: the
/// plots' reference lines show the gate that applied.
struct Gate {
    min_probe: f64,
    trust_ratio: f64,
}

impl Gate {
    fn of(dir: &Path) -> Self {
        let table = mtanet_summaries::files::read_table(&dir.join(run_folder::STACK)).ok();
        let get = |key: &str, default: f64| {
            (table.as_ref())
                .and_then(|t| {
                    t.get("predictor")?
                        .get("active_inference")?
                        .get(key)?
                        .as_float()
                })
                .unwrap_or(default)
        };
        Self {
            min_probe: get("min_probe", 0.7),
            trust_ratio: get("trust_ratio", 0.8),
        }
    }
}

fn series(name: &str, colour: mtanet_plot::Rgb, points: Vec<(f64, f64)>) -> Series<'_> {
    Series {
        name,
        colour,
        points,
    }
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
    let gate = Gate::of(dir);
    let probe_ref = format!("min_probe {}", gate.min_probe);
    let trust_ref = format!("trusted below {}", gate.trust_ratio);
    let path = dir.join(run_folder::PROGRESS);
    if !path.exists() {
        return Ok(false);
    }
    let (mut ratio, mut probe, mut ai) = (vec![], vec![], vec![]);
    for r in rows::read::<ProgressRow>(&path)? {
        let t = r.sim_s;
        if let Some(v) = r.model_over_copy_last {
            ratio.push((t, v));
        }
        if let Some(p) = r.probe {
            probe.push((t, p));
        }
        let driving = r.driver == CommandSource::ActiveInference.name();
        ai.push((t, if driving { 1.0 } else { 0.0 }));
    }
    if ratio.is_empty() && ai.is_empty() {
        return Ok(false);
    }
    let panels = [
        Panel {
            title: "Live model's next-frame error over copy-last-frame's",
            y_label: "error ratio (log scale)",
            series: vec![series("model / copy-last", BLUE, ratio)],
            refs: vec![
                (1.0, "as good as copy-last"),
                (gate.trust_ratio, &trust_ref),
            ],
            log_y: true,
            y_range: None,
        },
        Panel {
            title: "Probe of the predictor's weights",
            y_label: "rank correlation",
            series: vec![series("probe", GREEN, probe)],
            refs: vec![(gate.min_probe, &probe_ref)],
            log_y: false,
            y_range: Some((-0.2, 1.0)),
        },
        Panel {
            title: "Who drives",
            y_label: "active inference (1) or not (0)",
            series: vec![series("active inference", RED, ai)],
            refs: vec![],
            log_y: false,
            y_range: Some((-0.1, 1.1)),
        },
    ];
    mtanet_plot::lines_chart(&dir.join("model_error.png"), "simulated time (s)", &panels)?;
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

    /// Pixels of `colour` (give or take antialiasing).
    fn pixels(path: &Path, colour: mtanet_plot::Rgb) -> usize {
        let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut buf).unwrap();
        buf[..info.buffer_size()]
            .chunks(3)
            .filter(|p| (0..3).all(|i| p[i].abs_diff(colour[i]) <= 40))
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
