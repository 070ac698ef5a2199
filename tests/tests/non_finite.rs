//! Weights holding NaN never drive: a checkpoint with one NaN weight is refused by every command
//! that loads one, with an error naming the file and the tensor.

use std::path::Path;
use std::process::Command;

use mtanet_models::checkpoint;
use mtanet_system_tests::{bin, here};

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
