//! The learning bar, through the real processes: `mta up --lockstep` with the shipped config learns
//! from scratch on the oval and hands the wheel to active inference within 75 simulated seconds
//! (46 [46, 59] s over 5 seeds, docs/measurements.md), its model then predicting the next frame
//! better than copying the last one. A model that does not learn never passes the probe and the
//! trust ratio, so the rule drives the whole run and this test fails. About 2 minutes.

use std::path::PathBuf;
use std::process::Command;

use mtanet_report::report::Report;
use mtanet_system_tests::{bin, read_json, remove_namespace_files, unique_namespace};

#[test]
fn from_scratch_in_lockstep_active_inference_takes_the_wheel_within_75_s() {
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("scratch");
    let config = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../ops/mtanet.toml");
    let log = dir.path().join("up.log");
    let status = Command::new(bin("mta"))
        .args([
            "up",
            "--lockstep",
            "--sim-seconds",
            "75",
            "--namespace",
            &ns,
        ])
        .arg("--config")
        .arg(&config)
        .arg("--out")
        .arg(dir.path().join("run"))
        .stderr(std::fs::File::create(&log).unwrap())
        .status()
        .unwrap();
    let text = std::fs::read_to_string(&log).unwrap_or_default();
    assert!(status.success(), "mta up failed: {status}\n{text}");
    remove_namespace_files(&ns);
    let report: Report = read_json(&dir.path().join("run/report.json"));
    let c = &report.control;
    assert!(
        c.first_takeover_s.is_some_and(|s| s <= 75.0),
        "active inference never took the wheel: {report:#?}"
    );
    assert!(c.active_inference_steps > 250, "{report:#?}");
    // Lockstep replays the same on one machine, not across CPUs (libtorch's kernels differ in
    // the last bits): on an AMD EPYC this run loses the line once for 0.1 s, on an Intel Xeon
    // never. What must hold anywhere is that a fallback ends at once (issue bar: seconds).
    assert!(
        c.fallbacks <= 2 && c.longest_fallback_s <= 2.0,
        "{report:#?}"
    );
    let p = &report.prediction;
    let (mse, copy) = (p.mse.unwrap(), p.copy_last_mse.unwrap());
    assert!(mse < 0.8 * copy, "model {mse} vs copy-last {copy}");
}
