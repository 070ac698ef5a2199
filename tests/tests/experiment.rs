//! `mta experiment` end to end with the real binaries: the shipped smoke experiment
//! (`ops/experiments/smoke.toml`: 2 variants x 1 seed, 60 simulated s learnt on the oval, 20 s
//! evaluated on a generated track) into a temporary folder under a private namespace prefix, two
//! cells side by side (`--jobs 2`). Every run must leave its row, and the table, the summary and
//! the plots' points must say what the run folders' reports say; a second invocation must find
//! every cell finished and run nothing; a cell run again alone (`--jobs 1`) must give the same row.

use std::path::{Path, PathBuf};
use std::process::Command;

use mtanet_experiment::metrics::NAMES;
use mtanet_report::Report;
use mtanet_system_tests::{bin, here, unique_namespace};

/// Runs `mta experiment FILE ARGS` from the repository root; its success and its output.
fn run(file: &Path, out: &Path, ns: &str, args: &[&str], log: &Path) -> (bool, String) {
    let status = Command::new(bin("mta"))
        .current_dir(here().join(".."))
        .arg("experiment")
        .arg(file)
        .args(["--namespace", ns])
        .args(args)
        .arg("--out")
        .arg(out)
        .stderr(std::fs::File::create(log).unwrap())
        .status()
        .expect("starting mta experiment");
    (
        status.success(),
        std::fs::read_to_string(log).unwrap_or_default(),
    )
}

fn experiment(out: &Path, ns: &str, args: &[&str], log: &Path) -> String {
    let (ok, text) = run(Path::new("ops/experiments/smoke.toml"), out, ns, args, log);
    assert!(ok, "mta experiment failed\n{text}");
    text
}

/// Every `report.json` and `cell.json` under `dir` with its modification time.
fn finished_files(dir: &Path) -> Vec<(PathBuf, std::time::SystemTime)> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.ends_with("report.json") || p.ends_with("cell.json") {
                found.push((p.clone(), e.metadata().unwrap().modified().unwrap()));
            }
        }
    }
    found.sort();
    found
}

/// results.csv as a header and rows sorted by (variant, seed, phase, track).
fn table(out: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
    let mut lines = csv
        .lines()
        .map(|l| l.split(',').map(String::from).collect());
    let header: Vec<String> = lines.next().unwrap();
    let mut rows: Vec<Vec<String>> = lines.collect();
    rows.sort();
    (header, rows)
}

/// The figures a row must repeat, read straight from its run folder's report.
fn from_report(r: &Report) -> [(&'static str, Option<f64>); 6] {
    [
        ("laps", Some(r.laps.completed as f64)),
        (
            "laps_active_inference",
            Some(r.laps.completed_under_active_inference as f64),
        ),
        ("fallbacks", Some(r.control.fallbacks as f64)),
        ("trainer_updates", r.trainer.updates.map(|u| u as f64)),
        ("lateral_all_m", Some(r.lateral_error_m.all_mean)),
        ("lap_time_s", r.laps.lap_time_s),
    ]
}

#[test]
fn the_smoke_experiment_runs_every_cell_agrees_with_its_run_folders_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("smoke");
    let ns = unique_namespace("xt");
    experiment(&out, &ns, &["--jobs", "2"], &dir.path().join("first.log"));

    let (header, rows) = table(&out);
    let mut want_header = vec!["variant", "seed", "phase", "track"];
    want_header.extend(NAMES.iter().map(|n| n.0));
    assert_eq!(header, want_header);
    let keys: Vec<String> = rows.iter().map(|r| r[..4].join(",")).collect();
    assert_eq!(
        keys,
        [
            "flat,0,eval,generated:101",
            "flat,0,learn,scenes/tracks/oval.csv",
            "flat,0,rule,generated:101",
            "paper,0,eval,generated:101",
            "paper,0,learn,scenes/tracks/oval.csv",
            "paper,0,rule,generated:101",
        ],
        "one row per run"
    );
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let value = |r: &[String], name: &str| -> Option<f64> {
        let v = &r[col(name)];
        (!v.is_empty()).then(|| v.parse().expect("a number"))
    };
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    for r in &rows {
        let (variant, phase) = (&r[0], &r[2]);
        let folder = match phase.as_str() {
            "learn" => "learn".to_string(),
            p => format!("{p}-generated-101"),
        };
        let run = out.join(variant).join("0").join(folder);
        let report: Report = mtanet_summaries::files::read_json(&run.join("report.json")).unwrap();
        for (name, want) in from_report(&report) {
            assert_eq!(
                value(r, name),
                want,
                "{name} of {} vs its row {r:?}",
                run.display()
            );
        }
        // The plot of a metric draws exactly the table's values, labelled "variant (phase)".
        let points = std::fs::read_to_string(out.join("plots/laps.csv")).unwrap();
        let laps = value(r, "laps").unwrap();
        assert!(
            points
                .lines()
                .any(|l| l == format!("{variant} ({phase}),{laps}")),
            "{variant} ({phase}) laps {laps} not in plots/laps.csv:\n{points}"
        );
        if phase == "learn" {
            // Publishing every 2 updates, the trainer can send several versions during one
            // plan; each must reach the predictor, or the run does not replay (the last check).
            let p: mtanet_summaries::predictor::Summary =
                mtanet_summaries::files::read_json(&run.join("mta-predictor.json")).unwrap();
            assert_eq!(p.weights_lost, 0, "{}: {p:?}", run.display());
            assert!(p.weights_received > 100, "{}: {p:?}", run.display());
            // The checkpoint's analysis: its figures in the row are those of analysis.json.
            let path = out.join(variant).join("0/analysis/analysis.json");
            let a: mtanet_offline::analyze::Analysis =
                mtanet_summaries::files::read_json(&path).unwrap();
            let r0 = a.layers[0].r.steps.map(|s| s * a.step_s);
            assert!(r0.is_some_and(|s| s > 0.0), "{path:?}: {:?}", a.layers[0]);
            assert_eq!(value(r, "timescale_r0_s"), r0);
            let since = a.context.iter().find(|c| c.source == "R_2").unwrap();
            assert_eq!(
                value(r, "context_since_bend_r2"),
                since.r2(&a.targets, "since_bend_m")
            );
            for png in ["timescales.png", "context.png", "strip.png"] {
                assert!(
                    path.with_file_name(png).exists(),
                    "no {png} beside {path:?}"
                );
            }
            let updates = value(r, "trainer_updates").expect("a learn run trains");
            let ratio = value(r, "heldout_over_copy_last").expect("a held-out ratio");
            assert!(updates >= 20.0 && ratio.is_finite() && ratio > 0.0, "{r:?}");
        }
        if phase == "rule" {
            // The rule alone: no active inference, no trainer.
            assert_eq!(value(r, "laps_active_inference"), Some(0.0), "{r:?}");
            assert_eq!(value(r, "trainer_updates"), None, "{r:?}");
        }
    }
    // One seed: the summary's median of a variant is its one value.
    let learn_updates: Vec<String> = ["flat", "paper"]
        .iter()
        .map(|v| {
            let r = rows.iter().find(|r| &r[0] == v && r[2] == "learn").unwrap();
            format!("{:.0} [", value(r, "trainer_updates").unwrap())
        })
        .collect();
    let line = md
        .lines()
        .find(|l| l.starts_with("| `trainer_updates` |"))
        .unwrap_or_else(|| panic!("no trainer_updates row:\n{md}"));
    for cell in &learn_updates {
        assert!(line.contains(cell.as_str()), "{cell} not in {line}");
    }
    for section in [
        "# Experiment `smoke`",
        "## learn",
        "## eval",
        "## rule",
        "## The learnt driver against the rule alone, per evaluation track",
        "| `generated:101` |",
        "## Differences of medians",
        "### `flat` - `paper`",
        "## Metrics",
    ] {
        assert!(md.contains(section), "no {section:?} in summary.md:\n{md}");
    }
    assert!(!md.contains("## Failed cells"), "{md}");
    // Each cell records the commit and CPU it ran on; the summary counts them.
    let cell: serde_json::Value =
        mtanet_summaries::files::read_json(&out.join("paper/0/cell.json")).unwrap();
    let commit = cell["made_with"]["commit"].as_str().unwrap_or_default();
    assert!(!commit.is_empty(), "no commit in cell.json: {cell}");
    assert!(
        md.contains(&format!("- made with: commit `{commit}` on ")) && md.contains("(2 cells)"),
        "{md}"
    );
    let names = NAMES.iter().map(|n| n.0).chain(["lap_time_vs_lateral"]);
    for name in names {
        let png = out.join("plots").join(format!("{name}.png"));
        let bytes = std::fs::read(&png).unwrap_or_default();
        assert!(bytes.starts_with(b"\x89PNG"), "{} missing", png.display());
    }
    let shm_prefix = format!("iox2_{ns}");
    let left: Vec<String> = std::fs::read_dir("/dev/shm")
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&shm_prefix))
        .collect();
    assert!(left.is_empty(), "the runs left shared memory: {left:?}");

    // Resume: every cell is finished, so nothing runs and nothing in a run folder changes.
    let before = finished_files(&out);
    assert_eq!(before.len(), 2 + 6, "2 cell.json, 6 report.json");
    let analysed = std::fs::metadata(out.join("paper/0/analysis/analysis.json"))
        .unwrap()
        .modified()
        .unwrap();
    let log = experiment(&out, &ns, &["--jobs", "2"], &dir.path().join("second.log"));
    assert!(log.contains("2 finished, 0 to run"), "{log}");
    assert_eq!(finished_files(&out), before, "a finished cell ran again");
    let again = std::fs::metadata(out.join("paper/0/analysis/analysis.json"))
        .unwrap()
        .modified()
        .unwrap();
    assert_eq!(again, analysed, "a finished analysis ran again");
    assert_eq!(table(&out), (header.clone(), rows.clone()));

    // --summary-only runs no cell but remakes a missing analysis and the table.
    std::fs::remove_dir_all(out.join("paper/0/analysis")).unwrap();
    std::fs::remove_file(out.join("results.csv")).unwrap();
    let log = experiment(
        &out,
        &ns,
        &["--summary-only"],
        &dir.path().join("summary.log"),
    );
    assert!(log.contains("2 finished, 0 to run"), "{log}");
    assert_eq!(finished_files(&out), before, "a finished cell ran again");
    assert_eq!(table(&out), (header.clone(), rows.clone()));

    // The same cell run alone learns and drives the same (lockstep is deterministic): its rows
    // come back identical, latencies and wall time aside (results.csv has neither).
    std::fs::remove_dir_all(out.join("flat")).unwrap();
    let log = experiment(&out, &ns, &["--jobs", "1"], &dir.path().join("third.log"));
    assert!(log.contains("1 finished, 1 to run"), "{log}");
    assert_eq!(table(&out), (header, rows), "--jobs 1 and --jobs 2 differ");
}

/// A cell whose learn run leaves no checkpoint (3 s: the trainer never starts) fails with its
/// log named, in failed.json and summary.md; the command fails; the next invocation retries it.
#[test]
fn a_failed_cell_is_reported_with_its_log_and_retried() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("fails.toml");
    std::fs::write(
        &file,
        "name = \"fails\"\nseeds = [0]\nlearn_track = \"scenes/tracks/oval.csv\"\n\
         learn_sim_seconds = 3\neval_tracks = [\"generated:101\"]\neval_sim_seconds = 2\n\
         [heldout]\nsim_seconds = 10\n[[variant]]\nname = \"paper\"\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    let ns = unique_namespace("xf");
    let (ok, log) = run(&file, &out, &ns, &[], &dir.path().join("first.log"));
    assert!(!ok, "a failed cell fails the command\n{log}");
    let failure = out.join("paper/0/failed.json");
    let text =
        std::fs::read_to_string(&failure).unwrap_or_else(|_| panic!("no failed.json\n{log}"));
    assert!(
        text.contains("no model.safetensors") && text.contains("learn.log"),
        "{text}"
    );
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(
        md.contains("## Failed cells") && md.contains("`paper/0`"),
        "{md}"
    );
    assert!(!out.join("paper/0/cell.json").exists());
    let (ok, log) = run(&file, &out, &ns, &[], &dir.path().join("second.log"));
    assert!(
        !ok && log.contains("0 finished, 1 to run"),
        "retried:\n{log}"
    );
}
