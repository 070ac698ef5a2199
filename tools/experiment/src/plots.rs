//! `plots/<metric>.png`: per metric, the variants side by side (learn, then eval), every seed's
//! point and a bar at the median, drawn by `mtanet-plot`'s dot plot; beside it
//! `plots/<metric>.csv`, the points drawn (`column,value`), for whoever wants the numbers.

use std::path::Path;

use crate::matrix::{CellRecord, Phase};
use crate::metrics::NAMES;
use crate::spec::Spec;
use crate::summary::seed_values;

/// One PNG and its CSV per metric in `dir`; a metric with no value anywhere still gets them (empty).
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
        let mut csv = String::from("column,value\n");
        for (label, values) in &columns {
            for v in values {
                csv.push_str(&format!("{label},{v}\n"));
            }
        }
        mtanet_summaries::files::write_bytes(&path.with_extension("csv"), csv.as_bytes())?;
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
