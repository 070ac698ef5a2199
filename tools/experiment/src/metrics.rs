//! The figures of one run, from its folder: the typed `report.json` (`mta report`) and the
//! simulator's `trace.csv` (`step,episode,x,y,lateral_m,source`, every n-th step), for the
//! takeover time. The held-out next-frame error is the cell's (`heldout.rs`).

use mtanet_summaries::rows::{self, TraceRow};
use mtanet_summaries::run_folder;
use std::path::Path;

use mtanet_report::Report;
use serde::{Deserialize, Serialize};

/// Active inference must hold the wheel this share of...
pub const TAKEOVER_SHARE: f64 = 0.9;
/// ...this many simulated seconds from when it first drove.
pub const TAKEOVER_WINDOW_S: f64 = 60.0;

/// One run's metrics; `None` where the run has no such figure (no takeover, a driver that
/// never drove, no trainer in an evaluation run). The `timescale_*` and `context_*` figures are
/// the learnt checkpoint's, from `mta analyze` on the first evaluation track (learn rows).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Metrics {
    pub takeover_s: Option<f64>,
    pub laps: Option<f64>,
    pub laps_active_inference: Option<f64>,
    pub fallbacks: Option<f64>,
    pub lateral_reactive_m: Option<f64>,
    pub lateral_active_inference_m: Option<f64>,
    pub lateral_fallback_m: Option<f64>,
    pub lateral_all_m: Option<f64>,
    pub lap_time_s: Option<f64>,
    pub lap_time_active_inference_s: Option<f64>,
    pub longest_fallback_s: Option<f64>,
    pub laps_after_first_active_inference: Option<f64>,
    pub heldout_over_copy_last: Option<f64>,
    pub probe: Option<f64>,
    pub trainer_updates: Option<f64>,
    pub timescale_r0_s: Option<f64>,
    pub timescale_r1_s: Option<f64>,
    pub timescale_r2_s: Option<f64>,
    pub timescale_units0_s: Option<f64>,
    pub timescale_units1_s: Option<f64>,
    pub timescale_units2_s: Option<f64>,
    pub context_curvature_1s_r0: Option<f64>,
    pub context_curvature_1s_r1: Option<f64>,
    pub context_curvature_1s_r2: Option<f64>,
    pub context_curvature_1s_frames5: Option<f64>,
    pub context_curvature_1s_r2_untrained: Option<f64>,
    pub context_since_bend_r0: Option<f64>,
    pub context_since_bend_r1: Option<f64>,
    pub context_since_bend_r2: Option<f64>,
    pub context_since_bend_frames5: Option<f64>,
    pub context_since_bend_r2_untrained: Option<f64>,
}

/// The metric columns in results.csv order, with what each means (summary.md, plots).
pub const NAMES: [(&str, &str); 31] = [
    (
        "takeover_s",
        "simulated s until active inference first drives and then holds the wheel >= 90% of the next 60 s",
    ),
    ("laps", "laps completed (all drivers, all episodes)"),
    (
        "laps_active_inference",
        "laps in which active inference decided every step",
    ),
    (
        "fallbacks",
        "times the line was lost under active inference and the rule took over",
    ),
    (
        "lateral_reactive_m",
        "mean absolute lateral error (m) over the reactive rule's own steps",
    ),
    (
        "lateral_active_inference_m",
        "mean absolute lateral error (m) over active inference's steps",
    ),
    (
        "lateral_fallback_m",
        "mean absolute lateral error (m) over the fallback's steps",
    ),
    (
        "lateral_all_m",
        "mean absolute lateral error (m) over every step (rule rows: the rule alone's)",
    ),
    (
        "lap_time_s",
        "median simulated s of a whole lap, every driver (rule rows: the rule alone's)",
    ),
    (
        "lap_time_active_inference_s",
        "median simulated s of a lap active inference drove from start to end",
    ),
    (
        "longest_fallback_s",
        "the longest stretch the fallback drove without a break (s)",
    ),
    (
        "laps_after_first_active_inference",
        "share of the laps after the first that active inference drove from start to end",
    ),
    (
        "heldout_over_copy_last",
        "the learnt checkpoint's next-frame MSE over copy-last on the fixed held-out drive (learn rows)",
    ),
    (
        "probe",
        "counterfactual probe (rank correlation): the trainer's last (learn), the checkpoint's (eval)",
    ),
    ("trainer_updates", "trainer updates in the run (learn rows)"),
    (
        "timescale_r0_s",
        "e-folding time (s) of R_0's autocorrelation on the analysis drive (learn rows)",
    ),
    (
        "timescale_r1_s",
        "e-folding time (s) of R_1's autocorrelation",
    ),
    (
        "timescale_r2_s",
        "e-folding time (s) of R_2's autocorrelation",
    ),
    (
        "timescale_units0_s",
        "e-folding time (s) of layer 0's generative units' outputs, mean over units",
    ),
    ("timescale_units1_s", "the same for layer 1's units"),
    ("timescale_units2_s", "the same for layer 2's units"),
    (
        "context_curvature_1s_r0",
        "R^2 of the cross-validated read-out of the curvature 1 s ahead from R_0",
    ),
    ("context_curvature_1s_r1", "the same from R_1"),
    ("context_curvature_1s_r2", "the same from R_2"),
    (
        "context_curvature_1s_frames5",
        "the same from the last 5 frames stacked (baseline)",
    ),
    (
        "context_curvature_1s_r2_untrained",
        "the same from R_2 of the untrained network (baseline)",
    ),
    (
        "context_since_bend_r0",
        "R^2 of the cross-validated read-out of the line length since the last bend from R_0",
    ),
    ("context_since_bend_r1", "the same from R_1"),
    ("context_since_bend_r2", "the same from R_2"),
    (
        "context_since_bend_frames5",
        "the same from the last 5 frames stacked (baseline)",
    ),
    (
        "context_since_bend_r2_untrained",
        "the same from R_2 of the untrained network (baseline)",
    ),
];

impl Metrics {
    /// The values in [`NAMES`] order.
    pub fn values(&self) -> [Option<f64>; 31] {
        [
            self.takeover_s,
            self.laps,
            self.laps_active_inference,
            self.fallbacks,
            self.lateral_reactive_m,
            self.lateral_active_inference_m,
            self.lateral_fallback_m,
            self.lateral_all_m,
            self.lap_time_s,
            self.lap_time_active_inference_s,
            self.longest_fallback_s,
            self.laps_after_first_active_inference,
            self.heldout_over_copy_last,
            self.probe,
            self.trainer_updates,
            self.timescale_r0_s,
            self.timescale_r1_s,
            self.timescale_r2_s,
            self.timescale_units0_s,
            self.timescale_units1_s,
            self.timescale_units2_s,
            self.context_curvature_1s_r0,
            self.context_curvature_1s_r1,
            self.context_curvature_1s_r2,
            self.context_curvature_1s_frames5,
            self.context_curvature_1s_r2_untrained,
            self.context_since_bend_r0,
            self.context_since_bend_r1,
            self.context_since_bend_r2,
            self.context_since_bend_frames5,
            self.context_since_bend_r2_untrained,
        ]
    }

    /// Takes the learnt checkpoint's timescales and read-outs from its analysis.
    pub fn add_analysis(&mut self, a: &mtanet_offline::analyze::Analysis) {
        let seconds = |t: &mtanet_models::timescale::Timescale| t.steps.map(|s| s * a.step_s);
        let layer = |l: usize| a.layers.get(l);
        let r = |l| layer(l).and_then(|x| seconds(&x.r));
        let units = |l| layer(l)?.units_steps().map(|s| s * a.step_s);
        let r2 = |source: &str, target: &str| {
            a.context
                .iter()
                .find(|c| c.source == source)
                .and_then(|c| c.r2(&a.targets, target))
                .filter(|v| v.is_finite())
        };
        let (c, b) = ("curvature_1s", "since_bend_m");
        self.timescale_r0_s = r(0);
        self.timescale_r1_s = r(1);
        self.timescale_r2_s = r(2);
        self.timescale_units0_s = units(0);
        self.timescale_units1_s = units(1);
        self.timescale_units2_s = units(2);
        self.context_curvature_1s_r0 = r2("R_0", c);
        self.context_curvature_1s_r1 = r2("R_1", c);
        self.context_curvature_1s_r2 = r2("R_2", c);
        self.context_curvature_1s_frames5 = r2("frames_5", c);
        self.context_curvature_1s_r2_untrained = r2("R_2 untrained", c);
        self.context_since_bend_r0 = r2("R_0", b);
        self.context_since_bend_r1 = r2("R_1", b);
        self.context_since_bend_r2 = r2("R_2", b);
        self.context_since_bend_frames5 = r2("frames_5", b);
        self.context_since_bend_r2_untrained = r2("R_2 untrained", b);
    }

    /// A run folder's metrics (without the held-out error).
    pub fn of_run(dir: &Path) -> anyhow::Result<Self> {
        let r: Report = mtanet_summaries::files::read_json(&dir.join(run_folder::REPORT))?;
        let samples = ai_samples(&rows::read::<TraceRow>(&dir.join(run_folder::TRACE))?);
        Ok(Self {
            takeover_s: takeover_s(&samples, r.steps, TAKEOVER_WINDOW_S, TAKEOVER_SHARE),
            laps: Some(r.laps.completed as f64),
            laps_active_inference: Some(r.laps.completed_under_active_inference as f64),
            fallbacks: Some(r.control.fallbacks as f64),
            lateral_reactive_m: r.lateral_error_m.reactive_mean,
            lateral_active_inference_m: r.lateral_error_m.active_inference_mean,
            lateral_fallback_m: r.lateral_error_m.fallback_mean,
            lateral_all_m: Some(r.lateral_error_m.all_mean),
            lap_time_s: r.laps.lap_time_s,
            lap_time_active_inference_s: r.laps.lap_time_active_inference_s,
            longest_fallback_s: Some(r.control.longest_fallback_s),
            laps_after_first_active_inference: after_first_share(&r.laps),
            heldout_over_copy_last: None,
            probe: r.probe.rank_correlation,
            trainer_updates: r.trainer.updates.map(|u| u as f64),
            ..Self::default()
        })
    }
}

/// Laps active inference drove whole, over the laps after the first (that one begins before it
/// can take over); None with fewer than two laps.
fn after_first_share(laps: &mtanet_report::report::Laps) -> Option<f64> {
    let after_first = laps.completed.checked_sub(1).filter(|&n| n > 0)?;
    Some((laps.completed_under_active_inference as f64 / after_first as f64).min(1.0))
}

/// (step, active inference drove) per trace row.
pub fn ai_samples(rows: &[TraceRow]) -> Vec<(u64, bool)> {
    let ai = mtanet_ipc::CommandSource::ActiveInference.name();
    rows.iter().map(|r| (r.step, r.source == ai)).collect()
}

/// Simulated seconds until active inference first drives and then holds the wheel for at least
/// `share` of the next `window_s`: the earliest start of an active-inference stretch whose
/// window is so held. The window must lie within the run (`steps` control steps): a run too
/// short to show the hold has no takeover.
pub fn takeover_s(samples: &[(u64, bool)], steps: u64, window_s: f64, share: f64) -> Option<f64> {
    let period = mtanet_ipc::CONTROL_PERIOD_S;
    let window = (window_s / period).round() as u64;
    // ai[i]: active-inference rows among the first i.
    let mut ai = Vec::with_capacity(samples.len() + 1);
    ai.push(0usize);
    for s in samples {
        ai.push(ai.last().copied().unwrap_or(0) + s.1 as usize);
    }
    let mut was_ai = false;
    for (i, &(step, is_ai)) in samples.iter().enumerate() {
        let onset = is_ai && !was_ai;
        was_ai = is_ai;
        if !onset {
            continue;
        }
        if step + window > steps {
            return None;
        }
        let end = i + samples[i..].partition_point(|s| s.0 < step + window);
        let held = (ai[end] - ai[i]) as f64 / (end - i) as f64;
        if held >= share {
            return Some(step as f64 * period);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A trace every 5 steps (0.1 s) of `steps` steps where active inference drives in `ai`.
    fn trace(steps: u64, ai: impl Fn(u64) -> bool) -> Vec<(u64, bool)> {
        (0..steps).step_by(5).map(|s| (s, ai(s))).collect()
    }

    #[test]
    fn takeover_is_the_first_onset_that_holds() {
        // A 2 s try at 10 s, then from 100 s on for good: the try does not hold.
        let t = trace(10_000, |s| (500..600).contains(&s) || s >= 5000);
        assert_eq!(takeover_s(&t, 10_000, 60.0, 0.9), Some(100.0));
        // Active inference from 50 s, with short fallbacks (5% of the time): it holds.
        let t = trace(10_000, |s| s >= 2500 && s % 1000 >= 50);
        assert_eq!(takeover_s(&t, 10_000, 60.0, 0.9), Some(50.0));
        // Half the time only: never.
        let t = trace(10_000, |s| s % 1000 < 500);
        assert_eq!(takeover_s(&t, 10_000, 60.0, 0.9), None);
    }

    #[test]
    fn a_run_too_short_to_show_the_hold_has_no_takeover() {
        let t = trace(4000, |s| s >= 1500);
        assert_eq!(takeover_s(&t, 4000, 60.0, 0.9), None, "58 s left of 60");
        let t = trace(4500, |s| s >= 1500);
        assert_eq!(
            takeover_s(&t, 4500, 60.0, 0.9),
            Some(30.0),
            "exactly 60 s left"
        );
        assert_eq!(takeover_s(&[], 4500, 60.0, 0.9), None);
    }

    #[test]
    fn the_trace_is_read_by_its_header() {
        let text =
            "step,episode,x,y,lateral_m,source\n0,0,0,0,0,reactive\n5,0,0,0,0,active_inference\n";
        let parse_trace = |t: &str| rows::parse::<TraceRow>(t).map(|r| ai_samples(&r));
        assert_eq!(parse_trace(text).unwrap(), vec![(0, false), (5, true)]);
        assert!(
            parse_trace("step,episode\n0,0\n").is_err(),
            "no source column"
        );
        assert!(parse_trace("step,source\nx,reactive\n").is_err());
    }
}
