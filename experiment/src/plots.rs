//! `plots/<metric>.png`: per metric, the variants side by side (learn, then eval), every seed's
//! point and a bar at the median, drawn by `mtanet-plot`'s dot plot.

use std::path::Path;

use crate::matrix::{CellRecord, Phase};
use crate::metrics::NAMES;
use crate::spec::Spec;
use crate::summary::seed_values;

/// One PNG per metric in `dir`; a metric with no value anywhere still gets one (empty).
pub fn write(dir: &Path, spec: &Spec, records: &[CellRecord]) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)?;
    for (m, (name, meaning)) in NAMES.iter().enumerate() {
        // "variant (phase)" and its values per seed; phases without any value left out.
        let mut columns = Vec::new();
        for phase in Phase::ALL {
            let cols: Vec<(String, Vec<f64>)> = (spec.variants.iter())
                .map(|v| {
                    let label = format!("{} ({})", v.name, phase.name());
                    (label, seed_values(records, &v.name, phase, m))
                })
                .collect();
            if cols.iter().any(|c| !c.1.is_empty()) {
                columns.extend(cols);
            }
        }
        let path = dir.join(format!("{name}.png"));
        mtanet_plot::variants_dot_plot(&path, name, &short(meaning), &columns)
            .map_err(|e| anyhow::anyhow!("drawing {}: {e}", path.display()))?;
    }
    Ok(())
}

/// An axis label: the meaning's first clause, cut to fit.
fn short(meaning: &str) -> String {
    let first = meaning.split([';', '(']).next().unwrap_or(meaning).trim();
    if first.chars().count() <= 60 {
        first.to_string()
    } else {
        first.chars().take(57).collect::<String>() + "..."
    }
}
