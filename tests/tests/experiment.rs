//! `mta experiment` end to end with the real binaries: the shipped smoke experiment
//! (`experiments/smoke.toml`: 2 variants x 2 seeds, 20 simulated s learnt on the oval, 10 s
//! evaluated on a generated track) into a temporary folder under a private namespace prefix.
//! Every run must leave its row, the summary its sections, every metric its picture; a second
//! invocation must find every cell finished and run nothing.

use std::path::{Path, PathBuf};
use std::process::Command;

use mtanet_experiment::metrics::NAMES;
use mtanet_system_tests::{bin, here, unique_namespace};

/// Runs `mta experiment FILE` from the repository root; its success and its output.
fn run(file: &Path, out: &Path, ns: &str, log: &Path) -> (bool, String) {
    let status = Command::new(bin("mta"))
        .current_dir(here().join(".."))
        .arg("experiment")
        .arg(file)
        .args(["--namespace", ns])
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

fn experiment(out: &Path, ns: &str, log: &Path) -> String {
    let (ok, text) = run(Path::new("experiments/smoke.toml"), out, ns, log);
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

#[test]
fn the_smoke_experiment_runs_every_cell_summarises_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("smoke");
    let ns = unique_namespace("xt");
    experiment(&out, &ns, &dir.path().join("first.log"));

    let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let mut want_header = vec!["variant", "seed", "phase", "track"];
    want_header.extend(NAMES.iter().map(|n| n.0));
    assert_eq!(header, want_header);
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let mut keys: Vec<String> = rows.iter().map(|r| r[..4].join(",")).collect();
    keys.sort();
    let mut want = Vec::new();
    for v in ["flat", "paper"] {
        for s in ["0", "1"] {
            want.push(format!("{v},{s},eval,generated:101"));
            want.push(format!("{v},{s},learn,scenes/tracks/oval.csv"));
        }
    }
    assert_eq!(keys, want, "one row per run:\n{csv}");
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    for r in rows.iter().filter(|r| r[2] == "learn") {
        let updates: f64 = r[col("trainer_updates")]
            .parse()
            .expect("a learn run trains");
        let ratio: f64 = r[col("heldout_over_copy_last")]
            .parse()
            .expect("a held-out ratio");
        assert!(updates >= 1.0 && ratio.is_finite() && ratio > 0.0, "{r:?}");
    }
    for r in &rows {
        let laps: f64 = r[col("laps")].parse().expect("every run counts laps");
        assert!(laps >= 0.0);
    }

    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    for section in [
        "# Experiment `smoke`",
        "## learn",
        "## eval",
        "## Differences of medians",
        "### `flat` - `paper`",
        "## Metrics",
    ] {
        assert!(md.contains(section), "no {section:?} in summary.md:\n{md}");
    }
    assert!(!md.contains("## Failed cells"), "{md}");
    for (name, _) in NAMES {
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
    assert_eq!(before.len(), 4 + 8, "4 cell.json, 8 report.json");
    let log = experiment(&out, &ns, &dir.path().join("second.log"));
    assert!(log.contains("4 finished, 0 to run"), "{log}");
    assert_eq!(finished_files(&out), before, "a finished cell ran again");
    assert_eq!(
        std::fs::read_to_string(out.join("results.csv")).unwrap(),
        csv
    );
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
    let (ok, log) = run(&file, &out, &ns, &dir.path().join("first.log"));
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
    let (ok, log) = run(&file, &out, &ns, &dir.path().join("second.log"));
    assert!(
        !ok && log.contains("0 finished, 1 to run"),
        "retried:\n{log}"
    );
}
