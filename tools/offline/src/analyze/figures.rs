//! The analysis' PNGs: `timescales.png` (each layer's autocorrelation against the lag, with 1/e
//! marked: where a curve crosses it is the layer's timescale), `context.png` (per target, the
//! read-outs' R^2 from each layer and from the frame baselines) and `strip.png` (the paper's
//! Figs. 5-7: the first unit's output of every layer at frames 1, 10, 50, 100, 130).

use std::path::Path;

use mtanet_plot::{BLUE, GREEN, ORANGE, PURPLE, Panel, RED, Rgb, Series};

use super::{Analysis, Sequence};

const PALETTE: [Rgb; 5] = [BLUE, ORANGE, GREEN, PURPLE, RED];

pub fn write(
    out: &Path,
    a: &Analysis,
    model: &mtanet_models::MtaPredNet,
    seq: &Sequence,
) -> anyhow::Result<()> {
    timescales(&out.join("timescales.png"), a)?;
    context(&out.join("context.png"), a)?;
    let frames = super::figure::DEFAULT_FRAMES;
    let last = (*frames.iter().max().unwrap_or(&1) + 1).min(seq.truth.len()) as i64;
    super::figure::figure_strip(
        model,
        &seq.images.narrow(0, 0, last),
        &seq.actions.narrow(0, 0, last),
        &frames,
        &out.join("strip.png"),
    )?;
    Ok(())
}

fn timescales(path: &Path, a: &Analysis) -> anyhow::Result<()> {
    let curve = |acf: &[f64]| -> Vec<(f64, f64)> {
        (acf.iter().enumerate())
            .map(|(k, v)| (k as f64 * a.step_s, *v))
            .collect()
    };
    let names: Vec<String> = (a.layers.iter())
        .map(|l| format!("layer {} (tau {})", l.layer, l.tau))
        .collect();
    let unit_names: Vec<String> = (a.layers.iter())
        .flat_map(|l| (0..l.units.len()).map(move |d| format!("layer {} unit {d}", l.layer)))
        .collect();
    let r_series = (a.layers.iter().zip(&names).enumerate())
        .map(|(i, (l, name))| Series {
            name,
            colour: PALETTE[i % PALETTE.len()],
            points: curve(&l.r.autocorrelation),
        })
        .collect();
    let unit_series = (a
        .layers
        .iter()
        .flat_map(|l| l.units.iter().map(move |u| (l.layer, u))))
    .zip(&unit_names)
    .map(|((layer, u), name)| Series {
        name,
        colour: PALETTE[layer % PALETTE.len()],
        points: curve(&u.autocorrelation),
    })
    .collect();
    let e = (-1.0f64).exp();
    let panels = [
        Panel {
            title: "R_l: autocorrelation over the drive",
            y_label: "autocorrelation",
            series: r_series,
            refs: vec![(e, "1/e")],
            log_y: false,
            y_range: Some((-0.2, 1.0)),
        },
        Panel {
            title: "each generative unit's output h",
            y_label: "autocorrelation",
            series: unit_series,
            refs: vec![(e, "1/e")],
            log_y: false,
            y_range: Some((-0.2, 1.0)),
        },
    ];
    mtanet_plot::lines_chart(path, "lag (s)", &panels)?;
    Ok(())
}

fn context(path: &Path, a: &Analysis) -> anyhow::Result<()> {
    // One line per target across the states, bottom layer to the frame baselines.
    let series = (a.targets.iter().enumerate())
        .map(|(t, (name, _))| Series {
            name,
            colour: PALETTE[t % PALETTE.len()],
            points: (a.context.iter().enumerate())
                .map(|(i, row)| (i as f64, row.readouts[t].r2.max(-0.5)))
                .collect(),
        })
        .collect();
    let sources: Vec<&str> = a.context.iter().map(|r| r.source.as_str()).collect();
    let panels = [Panel {
        title: "what a linear read-out finds: cross-validated R^2, folds by lap",
        y_label: "R^2 (below -0.5 drawn at -0.5)",
        series,
        refs: vec![(0.0, "the target's mean")],
        log_y: false,
        y_range: None,
    }];
    mtanet_plot::category_chart(path, "read out from", &sources, &panels)?;
    Ok(())
}
