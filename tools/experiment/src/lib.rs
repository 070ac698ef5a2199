//! `mta experiment FILE.toml --out DIR`: one file describes a matrix of variants x seeds; each
//! cell learns from scratch in lockstep on one track and is then evaluated, with no learning, on
//! others; every run keeps its own folder (`DIR/<variant>/<seed>/`). Finished cells are not run
//! again; failed ones are reported and run again next time. Results: `results.csv`,
//! `summary.md`, `plots/<metric>.png`; each learnt checkpoint's timescales and read-outs (`mta
//! analyze`) in `<cell>/analysis/`. See docs/experiments.md.

pub mod analysis;
pub mod cell;
pub mod config;
pub mod heldout;
pub mod matrix;
pub mod metrics;
pub mod plots;
pub mod pool;
pub mod run;
pub mod spec;
pub mod stats;
pub mod summary;
pub mod versus;

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use mtanet_ipc::config::ConfigFile;
use mtanet_ipc::shutdown::Shutdown;

use crate::matrix::{Cell, CellRecord, Failure, State};

#[derive(Debug, clap::Args)]
pub struct ExperimentArgs {
    /// The experiment (TOML): seeds, learn track, eval tracks, variants (docs/experiments.md).
    pub file: PathBuf,
    /// Where the runs and results go; an interrupted experiment resumes from it.
    #[arg(long)]
    pub out: PathBuf,
    /// Cells run side by side, each run in its own iceoryx2 namespace.
    #[arg(long, default_value_t = 1)]
    pub jobs: usize,
    /// Base stack config the variants' overrides are merged over (default ops/mtanet.toml when
    /// it exists, else built-in defaults).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Check the experiment and every variant's config, print what would run, run nothing.
    #[arg(long)]
    pub check: bool,
    /// Run no cell: analyse the finished cells that lack their analysis and rebuild
    /// results.csv, summary.md and the plots from them (while another invocation still runs
    /// cells elsewhere, say, or to look at an interrupted experiment).
    #[arg(long, conflicts_with = "check")]
    pub summary_only: bool,
    /// Prefix of the runs' iceoryx2 namespaces (at most 24 letters, digits, '-' or '_'; each
    /// run adds `c<cell>r<run>`); default: one no other stack uses.
    #[arg(long)]
    pub namespace: Option<String>,
}

pub fn run(args: ExperimentArgs) -> anyhow::Result<()> {
    let shutdown = Shutdown::install().context("installing signal handlers")?;
    let spec = spec::Spec::load(&args.file)?;
    let (base, origin) = config::base(args.config.as_deref())?;
    let configs = (spec.variants.iter())
        .map(|v| {
            Ok((
                v.name.clone(),
                config::variant(&base, &spec, v, &args.file)?,
            ))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let prefix = namespace_prefix(args.namespace)?;
    let cells = matrix::cells(&spec, &args.out, &configs, &prefix)?;
    let states = cells
        .iter()
        .map(|c| c.state())
        .collect::<anyhow::Result<Vec<_>>>()?;
    let todo: Vec<usize> = (0..cells.len())
        .filter(|&i| !args.summary_only && !matches!(states[i], State::Done(_)))
        .collect();
    let done = states
        .iter()
        .filter(|s| matches!(s, State::Done(_)))
        .count();
    eprintln!(
        "[experiment] {}: {} cells ({} variants x {} seeds), {done} finished, {} to run; base config {origin}",
        spec.name,
        cells.len(),
        spec.variants.len(),
        spec.seeds.len(),
        todo.len(),
    );
    if args.check {
        for &i in &todo {
            eprintln!(
                "[experiment] would run {} in {}",
                cells[i].label(),
                cells[i].dir.display()
            );
        }
        return Ok(());
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let text =
        std::fs::read(&args.file).with_context(|| format!("reading {}", args.file.display()))?;
    mtanet_summaries::files::write_bytes(&args.out.join("experiment.toml"), &text)?;
    let heldout = args.out.join("heldout.npz");
    let scene = ConfigFile::parse(&toml::to_string(&base)?, Path::new(&origin))?
        .section::<mtanet_scenes::SceneConfig>("simulator.scene")?;
    tch::set_num_threads(1);
    heldout::ensure(&heldout, &spec.heldout, &scene)?;

    let outcomes = pool::run(&cells, todo, done, args.jobs, &heldout, &shutdown);
    let (mut records, failures) = gather(&cells, states, outcomes, &shutdown)?;
    analyse(&cells, &mut records, &spec, &scene, &shutdown);
    let records: Vec<CellRecord> = records.into_iter().flatten().collect();
    let failed: Vec<(String, Failure)> = (cells.iter().zip(failures))
        .filter_map(|(c, f)| Some((c.label(), f?)))
        .collect();
    let inputs = summary::Inputs {
        spec: &spec,
        records: &records,
        failures: &failed,
        cells: cells.len(),
        base_config: &origin,
    };
    write_results(&args.out, &inputs)?;
    if shutdown.requested() {
        bail!("stopped by a signal: run the same command again to resume");
    }
    failed_cells(&failed)
}

/// An error listing the failed cells (with their logs), if any.
fn failed_cells(failed: &[(String, Failure)]) -> anyhow::Result<()> {
    if failed.is_empty() {
        return Ok(());
    }
    let list: Vec<String> = failed
        .iter()
        .map(|(l, f)| {
            let log = f.log.as_ref().map(|p| p.display().to_string());
            format!("{l}: {}", log.unwrap_or_else(|| f.error.clone()))
        })
        .collect();
    bail!(
        "{} cell(s) failed (run again to retry them): {}",
        failed.len(),
        list.join("; ")
    )
}

/// `--namespace`, checked so that every run's namespace (`<prefix>c<cell>r<run>`) stays within
/// iceoryx2's 32 characters; default: one no other stack uses.
/// The offline analysis of each finished cell (kept with the cell: done once).
fn analyse(
    cells: &[Cell],
    records: &mut [Option<CellRecord>],
    spec: &spec::Spec,
    scene: &mtanet_scenes::SceneConfig,
    shutdown: &Shutdown,
) {
    for (cell, record) in cells.iter().zip(records.iter_mut()) {
        let Some(record) = record.as_mut() else {
            continue;
        };
        if shutdown.requested() {
            break;
        }
        // A cell without its analysis still counts: its figures are left empty.
        if let Err(e) = analysis::ensure(cell, record, spec, scene) {
            tracing::warn!(cell = %cell.label(), "no analysis: {e:#}");
        }
    }
}

/// results.csv, summary.md and the plots, from the cells finished so far.
fn write_results(out: &Path, inputs: &summary::Inputs) -> anyhow::Result<()> {
    summary::results_csv(&out.join("results.csv"), inputs.records)?;
    summary::summary_md(&out.join("summary.md"), inputs)?;
    plots::write(&out.join("plots"), inputs.spec, inputs.records)?;
    versus::plot(&out.join("plots"), inputs.records, &inputs.spec.variants)?;
    eprintln!(
        "[experiment] {} of {} cells finished; {}",
        inputs.records.len(),
        inputs.cells,
        out.join("summary.md").display()
    );
    Ok(())
}

fn namespace_prefix(given: Option<String>) -> anyhow::Result<String> {
    let ok = |p: &str| {
        p.len() <= 24
            && p.chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_".contains(c))
    };
    match given {
        Some(p) if ok(&p) => Ok(p),
        Some(p) => bail!("--namespace {p:?}: use at most 24 letters, digits, '-' or '_'"),
        None => Ok(mtanet_launch::stack::unique_namespace("exp")),
    }
}

/// Each cell's record or failure: as found on disk, updated by what this invocation ran (a
/// failure written to `failed.json`, a finished cell read back from its `cell.json`).
fn gather(
    cells: &[Cell],
    states: Vec<State>,
    outcomes: Vec<(usize, pool::Outcome)>,
    shutdown: &Shutdown,
) -> anyhow::Result<(Vec<Option<CellRecord>>, Vec<Option<Failure>>)> {
    let mut records: Vec<Option<CellRecord>> = Vec::with_capacity(cells.len());
    let mut failures: Vec<Option<Failure>> = Vec::with_capacity(cells.len());
    for s in states {
        let (r, f) = match s {
            State::Done(r) => (Some(r), None),
            State::Failed(f) => (None, Some(f)),
            State::Todo => (None, None),
        };
        records.push(r);
        failures.push(f);
    }
    for (i, out) in outcomes {
        match out {
            // As a later invocation will read it (JSON floats may differ in the last bit).
            Ok(_) => {
                let r = mtanet_summaries::files::read_json(&cells[i].record_path())?;
                (records[i], failures[i]) = (Some(r), None)
            }
            // A run stopped by our own SIGTERM is not a failure: the cell runs next time.
            Err(_) if shutdown.requested() => failures[i] = None,
            Err(e) => {
                let f = Failure {
                    error: format!("{:#}", e.error),
                    log: e.log,
                };
                mtanet_summaries::files::write_json(&cells[i].failure_path(), &f)?;
                failures[i] = Some(f);
            }
        }
    }
    Ok((records, failures))
}
