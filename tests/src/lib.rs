//! The system tests' harness: processes of the real binaries ([`Proc`]), waiting on a namespace's
//! nodes, and the soak runs the tests share. The tests themselves live in `tests/`.

use std::path::{Path, PathBuf};
use std::process::Command;

mod proc;
mod stats_watch;

use mtanet_summaries::soak::SoakReport;

pub use mtanet_launch::stack::*;
pub use mtanet_launch::{Run, plan};
pub use proc::*;
pub use stats_watch::StatsWatch;

/// This crate's folder (the test data and the shipped config are found from it).
pub fn here() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A run of the default stack in namespace `ns`, each process's summary in `dir`.
pub fn run_in(ns: &str, dir: &Path) -> Run {
    Run {
        namespace: Some(ns.into()),
        summaries: Some(dir.into()),
        ..Default::default()
    }
}

/// Starts `binary` with the launch plan's arguments for `run`, then `extra`; its log in `log_dir`.
pub fn start(binary: &str, run: &Run, extra: &[&str], log_dir: &Path) -> Proc {
    let mut args = mtanet_launch::args_of(binary, run);
    args.extend(extra.iter().map(|a| a.to_string()));
    Proc::spawn(binary, &args, log_dir)
}

/// Where the launch plan has `binary` write its summary.
pub fn summary(run: &Run, binary: &str) -> PathBuf {
    run.summaries
        .as_ref()
        .expect("a run with summaries")
        .join(format!("{binary}.json"))
}

/// A one-minute real-time `mta soak` of the stack in `config`, from the committed checkpoint,
/// with `extra` arguments, in `dir`; its `soak.json`. Fails with the soak's log if it failed.
pub fn one_minute_soak(dir: &Path, config: &Path, extra: &[&str]) -> SoakReport {
    let out = dir.join("soak");
    let log = dir.join("soak.log");
    let status = Command::new(bin("mta"))
        .args([
            "soak",
            "--realtime",
            "--minutes",
            "1",
            "--pingpong-seconds",
            "5",
        ])
        .args(extra)
        .arg("--config")
        .arg(config)
        .arg("--checkpoint")
        .arg(here().join("data/oval_lockstep.safetensors"))
        .arg("--out")
        .arg(&out)
        .stderr(std::fs::File::create(&log).expect("creating the soak's log"))
        .status()
        .expect("starting mta soak");
    let text = std::fs::read_to_string(&log).unwrap_or_default();
    assert!(status.success(), "mta soak failed: {status}\n{text}");
    assert!(out.join("soak.png").exists(), "no soak.png\n{text}");
    mtanet_summaries::files::read_json(&out.join("soak.json")).expect("reading soak.json")
}

/// A stack config with a small network, so a test's trainer learns and publishes within
/// seconds: training from `min_sequences` chunks, weights every `publish_every` updates; every
/// frame a model step and no imagined steps, the cheapest windows to learn from.
pub fn small_trainer(min_sequences: u32, publish_every: u32) -> String {
    format!(
        r#"
[trainer]
min_sequences = {min_sequences}
publish_every_updates = {publish_every}
[trainer.model]
channels = [4, 4, 4]
a_channels = [1, 4, 4]
action_offset = [8.0, 8.0]
action_scale = [5.0, 5.0]
frame_skip = 1
[trainer.train]
batch_size = 4
imagined_steps = 0
"#
    )
}
