//! The console table of an analysis: timescales per layer, then the read-outs' R^2.

use std::io::Write;

use super::Analysis;
use mtanet_models::timescale::Timescale;

fn steps(t: &Timescale, step_s: f64) -> String {
    match (t.steps, t.interval) {
        (Some(s), Some([lo, hi])) => format!("{s:.1} [{lo:.1}, {hi:.1}] ({:.2} s)", s * step_s),
        (Some(s), None) => format!("{s:.1} ({:.2} s)", s * step_s),
        (None, _) if t.features_used == 0 => "constant".into(),
        (None, _) => format!("> {} steps", t.autocorrelation.len().saturating_sub(1)),
    }
}

/// Writes the table to `out`.
pub fn print_table(a: &Analysis, out: &mut impl Write) -> std::io::Result<()> {
    writeln!(
        out,
        "{} on {}: {} model steps of {:.2} s, {} laps at {:.2} m/s",
        a.checkpoint, a.track, a.model_steps, a.step_s, a.laps, a.mean_speed_mps
    )?;
    writeln!(
        out,
        "\nTimescale: e-folding time of the autocorrelation, model steps [95% block bootstrap] (seconds)"
    )?;
    writeln!(out, "{:<16} {:>5}  {:<32} units", "layer", "tau", "R_l")?;
    for (net, layers) in [("", &a.layers), (" untrained", &a.layers_untrained)] {
        for l in layers {
            let units: Vec<String> = l.units.iter().map(|u| steps(u, a.step_s)).collect();
            writeln!(
                out,
                "{:<16} {:>5.2}  {:<32} {}",
                format!("{}{net}", l.layer),
                l.tau,
                steps(&l.r, a.step_s),
                units.join("; ")
            )?;
        }
    }
    writeln!(
        out,
        "\nContext: cross-validated R^2 of ridge read-outs (folds by lap; frame baselines see one frame more than R_l)"
    )?;
    write!(out, "{:<14} {:>8}", "state", "features")?;
    for (name, _) in &a.targets {
        write!(out, " {name:>15}")?;
    }
    writeln!(out)?;
    for row in &a.context {
        write!(out, "{:<14} {:>8}", row.source, row.features)?;
        for r in &row.readouts {
            write!(out, " {:>15.3}", r.r2)?;
        }
        writeln!(out)?;
    }
    Ok(())
}
