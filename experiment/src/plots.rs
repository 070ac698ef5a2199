//! `plots/<metric>.png`: per metric, the variants side by side (learn, then eval), every seed's
//! point and a bar at the median. Drawn with `mtanet-canvas` for now; all drawing code of the
//! experiment is here, so a plotting library can replace it in one place.

use std::path::Path;

use mtanet_canvas::{BLACK, Canvas, GREY, Rgb};

use crate::matrix::{CellRecord, Phase};
use crate::metrics::NAMES;
use crate::spec::Spec;
use crate::summary::seed_values;

const LEARN: Rgb = [0, 110, 220];
const EVAL: Rgb = [230, 130, 0];

/// One PNG per metric in `dir`; a metric with no value anywhere still gets one, saying so.
pub fn write(dir: &Path, spec: &Spec, records: &[CellRecord]) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)?;
    for (m, (name, meaning)) in NAMES.iter().enumerate() {
        // (phase, variant, values per seed), phases without any value left out.
        let mut columns = Vec::new();
        for phase in Phase::ALL {
            let cols: Vec<_> = (spec.variants.iter())
                .map(|v| {
                    (
                        phase,
                        v.name.as_str(),
                        seed_values(records, &v.name, phase, m),
                    )
                })
                .collect();
            if cols.iter().any(|c| !c.2.is_empty()) {
                columns.extend(cols);
            }
        }
        draw(&dir.join(format!("{name}.png")), name, meaning, &columns)?;
    }
    Ok(())
}

fn draw(
    path: &Path,
    name: &str,
    meaning: &str,
    columns: &[(Phase, &str, Vec<f64>)],
) -> anyhow::Result<()> {
    let (left, top, col_w, plot_h) = (90i64, 70i64, 110i64, 300i64);
    let w = (left + 20 + col_w * columns.len().max(2) as i64).max(560);
    let mut c = Canvas::new(w as usize, (top + plot_h + 60) as usize);
    c.text(10, 8, name, 2, BLACK);
    let chars = ((w - 20) / 8) as usize;
    for (i, line) in wrap(meaning, chars).iter().take(2).enumerate() {
        c.text(10, 30 + 12 * i as i64, line, 1, BLACK);
    }
    let all: Vec<f64> = columns.iter().flat_map(|c| c.2.iter().copied()).collect();
    let base = top + plot_h;
    c.line((left, base), (w - 10, base), BLACK);
    c.line((left, top), (left, base), BLACK);
    if all.is_empty() {
        c.text(left + 20, top + plot_h / 2, "no run has a value", 1, BLACK);
        return c.write(path);
    }
    let (mut lo, mut hi) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(*v), b.max(*v)));
    if hi - lo < 1e-9 {
        (lo, hi) = (lo - 1.0, hi + 1.0);
    }
    let pad = (hi - lo) * 0.08;
    let (lo, hi) = (lo - pad, hi + pad);
    let y = |v: f64| base - ((v - lo) / (hi - lo) * plot_h as f64) as i64;
    for k in 0..=4 {
        let v = lo + (hi - lo) * k as f64 / 4.0;
        c.line((left - 4, y(v)), (w - 10, y(v)), GREY);
        c.text(4, y(v) - 4, &tick(v), 1, BLACK);
    }
    for (i, (phase, variant, values)) in columns.iter().enumerate() {
        let x = left + col_w * i as i64 + col_w / 2;
        let colour = if *phase == Phase::Learn { LEARN } else { EVAL };
        // Seeds spread sideways so equal values stay visible.
        for (k, v) in values.iter().enumerate() {
            let dx = (k as i64 % 7 - 3) * 5;
            c.dot(x + dx, y(*v), 3, colour);
        }
        if let Some(med) = crate::stats::median(values) {
            c.rect((x - 25, y(med) - 1), (x + 25, y(med) + 1), BLACK);
        }
        let label: String = variant.chars().take(13).collect();
        c.text(x - 4 * label.len() as i64, base + 10, &label, 1, BLACK);
        c.text(x - 4 * 5, base + 24, phase.name(), 1, colour);
    }
    c.write(path)
}

fn tick(v: f64) -> String {
    match v.abs() {
        a if a >= 1000.0 => format!("{v:.0}"),
        a if a >= 10.0 => format!("{v:.1}"),
        _ => format!("{v:.3}"),
    }
}

fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = vec![String::new()];
    for word in text.split_whitespace() {
        let last = lines.last_mut().expect("one line at least");
        if !last.is_empty() && last.len() + 1 + word.len() > width {
            lines.push(word.to_string());
        } else {
            if !last.is_empty() {
                last.push(' ');
            }
            last.push_str(word);
        }
    }
    lines
}
