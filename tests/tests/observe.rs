//! Seeing a running stack, recording it and replaying it, with the real processes: `mta top`
//! against a learning stack, the run folder's learning curve and pictures, `mta record` inside
//! `mta up --record`, and `mta replay` of that recording to a fresh predictor reproducing every
//! command bit for bit in lockstep (and a truncated recording replayed as far as it reads).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use mtanet_observe::record::RecordSummary;
use mtanet_observe::replay::ReplaySummary;
use mtanet_report::report::Report;
use mtanet_system_tests::{
    Proc, Signal, arg, bin, nodes, read_json, remove_namespace_files, unique_namespace,
    wait_for_alive,
};

fn data(p: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// `mta up` in lockstep from the committed checkpoint, in the background.
fn up(dir: &Path, ns: &str, sim_seconds: u32, extra: &[&str]) -> std::process::Child {
    let mut cmd = Command::new(bin("mta"));
    cmd.args(["up", "--lockstep", "--namespace", ns])
        .args(["--sim-seconds", &sim_seconds.to_string()])
        .arg("--config")
        .arg(data("../ops/mtanet.toml"))
        .arg("--checkpoint")
        .arg(data("data/oval_lockstep.safetensors"))
        .arg("--out")
        .arg(dir.join("run"))
        .args(extra)
        .stdout(std::process::Stdio::null())
        .stderr(std::fs::File::create(dir.join("up.log")).unwrap());
    cmd.spawn().unwrap()
}

fn finish(mut child: std::process::Child, dir: &Path) {
    let status = child.wait().unwrap();
    let log = std::fs::read_to_string(dir.join("up.log")).unwrap_or_default();
    assert!(status.success(), "mta up failed: {status}\n{log}");
}

/// The number in front of " Hz" on the line that starts with `topic`.
fn rate(screen: &str, topic: &str) -> Option<f64> {
    let line = screen
        .lines()
        .find(|l| l.trim_start_matches('│').trim_start().starts_with(topic))?;
    let rest = &line[line.find(topic)? + topic.len()..];
    rest.split_whitespace().next()?.parse().ok()
}

#[test]
fn top_shows_a_learning_stack_and_the_run_folder_has_its_curves() {
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("top");
    // Long enough that top's frames come while it runs (lockstep runs ~3-5x real time here).
    let stack = up(dir.path(), &ns, 120, &[]);
    let c = wait_for_alive(&ns, 4, Duration::from_secs(60));
    assert!(c.alive.len() >= 4, "the stack did not come up: {c:?}");
    let out = Command::new(bin("mta"))
        .args(["top", "--frames", "3", "--namespace", &ns])
        .output()
        .unwrap();
    let screen = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Three frames of 24 rows of at most 80 columns; the last one has rates (two readings).
    let frames: Vec<&str> = screen.split("\n\n").collect();
    assert_eq!(frames.len(), 3, "{screen}");
    let last = frames.last().unwrap();
    println!("{last}");
    for f in &frames {
        assert_eq!(f.lines().count(), 24, "{f}");
        assert!(f.lines().all(|l| l.chars().count() <= 80), "{f}");
    }
    // Each process alive in a frame (the trainer is silent for a few seconds while it probes).
    for p in ["simulator", "predictor", "trainer"] {
        let shown = frames
            .iter()
            .any(|f| f.lines().any(|l| l.contains(p) && l.contains("alive")));
        assert!(shown, "{p} is not shown alive:\n{screen}");
    }
    let obs = rate(last, "observation").unwrap_or(0.0);
    let cmd = rate(last, "command").unwrap_or(0.0);
    assert!(obs > 1.0 && cmd > 1.0, "topic rates {obs} / {cmd}:\n{last}");
    assert!(last.contains("driver "), "{last}");
    finish(stack, dir.path());

    let run = dir.path().join("run");
    let (curve, bad) = mtanet_trainer::curve::read(&run.join("learning.jsonl")).unwrap();
    assert!(
        !curve.is_empty() && bad == 0,
        "{} updates, {bad} bad lines",
        curve.len()
    );
    assert!(curve.windows(2).all(|w| w[1].step > w[0].step));
    assert!(
        curve
            .iter()
            .all(|p| p.loss.is_finite() && p.update_ms > 0.0)
    );
    let progress = std::fs::read_to_string(run.join("progress.csv")).unwrap();
    assert!(progress.lines().count() >= 3, "{progress}");
    for f in ["learning.png", "model_error.png", "latency.png"] {
        std::fs::remove_file(run.join(f)).unwrap_or_else(|e| panic!("{f} not drawn: {e}"));
    }
    let plot = Command::new(bin("mta"))
        .arg("plot")
        .arg(&run)
        .output()
        .unwrap();
    assert!(
        plot.status.success(),
        "{}",
        String::from_utf8_lossy(&plot.stderr)
    );
    for f in ["learning.png", "model_error.png", "latency.png"] {
        assert!(run.join(f).exists(), "mta plot did not draw {f}");
    }
    // Curves, not empty axes: the loss (blue) and the histogram's bars.
    use mtanet_plot::{
        BLUE,
        test_png::{decode, near},
    };
    for (f, least) in [("learning.png", 300), ("latency.png", 2000)] {
        let (_, _, px) = decode(&run.join(f));
        assert!(near(&px, BLUE) > least, "{f} draws nothing");
    }
    let c = nodes(&ns);
    assert!(c.alive.is_empty() && c.dead.is_empty(), "{c:?}");
    remove_namespace_files(&ns);
}

#[test]
fn a_recorded_lockstep_run_replays_to_the_same_commands_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("rec");
    finish(
        up(dir.path(), &ns, 40, &["--no-learning", "--record"]),
        dir.path(),
    );
    let run = dir.path().join("run");
    let report: Report = read_json(&run.join("report.json"));
    let ai = report.control.active_inference_steps;
    assert!(
        ai > 300,
        "active inference must drive in the recording: {report:#?}"
    );
    let rec: RecordSummary = read_json(&run.join("recording.json"));
    assert_eq!(rec.messages["mtanet/observation"], 2000, "{rec:#?}");
    assert_eq!(rec.messages["mtanet/command"], 2000, "{rec:#?}");
    assert_eq!(rec.missed_observations, 0, "{rec:#?}");
    let size = std::fs::metadata(run.join("recording.mcap")).unwrap().len();
    println!("recording: {size} bytes for 2000 steps; {rec:?}");

    // A fresh predictor from the run's own start checkpoint and config, in another namespace.
    let ns2 = unique_namespace("rep");
    let config = run.join("stack.toml");
    let start = run.join("start.safetensors");
    let mut predictor = Proc::spawn(
        "mta-predictor",
        &[
            "--namespace",
            &ns2,
            "--config",
            arg(&config),
            "--checkpoint",
            arg(&start),
        ],
        dir.path(),
    );
    let summary = dir.path().join("replay.json");
    let out = Command::new(bin("mta"))
        .args([
            "replay",
            "--lockstep",
            "--expect-identical",
            "--namespace",
            &ns2,
        ])
        .arg("--config")
        .arg(&config)
        .arg("--summary")
        .arg(&summary)
        .arg(run.join("recording.mcap"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stderr),
        predictor.log_tail()
    );
    let s: ReplaySummary = read_json(&summary);
    println!("replay: {s:?}");
    assert_eq!(s.observations_sent, 2000, "{s:#?}");
    assert_eq!(s.compared, 2000, "{s:#?}");
    assert_eq!(s.identical, 2000, "{s:#?}");

    // A recording cut short (a recorder killed mid-run): what is readable is replayed, and the
    // summary says where it stopped.
    let bytes = std::fs::read(run.join("recording.mcap")).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let out = Command::new(bin("mta"))
        .args(["replay", "--lockstep", "--namespace", &ns2])
        .arg("--config")
        .arg(&config)
        .arg("--summary")
        .arg(&summary)
        .arg(&cut)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s: ReplaySummary = read_json(&summary);
    let sent = s.observations_sent;
    assert!(sent > 0 && sent < 2000, "{s:#?}");
    assert!(
        s.damaged.as_deref().is_some_and(|d| d.contains("cut.mcap")),
        "{s:#?}"
    );

    predictor.signal(Signal::TERM);
    assert!(predictor.wait(Duration::from_secs(20)).success());
    for n in [&ns, &ns2] {
        let c = nodes(n);
        assert!(c.alive.is_empty() && c.dead.is_empty(), "{n}: {c:?}");
        remove_namespace_files(n);
    }
}
