//! The learnt driver against the reactive rule alone, per evaluation track: medians over seeds
//! of each (lateral error, lap time) and whether the learnt driver is at least as close to the
//! line and no slower; a table in summary.md and `plots/lap_time_vs_lateral.png`.

use std::fmt::Write as _;
use std::path::Path;

use crate::matrix::{CellRecord, Phase};
use crate::metrics::NAMES;
use crate::stats::median;

/// One evaluation track of one variant: medians over the seeds with a value.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrackVersus {
    pub track: String,
    pub seeds: usize,
    /// The rule alone: lateral error over every step (m), lap time (s).
    pub rule_lateral_m: Option<f64>,
    pub rule_lap_s: Option<f64>,
    /// The learnt run over every step (its start and fallbacks included), and active
    /// inference's own steps.
    pub learnt_lateral_m: Option<f64>,
    pub ai_lateral_m: Option<f64>,
    /// Laps active inference drove whole.
    pub ai_lap_s: Option<f64>,
    /// Seeds in which active inference drove a whole lap.
    pub seeds_ai_drove: usize,
    pub ai_lap_share_after_first: Option<f64>,
    /// Summed over seeds, and the longest of any seed.
    pub fallbacks: f64,
    pub longest_fallback_s: f64,
}

impl TrackVersus {
    /// Closer to the line than the rule alone, on its own steps and over the whole run.
    pub fn closer(&self) -> Option<bool> {
        let r = self.rule_lateral_m?;
        Some(self.ai_lateral_m? <= r && self.learnt_lateral_m? <= r)
    }

    pub fn no_slower(&self) -> Option<bool> {
        Some(self.ai_lap_s? <= self.rule_lap_s?)
    }
}

fn metric(name: &str) -> usize {
    NAMES
        .iter()
        .position(|(n, _)| *n == name)
        .expect("a metric of NAMES")
}

/// Per evaluation track (in the records' order) of `variant`.
pub fn tracks(records: &[CellRecord], variant: &str) -> Vec<TrackVersus> {
    let cells: Vec<&CellRecord> = records
        .iter()
        .filter(|r| r.key.variant == variant)
        .collect();
    let mut names: Vec<&str> = Vec::new();
    for row in cells
        .iter()
        .flat_map(|c| &c.rows)
        .filter(|r| r.phase == Phase::Eval)
    {
        if !names.contains(&row.track.as_str()) {
            names.push(&row.track);
        }
    }
    names.into_iter().map(|t| one_track(&cells, t)).collect()
}

fn one_track(cells: &[&CellRecord], track: &str) -> TrackVersus {
    let values = |phase: Phase, name: &str| -> Vec<f64> {
        let m = metric(name);
        (cells.iter().flat_map(|c| &c.rows))
            .filter(|r| r.phase == phase && r.track == track)
            .filter_map(|r| r.metrics.values()[m])
            .collect()
    };
    let med = |phase, name| median(&values(phase, name));
    let ai_laps = values(Phase::Eval, "laps_active_inference");
    TrackVersus {
        track: track.to_string(),
        seeds: values(Phase::Eval, "laps").len(),
        rule_lateral_m: med(Phase::Rule, "lateral_all_m"),
        rule_lap_s: med(Phase::Rule, "lap_time_s"),
        learnt_lateral_m: med(Phase::Eval, "lateral_all_m"),
        ai_lateral_m: med(Phase::Eval, "lateral_active_inference_m"),
        ai_lap_s: med(Phase::Eval, "lap_time_active_inference_s"),
        seeds_ai_drove: ai_laps.iter().filter(|&&l| l > 0.0).count(),
        ai_lap_share_after_first: med(Phase::Eval, "laps_after_first_active_inference"),
        fallbacks: values(Phase::Eval, "fallbacks").iter().sum(),
        longest_fallback_s: (values(Phase::Eval, "longest_fallback_s").into_iter())
            .fold(0.0, f64::max),
    }
}

/// The summary.md section: per variant, a row per track.
pub fn markdown(md: &mut String, records: &[CellRecord], variants: &[crate::spec::Variant]) {
    md.push_str(
        "\n## The learnt driver against the rule alone, per evaluation track\n\n\
         Medians over seeds. Rule: the reactive rule alone on the track for the same time (no \
         model, no exploration). Learnt: the evaluation run over every step (its start before \
         the hand-over and any fallback included); AI: active inference's own steps and the laps \
         it drove whole. Closer: both learnt and AI lateral error at most the rule's. No slower: \
         AI lap time at most the rule's. AI drove: seeds in which it drove a whole lap.\n",
    );
    let mm = |v: Option<f64>| v.map_or("-".into(), |m| format!("{:.2}", m * 1e3));
    let s = |v: Option<f64>| v.map_or("-".into(), |t| format!("{t:.2}"));
    let yes = |v: Option<bool>| v.map_or("-", |b| if b { "yes" } else { "**no**" });
    for v in variants {
        let rows = tracks(records, &v.name);
        let _ = writeln!(
            md,
            "\n### `{}`\n\n| track | rule mm | learnt mm | AI mm | rule lap s | AI lap s | \
             closer | no slower | AI drove | AI laps after the first | fallbacks | longest \
             fallback s |\n|---|---|---|---|---|---|---|---|---|---|---|---|",
            v.name
        );
        for t in &rows {
            let _ = writeln!(
                md,
                "| `{}` | {} | {} | {} | {} | {} | {} | {} | {}/{} | {} | {} | {:.1} |",
                t.track,
                mm(t.rule_lateral_m),
                mm(t.learnt_lateral_m),
                mm(t.ai_lateral_m),
                s(t.rule_lap_s),
                s(t.ai_lap_s),
                yes(t.closer()),
                yes(t.no_slower()),
                t.seeds_ai_drove,
                t.seeds,
                t.ai_lap_share_after_first
                    .map_or("-".into(), |f| format!("{:.0}%", f * 100.0)),
                t.fallbacks,
                t.longest_fallback_s
            );
        }
        let count = |f: fn(&TrackVersus) -> Option<bool>| {
            rows.iter().filter(|t| f(t) == Some(true)).count()
        };
        let _ = writeln!(
            md,
            "\nCloser on {} of {} tracks, no slower on {} of {}.",
            count(TrackVersus::closer),
            rows.len(),
            count(TrackVersus::no_slower),
            rows.len()
        );
    }
}

/// `lap_time_vs_lateral[_<variant>].png`: per track the rule alone and the learnt driver.
pub fn plot(
    dir: &Path,
    records: &[CellRecord],
    variants: &[crate::spec::Variant],
) -> anyhow::Result<()> {
    for (i, v) in variants.iter().enumerate() {
        let rows = tracks(records, &v.name);
        let pairs: Vec<mtanet_plot::Pair> = rows
            .iter()
            .map(|t| mtanet_plot::Pair {
                name: short_track(&t.track),
                baseline: t.rule_lateral_m.map(|l| l * 1e3).zip(t.rule_lap_s),
                driver: t.ai_lateral_m.map(|l| l * 1e3).zip(t.ai_lap_s),
            })
            .collect();
        let name = match i {
            0 => "lap_time_vs_lateral.png".to_string(),
            _ => format!("lap_time_vs_lateral_{}.png", v.name),
        };
        let path = dir.join(name);
        let title = format!("{}: per track, median over seeds", v.name);
        mtanet_plot::pairs_chart(
            &path,
            &title,
            ("mean |lateral error| (mm)", "lap time (simulated s)"),
            ("the rule alone", "active inference (learnt)"),
            &pairs,
        )
        .map_err(|e| anyhow::anyhow!("drawing {}: {e}", path.display()))?;
    }
    Ok(())
}

/// `scenes/tracks/oval.csv` -> `oval`; `generated:101` stays.
fn short_track(track: &str) -> &str {
    let file = track.rsplit('/').next().unwrap_or(track);
    file.strip_suffix(".csv").unwrap_or(file)
}
