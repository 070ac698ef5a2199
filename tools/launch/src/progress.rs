//! What `mta up` shows while a run goes: the live line on the terminal and `progress.csv` in the
//! run folder, both from the latest observation and command.

use std::path::Path;
use std::time::Duration;

use anyhow::Context;
use mtanet_ipc::{Command, CommandSource, Observation};
use mtanet_summaries::rows::{self, ProgressRow};

/// `progress.csv` ([`ProgressRow`]), one row a second. A failed write stops the file, not the run.
pub(crate) struct ProgressCsv {
    out: Option<csv::Writer<std::fs::File>>,
}

impl ProgressCsv {
    pub(crate) fn create(path: &Path) -> anyhow::Result<Self> {
        let f =
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
        let out = rows::writer::<ProgressRow, _>(f)
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(Self { out: Some(out) })
    }

    pub(crate) fn row(
        &mut self,
        o: Option<&Observation>,
        c: Option<&Command>,
        laps: u32,
        wall: Duration,
    ) {
        let (Some(out), Some(v)) = (self.out.as_mut(), Latest::of(o, c)) else {
            return;
        };
        // Four decimals are all a curve needs.
        let f = |v: Option<f32>| v.map(|v| rows::round_to(f64::from(v), 4));
        let row = ProgressRow {
            wall_s: rows::round_to(wall.as_secs_f64(), 1),
            step: v.step,
            sim_s: rows::round_to(v.sim_s, 2),
            laps,
            driver: v.driver.unwrap_or("").to_owned(),
            model_over_copy_last: f(v.ratio),
            probe: f(v.probe),
            predictor_ms: f(v.predictor_ms),
        };
        let res = out.serialize(row).and_then(|_| Ok(out.flush()?));
        if let Err(e) = res {
            tracing::error!("progress.csv stops here: {e}");
            self.out = None;
        }
    }
}

/// What progress.csv and the progress line show of the newest observation and command.
struct Latest {
    step: u64,
    sim_s: f64,
    driver: Option<&'static str>,
    /// Non-finite values (no model yet) are left out.
    ratio: Option<f32>,
    probe: Option<f32>,
    predictor_ms: Option<f32>,
}

impl Latest {
    fn of(o: Option<&Observation>, c: Option<&Command>) -> Option<Self> {
        let o = o?;
        let finite = |v: Option<f32>| v.filter(|v| v.is_finite());
        Some(Self {
            step: o.step,
            sim_s: o.step as f64 * mtanet_ipc::CONTROL_PERIOD_S,
            driver: c
                .and_then(|c| CommandSource::from_u32(c.source))
                .map(CommandSource::name),
            ratio: finite(c.map(|c| c.model_error_ratio)),
            probe: finite(c.map(|c| c.probe)),
            predictor_ms: c.map(|c| (c.compute_ns as f64 / 1e6) as f32),
        })
    }
}

/// The live line: how far the run is (of how much, and the wall time left at the pace so far),
/// laps, who drives, and the model's standing.
pub(crate) fn progress(
    o: Option<&Observation>,
    c: Option<&Command>,
    laps: u32,
    wall: Duration,
    target_sim_s: Option<f64>,
) -> String {
    let wall = wall.as_secs_f64();
    let Some(v) = Latest::of(o, c) else {
        return format!("{wall:.0} s: waiting for the simulator");
    };
    let fmt = |v: Option<f32>| v.map_or("-".into(), |v| format!("{v:.2}"));
    let how_far = match target_sim_s {
        Some(t) if v.sim_s > 0.0 => {
            let left = wall * (t - v.sim_s).max(0.0) / v.sim_s;
            format!(
                "{:.0} of {t:.0} s sim ({:.0}%), {wall:.0} s wall, ~{} left",
                v.sim_s,
                100.0 * v.sim_s / t,
                humanize(left)
            )
        }
        _ => format!("{:.0} s sim, {wall:.0} s wall", v.sim_s),
    };
    format!(
        "{how_far} | laps {laps} | driver {} | model/copy-last {} | probe {}",
        v.driver.unwrap_or("-"),
        fmt(v.ratio),
        fmt(v.probe),
    )
}

/// Seconds as "42 s" or "3.5 min".
fn humanize(s: f64) -> String {
    if s < 90.0 {
        format!("{s:.0} s")
    } else {
        format!("{:.1} min", s / 60.0)
    }
}
