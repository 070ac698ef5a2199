//! `results.csv` (one row per run) and `summary.md` (per variant and phase the median and
//! interquartile range over seeds of each metric; per pair of variants a bootstrap interval of
//! the difference of medians), from the finished cells.

use std::fmt::Write as _;
use std::path::Path;

use crate::matrix::{CellRecord, Failure, MadeWith, Phase};
use crate::metrics::NAMES;
use crate::spec::Spec;
use crate::stats::{Spread, bootstrap_median_difference};

/// One value per seed of `variant` in `phase` for metric `m` (index into [`NAMES`]): the learn
/// run's, or the mean over the seed's evaluation tracks that have one. Seeds without a value
/// are left out.
pub fn seed_values(records: &[CellRecord], variant: &str, phase: Phase, m: usize) -> Vec<f64> {
    records
        .iter()
        .filter(|r| r.key.variant == variant)
        .filter_map(|r| {
            let v: Vec<f64> = (r.rows.iter())
                .filter(|row| row.phase == phase)
                .filter_map(|row| row.metrics.values()[m])
                .collect();
            (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
        })
        .collect()
}

pub fn results_csv(path: &Path, records: &[CellRecord]) -> anyhow::Result<()> {
    // Quoted where a field needs it (a track file named `a,b.csv`).
    let mut w = csv::Writer::from_writer(Vec::new());
    let names = NAMES.iter().map(|(name, _)| *name);
    w.write_record(
        ["variant", "seed", "phase", "track"]
            .into_iter()
            .chain(names),
    )?;
    for row in records.iter().flat_map(|r| &r.rows) {
        let key = [
            row.variant.clone(),
            row.seed.to_string(),
            row.phase.name().to_string(),
            row.track.clone(),
        ];
        let values = row.metrics.values().into_iter();
        w.write_record(
            key.into_iter()
                .chain(values.map(|v| v.map_or(String::new(), |v| v.to_string()))),
        )?;
    }
    let bytes = w.into_inner().map_err(|e| anyhow::anyhow!("{e}"))?;
    mtanet_summaries::files::write_bytes(path, &bytes)?;
    Ok(())
}

fn num(v: f64) -> String {
    match v.abs() {
        // Counts (laps, fallbacks, updates) and their medians stay whole.
        a if v.fract() == 0.0 && a < 1e9 => format!("{v:.0}"),
        a if a >= 100.0 => format!("{v:.0}"),
        a if a >= 1.0 => format!("{v:.2}"),
        _ => format!("{v:.3}"),
    }
}

/// What summary.md is built from.
pub struct Inputs<'a> {
    pub spec: &'a Spec,
    pub records: &'a [CellRecord],
    /// Failed cells (label, what failed).
    pub failures: &'a [(String, Failure)],
    pub cells: usize,
    pub base_config: &'a str,
}

pub fn summary_md(path: &Path, x: &Inputs) -> anyhow::Result<()> {
    let (s, mut md) = (x.spec, String::new());
    let tracks: Vec<String> = s
        .eval_tracks
        .iter()
        .map(|t| format!("`{}`", t.display()))
        .collect();
    let _ = writeln!(md, "# Experiment `{}`\n", s.name);
    if !s.description.is_empty() {
        let _ = writeln!(md, "{}\n", s.description.trim());
    }
    let _ = writeln!(
        md,
        "- learn: from scratch in lockstep on `{}`{} for {} simulated s\n\
         - eval: the learnt checkpoint with no learning on {} for {} simulated s each\n\
         - seeds {:?}, each setting {}\n\
         - base config `{}`; variants {}\n\
         - held-out drive: `{}`, {} s, seed {} (`heldout.npz`)\n\
         - cells: {} finished, {} failed, of {}; `results.csv` has one row per run",
        s.learn_track.display(),
        also_tracks(s),
        s.learn_sim_seconds,
        if tracks.is_empty() {
            "no track".into()
        } else {
            tracks.join(", ")
        },
        s.eval_sim_seconds,
        s.seeds,
        crate::config::SEED_KEYS.join(", "),
        x.base_config,
        s.variants
            .iter()
            .map(|v| format!("`{}`", v.name))
            .collect::<Vec<_>>()
            .join(", "),
        s.heldout.track.display(),
        s.heldout.sim_seconds,
        s.heldout.seed,
        x.records.len(),
        x.failures.len(),
        x.cells,
    );
    let _ = writeln!(md, "- made with: {}", made_with(x.records));
    if !x.failures.is_empty() {
        md.push_str("\n## Failed cells\n\n");
        for (label, f) in x.failures {
            let log = f.log.as_ref().map(|l| format!(" (log: `{}`)", l.display()));
            let _ = writeln!(
                md,
                "- `{label}`: {}{}",
                f.error.replace('\n', " "),
                log.unwrap_or_default()
            );
        }
    }
    for phase in Phase::ALL {
        spreads(&mut md, x, phase);
    }
    crate::versus::markdown(&mut md, x.records, &x.spec.variants);
    differences(&mut md, x);
    md.push_str("\n## Metrics\n\n| metric | meaning |\n|---|---|\n");
    for (name, meaning) in NAMES {
        let _ = writeln!(md, "| `{name}` | {meaning} |");
    }
    mtanet_summaries::files::write_bytes(path, md.as_bytes())?;
    Ok(())
}

fn spreads(md: &mut String, x: &Inputs, phase: Phase) {
    let variants = &x.spec.variants;
    let _ = writeln!(md, "\n## {}\n", phase.name());
    md.push_str(match phase {
        Phase::Learn => "Median [first quartile, third quartile] over seeds (n: seeds with a value).\n\n",
        Phase::Eval => "Each seed's value is its mean over the evaluation tracks that have one; then \
                        median [first quartile, third quartile] over seeds (n: seeds with a value).\n\n",
        Phase::Rule => "The reactive rule alone (no model, no exploration) on each evaluation track \
                        for the same time: each seed's value is its mean over the tracks; then \
                        median [first quartile, third quartile] over seeds.\n\n",
    });
    let _ = writeln!(md, "| metric | {} |", names(variants).join(" | "));
    let _ = writeln!(md, "|---|{}", "---|".repeat(variants.len()));
    for (m, (name, _)) in NAMES.iter().enumerate() {
        let cells: Vec<String> = variants
            .iter()
            .map(
                |v| match Spread::of(&seed_values(x.records, &v.name, phase, m)) {
                    Some(s) => format!(
                        "{} [{}, {}] (n {})",
                        num(s.median),
                        num(s.q1),
                        num(s.q3),
                        s.n
                    ),
                    None => "-".into(),
                },
            )
            .collect();
        let _ = writeln!(md, "| `{name}` | {} |", cells.join(" | "));
    }
}

fn differences(md: &mut String, x: &Inputs) {
    let (variants, b) = (&x.spec.variants, &x.spec.bootstrap);
    if variants.len() < 2 {
        return;
    }
    let _ = writeln!(
        md,
        "\n## Differences of medians\n\n`B - A`: median over seeds of B minus that of A, and its {:.0}% \
         percentile-bootstrap interval ({} resamples, each drawing every variant's seeds with \
         replacement; seed {}). `-`: fewer than two seeds with a value on either side. With a \
         handful of seeds the interval is coarse: read it as a rough range, not a test.",
        b.confidence * 100.0,
        b.resamples,
        b.seed
    );
    for (i, a) in variants.iter().enumerate() {
        for v in &variants[i + 1..] {
            let _ = writeln!(md, "\n### `{}` - `{}`\n", v.name, a.name);
            md.push_str("| metric | learn | eval | rule |\n|---|---|---|---|\n");
            for (m, (name, _)) in NAMES.iter().enumerate() {
                let cols: Vec<String> = Phase::ALL
                    .iter()
                    .map(|&p| {
                        let (va, vb) = (
                            seed_values(x.records, &a.name, p, m),
                            seed_values(x.records, &v.name, p, m),
                        );
                        let d = crate::stats::median(&vb).zip(crate::stats::median(&va));
                        let ci = bootstrap_median_difference(
                            &vb,
                            &va,
                            b.resamples,
                            b.confidence,
                            b.seed,
                        );
                        match (d, ci) {
                            (Some((mb, ma)), Some((lo, hi))) => {
                                format!("{} [{}, {}]", num(mb - ma), num(lo), num(hi))
                            }
                            _ => "-".into(),
                        }
                    })
                    .collect();
                let _ = writeln!(md, "| `{name}` | {} |", cols.join(" | "));
            }
        }
    }
}

fn names(variants: &[crate::spec::Variant]) -> Vec<String> {
    variants.iter().map(|v| format!("`{}`", v.name)).collect()
}

/// The commits and CPUs the finished cells ran on, with how many cells each: more than one
/// commit says the experiment was resumed with other code.
fn made_with(records: &[CellRecord]) -> String {
    let mut seen: Vec<(&MadeWith, usize)> = Vec::new();
    for r in records {
        match seen.iter_mut().find(|(m, _)| **m == r.made_with) {
            Some((_, n)) => *n += 1,
            None => seen.push((&r.made_with, 1)),
        }
    }
    if seen.is_empty() {
        return "no cell finished".into();
    }
    seen.iter()
        .map(|(m, n)| {
            let commit = if m.commit.is_empty() {
                "commit not recorded".into()
            } else {
                format!("commit `{}`", m.commit)
            };
            let cpu = if m.cpu.is_empty() {
                "a CPU not recorded"
            } else {
                &m.cpu
            };
            format!(
                "{commit} on {cpu} ({n} cell{})",
                if *n == 1 { "" } else { "s" }
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// ", then `a`, `b` in turn" for a learning that also drives other tracks.
fn also_tracks(s: &Spec) -> String {
    if s.learn_also_tracks.is_empty() {
        return String::new();
    }
    let t: Vec<String> = s
        .learn_also_tracks
        .iter()
        .map(|t| format!("`{}`", t.display()))
        .collect();
    format!(
        " then {} in turn (`[simulator] switch_track_after_s` each)",
        t.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matrix::CellKey;
    use crate::matrix::Row;
    use crate::metrics::Metrics;

    fn record(variant: &str, seed: u64, learn_laps: f64, eval_laps: &[Option<f64>]) -> CellRecord {
        let row = |phase, track: &str, laps| Row {
            variant: variant.into(),
            seed,
            phase,
            track: track.into(),
            metrics: Metrics {
                laps,
                ..Default::default()
            },
        };
        let mut rows = vec![row(Phase::Learn, "oval", Some(learn_laps))];
        rows.extend(
            eval_laps
                .iter()
                .enumerate()
                .map(|(i, l)| row(Phase::Eval, &format!("g{i}"), *l)),
        );
        CellRecord {
            key: CellKey {
                variant: variant.into(),
                seed,
                learn_track: "oval".into(),
                learn_sim_seconds: 1.0,
                learn_also_tracks: vec![],
                eval_tracks: vec![],
                eval_sim_seconds: 1.0,
                heldout: Default::default(),
                config: String::new(),
            },
            rows,
            wall_seconds: 0.0,
            made_with: Default::default(),
        }
    }

    #[test]
    fn a_seed_is_its_learn_run_or_its_mean_over_eval_tracks() {
        let laps = NAMES.iter().position(|n| n.0 == "laps").unwrap();
        let recs = [
            record("a", 0, 3.0, &[Some(1.0), Some(3.0)]),
            record("a", 1, 5.0, &[None, Some(4.0)]),
            record("b", 0, 9.0, &[None, None]),
        ];
        assert_eq!(seed_values(&recs, "a", Phase::Learn, laps), vec![3.0, 5.0]);
        assert_eq!(seed_values(&recs, "a", Phase::Eval, laps), vec![2.0, 4.0]);
        assert!(seed_values(&recs, "b", Phase::Eval, laps).is_empty());
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("r.csv");
        results_csv(&csv, &recs).unwrap();
        let text = std::fs::read_to_string(&csv).unwrap();
        assert_eq!(text.lines().count(), 1 + 9);
        assert!(
            text.starts_with("variant,seed,phase,track,takeover_s,laps,"),
            "{text}"
        );
        assert!(
            text.contains("\na,1,eval,g0,,,"),
            "a missing value is an empty field: {text}"
        );
        // A track whose name holds a comma stays one field.
        let mut odd = record("c", 0, 1.0, &[]);
        odd.rows[0].track = "tracks/a,b.csv".into();
        results_csv(&csv, &[odd]).unwrap();
        let mut r = csv::Reader::from_path(&csv).unwrap();
        let headers = r.headers().unwrap().len();
        let rows: Vec<csv::StringRecord> = r.records().map(|x| x.unwrap()).collect();
        assert_eq!(rows[0].len(), headers);
        assert_eq!(&rows[0][3], "tracks/a,b.csv");
    }

    #[test]
    fn made_with_counts_cells_per_commit_and_cpu_and_says_what_was_not_recorded() {
        let with = |commit: &str| MadeWith {
            commit: commit.into(),
            cpu: "X (no AVX-512), 2 CPUs".into(),
        };
        let mut recs = vec![
            record("a", 0, 1.0, &[]),
            record("a", 1, 1.0, &[]),
            record("b", 0, 1.0, &[]),
        ];
        recs[0].made_with = with("abc");
        recs[1].made_with = with("abc");
        assert_eq!(
            made_with(&recs),
            "commit `abc` on X (no AVX-512), 2 CPUs (2 cells); \
             commit not recorded on a CPU not recorded (1 cell)"
        );
        assert_eq!(made_with(&[]), "no cell finished");
        // An old cell.json without the field still reads.
        let mut json = serde_json::to_value(&recs[2]).unwrap();
        json.as_object_mut().unwrap().remove("made_with");
        let old: CellRecord = serde_json::from_value(json).unwrap();
        assert_eq!(old.made_with, MadeWith::default());
        // This build knows its commit and this machine its CPU.
        let here = MadeWith::here();
        assert!(
            !here.commit.is_empty() && here.cpu.contains("CPUs"),
            "{here:?}"
        );
    }
}
