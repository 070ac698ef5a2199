//! System tests live in `tests/`; the process helpers they use are `mtanet_mta::stack`, and the
//! soak runs they share are here.

use std::path::{Path, PathBuf};
use std::process::Command;

use mtanet_mta::stack::bin;

/// This crate's folder (the test data and the shipped config are found from it).
pub fn here() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A one-minute real-time `mta soak` of the stack in `config`, from the committed checkpoint,
/// with `extra` arguments, in `dir`; its `soak.json`. Fails with the soak's log if it failed.
pub fn one_minute_soak(dir: &Path, config: &Path, extra: &[&str]) -> serde_json::Value {
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
    let json = std::fs::read(out.join("soak.json")).expect("reading soak.json");
    serde_json::from_slice(&json).expect("soak.json is JSON")
}
