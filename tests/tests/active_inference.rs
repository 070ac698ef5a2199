//! Active inference drives the car through the learned model, with the real processes: `mta up`
//! starts the predictor and the simulator (no trainer) from the committed checkpoint made by a
//! from-scratch lockstep run on the oval (tests/data/README.md), in lockstep for 60 simulated
//! seconds, and the run's report must show a lap driven by active inference from start to end,
//! beside the rule-alone baseline; and `mta up --rule`, the rule alone through the processes.

use std::path::{Path, PathBuf};
use std::process::Command;

use mtanet_report::report::Report;
use mtanet_system_tests::{bin, nodes, read_json, remove_namespace_files, unique_namespace};

fn checkpoint() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/oval_lockstep.safetensors")
}

/// `mta up --lockstep` with the shipped config and `args` into `dir/run`; its report.
fn up_lockstep(dir: &Path, ns: &str, args: &[&str]) -> Report {
    let config = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../ops/mtanet.toml");
    let status = Command::new(bin("mta"))
        .args(["up", "--lockstep", "--namespace", ns])
        .args(args)
        .arg("--config")
        .arg(&config)
        .arg("--out")
        .arg(dir.join("run"))
        .stderr(std::fs::File::create(dir.join("up.log")).unwrap())
        .status()
        .unwrap();
    let log = std::fs::read_to_string(dir.join("up.log")).unwrap_or_default();
    assert!(status.success(), "mta up {args:?} failed: {status}\n{log}");
    read_json(&dir.join("run/report.json"))
}

#[test]
fn active_inference_drives_a_lap_through_the_learned_model() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let ns = unique_namespace("ai");
    let ck = checkpoint();
    let args = [
        "--sim-seconds",
        "60",
        "--no-learning",
        "--checkpoint",
        ck.to_str().unwrap(),
    ];
    let report = up_lockstep(dir.path(), &ns, &args);
    assert_eq!(report.steps, 3000, "{report:#?}");
    assert!(
        report.laps.completed_under_active_inference >= 1,
        "no lap under active inference:\n{report:#?}"
    );
    assert!(report.control.active_inference_steps > 1500, "{report:#?}");
    assert_eq!(report.control.fallbacks, 0, "{report:#?}");
    assert_eq!(report.laps.lost_line_events, 0, "{report:#?}");
    // The clean baseline beside it: the rule alone on the oval for the same 60 s.
    let rule = report
        .rule_alone
        .as_ref()
        .expect("report.json has rule_alone");
    assert!((rule.sim_seconds - 60.0).abs() < 1e-6, "{rule:?}");
    assert!(rule.laps >= 2 && rule.lost_line_events == 0, "{rule:?}");
    // Planning kept up: every plan was taken up at its segment.
    assert_eq!(report.control.late_plans, 0, "{report:#?}");
    for f in [
        "lap_trace.png",
        "latency.png",
        "figure.png",
        "model.safetensors",
        "trace.csv",
    ] {
        assert!(out.join(f).exists(), "{f} missing from the run folder");
    }
    // The pictures show the run: the path active inference drove, the step's latency bars.
    use mtanet_plot::{
        BLUE,
        test_png::{decode, near},
    };
    let (_, _, px) = decode(&out.join("lap_trace.png"));
    assert!(
        near(&px, BLUE) > 500,
        "lap_trace.png shows no active-inference path"
    );
    let (_, _, px) = decode(&out.join("latency.png"));
    assert!(near(&px, BLUE) > 2000, "latency.png shows no histogram");
    let c = nodes(&ns);
    assert!(
        c.alive.is_empty() && c.dead.is_empty(),
        "nodes left behind: {c:?}"
    );
    remove_namespace_files(&ns);
}

/// `mta up --rule`: the reactive rule alone through the real processes (no trainer, no model,
/// no exploration); its lateral error agrees with the in-process baseline every report carries.
#[test]
fn the_rule_alone_drives_every_step_and_agrees_with_the_in_process_baseline() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let ns = unique_namespace("rule");
    let args = ["--rule", "--sim-seconds", "30", "--track", "generated:101"];
    let report = up_lockstep(dir.path(), &ns, &args);
    let c = &report.control;
    assert_eq!(c.reactive_steps, 1500, "{report:#?}");
    assert_eq!(
        c.active_inference_steps + c.exploration_steps,
        0,
        "{report:#?}"
    );
    assert!(
        report.trainer.updates.is_none(),
        "a trainer ran: {report:#?}"
    );
    assert!(!out.join("model.safetensors").exists());
    let stack = report.lateral_error_m.all_mean;
    let rule = report.rule_alone.as_ref().expect("rule_alone");
    let alone = rule.lateral_mean_m.expect("a lateral error");
    assert!(
        (stack - alone).abs() <= 0.05 * alone,
        "the stack's rule {stack} m against the in-process rule {alone} m"
    );
    assert!(
        report.laps.completed >= 1 && report.laps.lap_time_s.is_some(),
        "{report:#?}"
    );
    remove_namespace_files(&ns);
}
