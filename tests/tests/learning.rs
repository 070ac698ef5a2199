//! The learning loop across processes: the trainer learns from replay chunks in shared memory and
//! hands weights to the predictor, which loads them; damaged weights are refused without harm.

use std::path::{Path, PathBuf};
use std::time::Duration;

use mtanet_ipc::WeightsHeader;
use mtanet_ipc::node::{IpcConfig, create_node};
use mtanet_ipc::weights_topic::WeightsSender;
use mtanet_predictor::service::Summary as PredictorSummary;
use mtanet_system_tests::*;
use mtanet_trainer::service::Summary as TrainerSummary;

/// Writes a small trainer (eager: training from 4 chunks) publishing every `publish_every`
/// updates and keeping checkpoints in `dir/ck`; returns the config file and the checkpoint folder.
fn checkpointing_config(dir: &Path, publish_every: u32) -> (PathBuf, PathBuf) {
    let cfg = dir.join("stack.toml");
    let ck_dir = dir.join("ck");
    let config = small_trainer(4, publish_every).replace(
        "[trainer]\n",
        &format!("[trainer]\ncheckpoint_dir = {:?}\n", ck_dir),
    );
    std::fs::write(&cfg, config).unwrap();
    (cfg, ck_dir)
}

#[test]
fn weights_reach_the_predictor_survive_a_trainer_restart_and_damaged_ones_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("ln");
    let (cfg, ck_dir) = checkpointing_config(dir.path(), 2);
    let run = Run {
        config: Some(cfg.clone()),
        ..run_in(&ns, dir.path())
    };
    let mut trainer = start("mta-trainer", &run, &[], dir.path());
    let mut predictor = start("mta-predictor", &run, &[], dir.path());
    wait_for_alive(&ns, 2, Duration::from_secs(30));
    let mut sim = start("mta-simulator", &run, &["--mode", "realtime"], dir.path());
    let stats = StatsWatch::open(&ns);

    // No weights reaching the predictor fails here, with the last figures it reported.
    stats.wait_for("predictor", Duration::from_secs(120), |s| {
        s.weights_installed >= 1
    });
    // The trainer stops publishing when we stop it; then a damaged blob arrives on the topic.
    trainer.signal(Signal::TERM);
    assert!(
        trainer.wait(Duration::from_secs(30)).success(),
        "{}",
        trainer.log_tail()
    );
    let before = {
        let node = create_node(
            &IpcConfig {
                namespace: ns.clone(),
            },
            "bad-trainer",
        )
        .unwrap();
        let sender = WeightsSender::open(&node).unwrap();
        let header = WeightsHeader {
            version: 999,
            ..Default::default()
        };
        sender
            .send(header, b"definitely not a safetensors checkpoint")
            .unwrap();
        // Trainer 1 is gone: every weights it sent are in, and the damaged blob is refused
        // (while its sender lives: a publisher's samples leave with it).
        stats
            .wait_for("predictor", Duration::from_secs(20), |s| {
                s.weights_rejected == 1
            })
            .weights_installed
    };
    assert!(
        ck_dir.join("latest.safetensors").exists(),
        "the trainer keeps its latest checkpoint on disk"
    );

    // A restarted trainer resumes from disk and hands the predictor its weights at once.
    let t2_dir = dir.path().join("t2");
    std::fs::create_dir_all(&t2_dir).unwrap();
    let t2_run = Run {
        config: Some(cfg.clone()),
        ..run_in(&ns, &t2_dir)
    };
    let mut trainer2 = start("mta-trainer", &t2_run, &[], &t2_dir);
    let pid2 = trainer2.pid() as u32;
    let resumed = stats.wait_for("trainer", Duration::from_secs(60), |s| {
        s.pid == pid2 && s.resumed_from_update > 0 && s.weights_published >= 1
    });
    assert!(resumed.resumed_from_update >= 2, "{resumed:?}");
    stats.wait_for("predictor", Duration::from_secs(30), |s| {
        s.weights_installed > before
    });
    trainer2.signal(Signal::TERM);
    assert!(
        trainer2.wait(Duration::from_secs(30)).success(),
        "{}",
        trainer2.log_tail()
    );
    // Both still report after the trainer has gone.
    let gone = mtanet_ipc::stamp::monotonic_ns();
    for role in ["simulator", "predictor"] {
        stats.wait_for(role, Duration::from_secs(10), |s| s.stamp_ns > gone);
    }
    drop(stats);
    assert!(
        sim.is_running() && predictor.is_running(),
        "a damaged checkpoint must not stop the stack"
    );
    for p in [&sim, &predictor] {
        p.signal(Signal::TERM);
    }
    assert!(
        sim.wait(Duration::from_secs(20)).success(),
        "{}",
        sim.log_tail()
    );
    assert!(
        predictor.wait(Duration::from_secs(20)).success(),
        "{}",
        predictor.log_tail()
    );

    let t: TrainerSummary = read_json(&summary(&run, "mta-trainer"));
    assert!(t.weights_published >= 1, "{t:?}");
    assert!(t.updates >= 2, "{t:?}");
    assert!(t.last_loss.unwrap().is_finite(), "{t:?}");
    let p: PredictorSummary = read_json(&summary(&run, "mta-predictor"));
    assert!(p.weights_received >= 3, "{p:?}");
    assert_eq!(p.weights_rejected, 1, "{p:?}");
    let version = p.model_version;
    assert!(
        (1..999).contains(&version),
        "the damaged version must not be in use: {p:?}"
    );
    assert!(
        p.model_mse.is_some(),
        "the loaded model must be stepped: {p:?}"
    );
    remove_namespace_files(&ns);
}

/// SIGTERM keeps what the trainer learned since its last publish: with publishing far away, the
/// checkpoint on disk exists only because the stop saved it, at the last update's step.
#[test]
fn a_stopped_trainer_saves_the_updates_it_had_not_published() {
    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("sv");
    let (cfg, ck_dir) = checkpointing_config(dir.path(), 1_000_000);
    let run = Run {
        config: Some(cfg.clone()),
        max_steps: Some(200),
        ..run_in(&ns, dir.path())
    };
    let mut trainer = start("mta-trainer", &run, &[], dir.path());
    let mut predictor = start("mta-predictor", &run, &[], dir.path());
    wait_for_alive(&ns, 2, Duration::from_secs(30));
    let stats = StatsWatch::open(&ns);
    let mut sim = start(
        "mta-simulator",
        &run,
        &["--mode", "lockstep", "--expect-trainer"],
        dir.path(),
    );
    assert!(
        sim.wait(Duration::from_secs(120)).success(),
        "{}",
        sim.log_tail()
    );
    // 10 chunks are in; the tiny model makes an update in milliseconds.
    stats.wait_for("trainer", Duration::from_secs(30), |s| s.count >= 1);
    drop(stats);
    let latest = ck_dir.join("latest.safetensors");
    assert!(!latest.exists(), "nothing should be saved before the stop");
    for p in [&predictor, &trainer] {
        p.signal(Signal::TERM);
    }
    for p in [&mut predictor, &mut trainer] {
        assert!(
            p.wait(Duration::from_secs(30)).success(),
            "{}",
            p.log_tail()
        );
    }
    let t: TrainerSummary = read_json(&summary(&run, "mta-trainer"));
    assert_eq!(t.chunks_received, 10, "{t:?}");
    let updates = t.updates;
    assert!(updates >= 1, "the trainer never trained: {t:?}");
    let saved = mtanet_models::checkpoint::load(&latest)
        .unwrap_or_else(|e| panic!("no checkpoint saved at stop: {e}"));
    assert_eq!(
        saved.meta.step, updates,
        "the saved step is the last update"
    );
    remove_namespace_files(&ns);
}
