//! Lockstep learning replays the same: the same config and seed learn from scratch to the same
//! weights and the same report, whether the machine is idle or a CPU hog runs on every core
//! (the trainer's `schedule.rs`: each update's data and each weights' install step are fixed by
//! the data, not by timing).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use mtanet_report::report::Report;
use mtanet_system_tests::{
    bin, nodes, read_json, remove_namespace_files, small_trainer, unique_namespace,
};

fn learn(dir: &Path, name: &str) -> PathBuf {
    let out = dir.join(name);
    let ns = unique_namespace("det");
    let config = dir.join("stack.toml");
    // Weights every 10 updates: 250 steps, more than the install lag, so 60 simulated seconds
    // hold several versions.
    std::fs::write(&config, small_trainer(16, 10)).unwrap();
    let log = dir.join(format!("{name}.log"));
    let status = Command::new(bin("mta"))
        .args([
            "up",
            "--lockstep",
            "--sim-seconds",
            "60",
            "--namespace",
            &ns,
        ])
        .arg("--config")
        .arg(&config)
        .arg("--out")
        .arg(&out)
        .stderr(std::fs::File::create(&log).unwrap())
        .status()
        .unwrap();
    let text = std::fs::read_to_string(&log).unwrap_or_default();
    assert!(status.success(), "mta up failed: {status}\n{text}");
    let c = nodes(&ns);
    assert!(c.alive.is_empty() && c.dead.is_empty(), "{c:?}");
    remove_namespace_files(&ns);
    out
}

/// One busy loop per core, at the stack's own priority.
fn hogs() -> Vec<Child> {
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    (0..cores)
        .map(|_| {
            Command::new("sh")
                .args(["-c", "while :; do :; done"])
                .stdout(Stdio::null())
                .spawn()
                .unwrap()
        })
        .collect()
}

/// Each tensor's name and little-endian f32 bytes, the training step and the last loss.
type Learnt = (Vec<(String, Vec<u8>)>, u64, Option<f64>);

/// The checkpoint's tensors and training figures (its save time aside).
fn weights(run: &Path) -> Learnt {
    let bytes = std::fs::read(run.join("model.safetensors")).unwrap();
    let ck = mtanet_models::checkpoint::from_bytes(&bytes).unwrap();
    let tensors = ck
        .tensors
        .iter()
        .map(|(name, t)| {
            let t = t.contiguous().to_kind(tch::Kind::Float);
            let mut v = vec![0f32; t.numel()];
            t.copy_data(&mut v, t.numel());
            (
                name.clone(),
                v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            )
        })
        .collect();
    (tensors, ck.meta.step, ck.meta.loss)
}

/// The report without what wall-clock time decides (latencies, wall seconds, overruns, and the
/// pace's updates per 1000 steps: counted from the step at which the simulator first saw the
/// trainer training, which its status reaches when it reaches it; the updates are the same).
fn timeless(mut r: Report) -> Report {
    r.latency.clear();
    r.wall_seconds = 0.0;
    r.overruns = 0;
    r.trainer.update_time = None;
    r.trainer.updates_per_1000_steps = None;
    r
}

#[test]
fn the_same_lockstep_learning_gives_the_same_weights_and_report_beside_a_cpu_hog() {
    let dir = tempfile::tempdir().unwrap();
    let idle = learn(dir.path(), "idle");
    let mut load = hogs();
    let loaded = learn(dir.path(), "loaded");
    for h in &mut load {
        let _ = h.kill();
        let _ = h.wait();
    }
    let (a, b): (Report, Report) = (
        read_json(&idle.join("report.json")),
        read_json(&loaded.join("report.json")),
    );
    let (wa, wb) = (weights(&idle), weights(&loaded));
    println!(
        "updates {:?}, loss {:?}; wall {:.1} s idle, {:.1} s loaded",
        a.trainer.updates, wa.2, a.wall_seconds, b.wall_seconds
    );
    assert!(wa.1 >= 20, "too little learning to compare: {a:#?}");
    assert_eq!(wa, wb, "the learnt weights differ");
    assert_eq!(
        format!("{:#?}", timeless(a)),
        format!("{:#?}", timeless(b)),
        "the reports differ"
    );
}
