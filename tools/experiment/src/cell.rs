//! One cell from an empty folder: learn from scratch on the learn track, score the learnt
//! checkpoint on the held-out drive, drive each evaluation track from it with no learning and
//! with the reactive rule alone (the baseline), then `cell.json` (atomically, last: only a whole cell counts as done).

use mtanet_summaries::run_folder;
use std::path::Path;
use std::time::Instant;

use anyhow::Context;

use crate::matrix::{Cell, CellRecord, MadeWith, Phase, Row};
use crate::metrics::Metrics;
use crate::run::{Live, Run, up};
use crate::spec::track_slug;

/// The error of a failed cell, and the log of the run it failed in.
pub struct CellError {
    pub error: anyhow::Error,
    pub log: Option<std::path::PathBuf>,
}

pub fn run(cell: &Cell, heldout: &Path, live: &Live, slot: usize) -> Result<CellRecord, CellError> {
    let start = Instant::now();
    let no_log = |error: anyhow::Error| CellError { error, log: None };
    cell.reset().map_err(no_log)?;
    let config = cell.eval_config();
    let learn_config = cell.learn_config();
    let key = &cell.key;
    let row = |phase, track: &Path, metrics| Row {
        variant: key.variant.clone(),
        seed: key.seed,
        phase,
        track: track.display().to_string(),
        metrics,
    };
    let learn = Run {
        label: format!("{} learn", cell.label()),
        track: &key.learn_track,
        sim_seconds: key.learn_sim_seconds,
        out: cell.dir.join("learn"),
        config: &learn_config,
        checkpoint: None,
        rule: false,
        namespace: format!("{}r0", cell.namespace),
    };
    let in_run = |run: &Run, r: anyhow::Result<Metrics>| {
        r.map_err(|error| CellError {
            error,
            log: Some(run.log()),
        })
    };
    let metrics = in_run(&learn, learn_run(&learn, heldout, live, slot))?;
    let mut rows = vec![row(Phase::Learn, &key.learn_track, metrics)];
    let model = learn.out.join(run_folder::MODEL);
    let n = key.eval_tracks.len();
    for (k, track) in key.eval_tracks.iter().enumerate() {
        // The learnt driver, then the rule alone on the same track for the same time.
        for (phase, r) in [(Phase::Eval, k + 1), (Phase::Rule, n + k + 1)] {
            let rule = phase == Phase::Rule;
            let run = Run {
                label: format!("{} {} {}", cell.label(), phase.name(), track.display()),
                track,
                sim_seconds: key.eval_sim_seconds,
                out: cell
                    .dir
                    .join(format!("{}-{}", phase.name(), track_slug(track))),
                config: &config,
                checkpoint: (!rule).then_some(model.as_path()),
                rule,
                namespace: format!("{}r{r}", cell.namespace),
            };
            let m = up(&run, live, slot).and_then(|()| Metrics::of_run(&run.out));
            rows.push(row(phase, track, in_run(&run, m)?));
        }
    }
    let record = CellRecord {
        key: key.clone(),
        rows,
        wall_seconds: start.elapsed().as_secs_f64(),
        made_with: MadeWith::here(),
    };
    mtanet_summaries::files::write_json(&cell.record_path(), &record)
        .map_err(|e| no_log(e.into()))?;
    Ok(record)
}

fn learn_run(run: &Run, heldout: &Path, live: &Live, slot: usize) -> anyhow::Result<Metrics> {
    up(run, live, slot)?;
    let model = run.out.join(run_folder::MODEL);
    anyhow::ensure!(
        model.exists(),
        "the learn run left no model.safetensors: the trainer made no update in {} simulated s \
         (it starts once [trainer] min_sequences chunks of 20 steps are buffered)",
        run.sim_seconds
    );
    let mut m = Metrics::of_run(&run.out)?;
    m.heldout_over_copy_last = Some(
        crate::heldout::ratio(&model, heldout)
            .with_context(|| format!("scoring {} on the held-out drive", model.display()))?,
    );
    Ok(m)
}
