//! The system tests' harness: processes of the real binaries ([`Proc`]), waiting on a namespace's
//! nodes, and the soak runs the tests share. The tests themselves live in `tests/`.

use std::path::{Path, PathBuf};
use std::process::Command;

mod proc;
mod stats_watch;

use mtanet_mta::summary::SoakReport;

pub use mtanet_mta::stack::*;
pub use proc::*;
pub use stats_watch::StatsWatch;

/// This crate's folder (the test data and the shipped config are found from it).
pub fn here() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
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
    mtanet_files::read_json(&out.join("soak.json")).expect("reading soak.json")
}
