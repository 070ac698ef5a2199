//! The run's pictures from its trace and summaries: `lap_trace.png` (the car's path over the
//! track, coloured by who drove) and the latency histograms (`latency.png`, `soak.png`).

use mtanet_summaries::run_folder;
use std::path::Path;

use anyhow::Context;
use mtanet_plot::{BLUE, GREEN, ORANGE, PURPLE, Path2d, RED, Rgb};
use mtanet_summaries::predictor::Summary as PredictorSummary;
use mtanet_summaries::simulator::Summary as SimulatorSummary;

use crate::report::read_json;

/// The drivers as `trace.csv` names them, their legend names and colours.
const DRIVERS: [(&str, &str, Rgb); 5] = [
    ("reactive", "reactive rule", GREEN),
    ("exploration", "exploration", ORANGE),
    ("active_inference", "active inference", BLUE),
    ("fallback", "fallback", RED),
    ("teacher", "teacher", PURPLE),
];

/// The car's path over the track, coloured by who drove.
pub(crate) fn lap_trace(dir: &Path, track: &Path) -> anyhow::Result<()> {
    let rows = mtanet_summaries::rows::read::<mtanet_summaries::rows::TraceRow>(
        &dir.join(run_folder::TRACE),
    )?;
    let mut paths: Vec<Path2d> = DRIVERS
        .iter()
        .map(|&(_, name, colour)| Path2d {
            name,
            colour,
            points: Vec::new(),
        })
        .collect();
    for r in rows {
        // An unknown source is drawn as the reactive rule's.
        let k = DRIVERS.iter().position(|d| d.0 == r.source).unwrap_or(0);
        paths[k].points.push((r.x, r.y));
    }
    let track = mtanet_track::Track::load(track).context("loading the run's track")?;
    mtanet_plot::lap_trace(
        &dir.join("lap_trace.png"),
        "The car's path over the track, by who drove",
        track.points(),
        &paths,
    )?;
    Ok(())
}

/// `latency.png` from the simulator's and the predictor's summaries in `dir`; false without a
/// simulator summary.
pub fn latency_from_summaries(dir: &Path) -> anyhow::Result<bool> {
    let Some(sim) =
        read_json::<SimulatorSummary>(&dir.join(run_folder::summary_of("mta-simulator")))?
    else {
        return Ok(false);
    };
    let pred: Option<PredictorSummary> =
        read_json(&dir.join(run_folder::summary_of("mta-predictor")))?;
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

/// Latency histograms, one row per leg (`latency.png`, the soak's `soak.png`).
pub fn latency_picture(path: &Path, series: &[(&str, &Vec<[f64; 2]>)]) -> anyhow::Result<()> {
    let rows: Vec<(&str, &[[f64; 2]])> = series.iter().map(|(n, h)| (*n, h.as_slice())).collect();
    mtanet_plot::latency_histograms(path, &rows)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_the_lap_trace_and_the_latency_rows() {
        let dir = tempfile::tempdir().unwrap();
        let track = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/tracks/oval.csv");
        let mut trace = String::from("step,episode,x,y,lateral_m,source\n");
        for k in 0..100 {
            let a = k as f64 * 0.063;
            let source = if k < 50 {
                "reactive"
            } else {
                "active_inference"
            };
            trace.push_str(&format!(
                "{k},0,{},{},0,{source}\n",
                0.8 * a.cos(),
                0.4 + 0.4 * a.sin()
            ));
        }
        trace.push_str("torn,line\n");
        std::fs::write(dir.path().join("trace.csv"), trace).unwrap();
        lap_trace(dir.path(), &track).unwrap();
        let bins: Vec<[f64; 2]> = (20..40)
            .map(|k| [10f64.powf(k as f64 / 10.0), 9.0])
            .collect();
        latency_picture(&dir.path().join("latency.png"), &[("step", &bins)]).unwrap();
        use mtanet_plot::test_png::{decode, near};
        // What was drawn, not just a canvas: both drivers' stretches of the path, and the bars.
        let (width, _, px) = decode(&dir.path().join("lap_trace.png"));
        assert!(width >= 900);
        assert!(near(&px, GREEN) > 500, "the reactive half of the path");
        assert!(
            near(&px, BLUE) > 500,
            "the active-inference half of the path"
        );
        let (width, _, px) = decode(&dir.path().join("latency.png"));
        assert!(width >= 900);
        assert!(near(&px, BLUE) > 2000, "the histogram's bars");
    }
}
