//! Weights holding NaN never drive: a checkpoint with one NaN weight is refused by every command
//! that loads one, with an error naming the file and the tensor.

use std::path::Path;
use std::process::Command;

use mtanet_models::checkpoint;
use mtanet_system_tests::{Signal, bin, here};

/// The committed checkpoint with one weight set to NaN, saved as `dir/nan.safetensors`.
fn nan_checkpoint(dir: &Path) -> std::path::PathBuf {
    let ck = checkpoint::load(here().join("data/oval_lockstep.safetensors")).unwrap();
    let (vs, _model) = ck.build().unwrap();
    tch::no_grad(|| {
        let w = &vs.variables()["layer0.xhat.weight"];
        let _ = w.flatten(0, -1).get(3).fill_(f64::NAN);
    });
    let path = dir.join("nan.safetensors");
    checkpoint::save(&path, &vs, &ck.config, &ck.meta).unwrap();
    path
}

#[test]
fn a_checkpoint_with_a_nan_weight_is_refused_naming_file_and_tensor() {
    let dir = tempfile::tempdir().unwrap();
    let nan = nan_checkpoint(dir.path());
    let config = here().join("../ops/mtanet.toml");
    let out = dir.path().join("run");
    let out = out.to_string_lossy();
    let up = [
        "up",
        "--lockstep",
        "--no-learning",
        "--sim-seconds",
        "2",
        "--out",
        &out,
    ];
    // Every command that loads a checkpoint, and the predictor on its own (it refuses the file
    // before it joins a stack).
    let runs: [(&str, &[&str]); 4] = [
        ("mta", &up),
        ("mta", &["drive", "--steps", "50"]),
        ("mta", &["probe"]),
        ("mta-predictor", &[]),
    ];
    for (binary, args) in runs {
        let o = Command::new(bin(binary))
            .args(args)
            .arg("--config")
            .arg(&config)
            .arg("--checkpoint")
            .arg(&nan)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success(),
            "{binary} {args:?} ran with NaN weights\n{err}"
        );
        assert!(
            err.contains("nan.safetensors")
                && err.contains("`layer0.xhat.weight` holds 1 non-finite"),
            "{binary} {args:?}: {err}"
        );
    }
}

/// The committed checkpoint made to overflow: every weight finite, but the layer-0 prediction
/// ~1e38, so the next-frame error is inf. Its bytes.
fn overflowing_checkpoint(dir: &Path) -> Vec<u8> {
    let ck = checkpoint::load(here().join("data/oval_lockstep.safetensors")).unwrap();
    let (vs, _model) = ck.build().unwrap();
    tch::no_grad(|| {
        let vars = vs.variables();
        let bias = &vars["layer0.xhat.bias"];
        let _ = bias.shallow_clone().fill_(1e38);
    });
    let path = dir.join("overflow.safetensors");
    checkpoint::save(&path, &vs, &ck.config, &ck.meta).unwrap();
    std::fs::read(&path).unwrap()
}

/// A model whose error turns non-finite mid-run loses the wheel at once, through the real
/// processes: the predictor drives by active inference with good weights, then weights that pass
/// every load check (finite, a passing probe) but overflow arrive on the topic; the rule takes
/// over and no non-finite command reaches the simulator.
#[test]
fn a_model_whose_error_overflows_mid_run_hands_the_wheel_to_the_rule() {
    use mtanet_ipc::node::{IpcConfig, create_node};
    use mtanet_ipc::weights_topic::WeightsSender;
    use mtanet_ipc::{CommandSource, WeightsHeader};
    use mtanet_system_tests::{StatsWatch, run_in, start, unique_namespace, wait_for_alive};
    use std::time::Duration;

    let dir = tempfile::tempdir().unwrap();
    let ns = unique_namespace("nf");
    // A bad but finite error would need this many model steps in a row to lose the wheel
    // (hours): only the non-finite rule can hand it back within the test.
    let config = dir.path().join("stack.toml");
    std::fs::write(
        &config,
        "[predictor.active_inference]\ndistrust_after_steps = 1000000\n",
    )
    .unwrap();
    let run = mtanet_system_tests::Run {
        config: Some(config),
        ..run_in(&ns, dir.path())
    };
    let mut predictor = start("mta-predictor", &run, &[], dir.path());
    wait_for_alive(&ns, 1, Duration::from_secs(30));
    let mut sim = start("mta-simulator", &run, &["--mode", "lockstep"], dir.path());
    let stats = StatsWatch::open(&ns);
    let node = create_node(
        &IpcConfig {
            namespace: ns.clone(),
        },
        "test-trainer",
    )
    .unwrap();
    let sender = WeightsSender::open(&node).unwrap();
    let send = |version: u64, bytes: &[u8]| {
        let header = WeightsHeader {
            version,
            probe: 0.9,
            probe_step: 1,
            ..Default::default()
        };
        sender.send(header, bytes).unwrap();
    };
    let ai = CommandSource::ActiveInference as u32;
    send(
        1,
        &std::fs::read(here().join("data/oval_lockstep.safetensors")).unwrap(),
    );
    stats.wait_for("predictor", Duration::from_secs(180), |s| {
        s.model_version == 1 && s.driver == ai
    });
    send(2, &overflowing_checkpoint(dir.path()));
    let after = stats.wait_for("predictor", Duration::from_secs(120), |s| {
        s.model_version == 2 && s.driver != ai
    });
    // Some steps later it still does not drive: the model stays distrusted.
    stats.wait_for("predictor", Duration::from_secs(60), |s| {
        s.count > after.count + 500
    });
    let last = stats.wait_for("predictor", Duration::from_secs(5), |_| true);
    assert_ne!(last.driver, ai, "{last:?}");
    for p in [&sim, &predictor] {
        p.signal(Signal::TERM);
    }
    assert!(
        sim.wait(Duration::from_secs(30)).success(),
        "{}",
        sim.log_tail()
    );
    assert!(
        predictor.wait(Duration::from_secs(30)).success(),
        "{}",
        predictor.log_tail()
    );
    let s: mtanet_summaries::simulator::Summary =
        mtanet_system_tests::read_json(&dir.path().join("mta-simulator.json"));
    assert_eq!(
        s.rejected_commands, 0,
        "a non-finite command reached the simulator"
    );
    let p: mtanet_summaries::predictor::Summary =
        mtanet_system_tests::read_json(&dir.path().join("mta-predictor.json"));
    assert!(p.control.switches_to_reactive >= 1, "{:?}", p.control);
    mtanet_system_tests::remove_namespace_files(&ns);
}
