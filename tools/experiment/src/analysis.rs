//! Each finished cell's learnt checkpoint analysed (`mta analyze`: per-layer timescales and
//! context read-outs) on the experiment's analysis drive, the same for every cell. Made once
//! into `<cell>/analysis/` (again only if the experiment now asks for another drive, so cells
//! finished before the analysis existed get theirs on the next invocation); its figures join
//! the cell's learn row.

use mtanet_summaries::run_folder;
use std::path::Path;

use anyhow::Context;
use mtanet_offline::analyze::{Analysis, Options};
use mtanet_scenes::SceneConfig;

use crate::matrix::{Cell, CellRecord, Phase};
use crate::spec::Spec;

/// Adds the analysis' figures to `record`'s learn row, analysing first if needed; `Ok(false)`
/// when the experiment has no analysis drive (no evaluation track).
pub fn ensure(
    cell: &Cell,
    record: &mut CellRecord,
    spec: &Spec,
    scene: &SceneConfig,
) -> anyhow::Result<bool> {
    let Some(track) = spec.analysis_track() else {
        return Ok(false);
    };
    let out = cell.dir.join("analysis");
    let o = Options {
        sim_seconds: spec.analysis.sim_seconds,
        seed: spec.analysis.seed,
        ..Options::default()
    };
    let a = match made(&out.join("analysis.json"), track, &o) {
        Some(a) => a,
        None => {
            eprintln!(
                "[experiment] analysing {} on {}",
                cell.label(),
                track.display()
            );
            let model = cell.dir.join("learn").join(run_folder::MODEL);
            mtanet_offline::analyze::analyze_checkpoint(
                &model,
                &scene.clone().with_track(track),
                &o,
                &out,
            )
            .with_context(|| format!("analysing {}", model.display()))?
        }
    };
    for row in record.rows.iter_mut().filter(|r| r.phase == Phase::Learn) {
        row.metrics.add_analysis(&a);
    }
    Ok(true)
}

/// The analysis already in `path`, if it was made on this drive.
fn made(path: &Path, track: &Path, o: &Options) -> Option<Analysis> {
    let a: Analysis = mtanet_summaries::files::read_json(path).ok()?;
    let same = a.track == track.display().to_string()
        && a.options.sim_seconds == o.sim_seconds
        && a.options.seed == o.seed;
    same.then_some(a)
}
