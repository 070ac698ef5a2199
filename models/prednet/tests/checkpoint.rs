//! Checkpoints: exact round trips (in this process and another), atomic writes, and clear
//! refusals that leave the target model untouched.

use mtanet_models::checkpoint::{self, CheckpointError, Meta};
use mtanet_models::{ModelConfig, MtaPredNet};
use std::process::Command;
use tch::{Device, Kind, Tensor, nn::VarStore};

fn small() -> ModelConfig {
    ModelConfig::small(&ModelConfig::default().tau)
}

fn model(cfg: &ModelConfig, seed: i64) -> (VarStore, MtaPredNet) {
    tch::set_num_threads(1);
    tch::manual_seed(seed);
    let vs = VarStore::new(Device::Cpu);
    let m = MtaPredNet::new(&vs.root(), cfg);
    (vs, m)
}

fn same_weights(a: &VarStore, b: &VarStore) -> bool {
    let (a, b) = (a.variables(), b.variables());
    a.len() == b.len() && a.iter().all(|(n, t)| b.get(n).is_some_and(|u| u.equal(t)))
}

/// A fixed input's prediction, to compare behaviour and not only tensors.
fn probe(m: &MtaPredNet) -> Tensor {
    let _g = tch::no_grad_guard();
    let frames = Tensor::linspace(0.0, 1.0, 3 * 96, (Kind::Float, Device::Cpu)).view([1, 3, 8, 12]);
    let actions = Tensor::linspace(-1.0, 1.0, 6, (Kind::Float, Device::Cpu)).view([1, 3, 2]);
    m.forward_sequence(&frames, &actions).predictions
}

#[test]
fn round_trip_restores_weights_config_and_meta() {
    let cfg = small();
    let (vs, m) = model(&cfg, 1);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.safetensors");
    let meta = Meta::new(1234, Some(0.0125));
    checkpoint::save(&path, &vs, &cfg, &meta).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    // (No assert_eq: a failure would print megabytes.)
    assert!(
        bytes == checkpoint::to_bytes(&vs, &cfg, &meta).unwrap(),
        "the bytes form is the file"
    );

    let (mut other, m2) = model(&cfg, 2);
    assert!(!same_weights(&vs, &other));
    let got = checkpoint::load_into(&path, &mut other, &cfg).unwrap();
    assert_eq!(got, meta);
    assert!(same_weights(&vs, &other));
    assert!(
        probe(&m).equal(&probe(&m2)),
        "same weights, same predictions"
    );

    let ck = checkpoint::from_bytes(&bytes).unwrap();
    assert_eq!(
        (ck.config.clone(), ck.meta.step, ck.meta.schema_version),
        (cfg, 1234, checkpoint::SCHEMA_VERSION)
    );
    let (built, m3) = ck.build().unwrap();
    assert!(same_weights(&vs, &built));
    assert!(probe(&m).equal(&probe(&m3)));
    // Atomic write: no temporary file is left behind.
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "{names:?}");
}

#[test]
fn config_mismatch_names_the_keys() {
    let (vs, _m) = model(&small(), 1);
    let bytes = checkpoint::to_bytes(&vs, &small(), &Meta::new(1, None)).unwrap();
    let other_cfg = ModelConfig {
        gus: vec![3, 2, 2],
        tau: vec![1.0, 1.5, 2.0],
        ..small()
    };
    let (mut other, _m) = model(&other_cfg, 2);
    let before = other.variables()["layer0.units.wx"].copy();
    let err = checkpoint::load_bytes_into(&bytes, &mut other, &other_cfg).unwrap_err();
    let text = err.to_string();
    assert!(
        matches!(err, CheckpointError::Config(ref d) if d.len() == 2),
        "{text}"
    );
    assert!(text.contains("gus") && text.contains("tau"), "{text}");
    assert!(
        other.variables()["layer0.units.wx"].equal(&before),
        "nothing loaded"
    );
}

#[test]
fn tensor_mismatches_are_listed_and_nothing_is_loaded() {
    let cfg = small();
    let (vs, _m) = model(&cfg, 1);
    let bytes = checkpoint::to_bytes(&vs, &cfg, &Meta::new(1, None)).unwrap();
    let mut ck = checkpoint::from_bytes(&bytes).unwrap();
    ck.tensors.remove("layer1.xhat.bias");
    ck.tensors.insert(
        "layer0.units.wx".into(),
        Tensor::zeros([3, 3], (Kind::Float, Device::Cpu)),
    );
    ck.tensors.insert(
        "layer2.xhat.weight".into(),
        ck.tensors["layer2.xhat.weight"].to_kind(Kind::Double),
    );
    ck.tensors.insert(
        "layer9.extra".into(),
        Tensor::zeros([1], (Kind::Float, Device::Cpu)),
    );
    let (mut other, _m) = model(&cfg, 2);
    let before: Vec<Tensor> = ["layer0.units.wh", "layer1.units.bias"]
        .iter()
        .map(|n| other.variables()[*n].copy())
        .collect();
    let err = ck.apply(&mut other, &cfg).unwrap_err();
    let CheckpointError::Tensors(problems) = &err else {
        panic!("{err}")
    };
    let text = problems.join("\n");
    assert_eq!(problems.len(), 4, "{text}");
    for needle in [
        "missing `layer1.xhat.bias`",
        "`layer0.units.wx` shape [3, 3]",
        "`layer2.xhat.weight` dtype Double",
        "unexpected `layer9.extra`",
    ] {
        assert!(text.contains(needle), "no `{needle}` in:\n{text}");
    }
    for (n, b) in ["layer0.units.wh", "layer1.units.bias"].iter().zip(&before) {
        assert!(
            other.variables()[*n].equal(b),
            "{n} was loaded from a rejected checkpoint"
        );
    }
}

#[test]
fn truncated_or_damaged_files_are_clear_errors() {
    let cfg = small();
    let (vs, _m) = model(&cfg, 1);
    let bytes = checkpoint::to_bytes(&vs, &cfg, &Meta::new(7, Some(1.0))).unwrap();
    let (mut target, _m) = model(&cfg, 3);
    let before = target.variables()["layer0.xhat.weight"].copy();
    for cut in [0, 5, 100, bytes.len() / 2, bytes.len() - 1] {
        let err = checkpoint::load_bytes_into(&bytes[..cut], &mut target, &cfg).unwrap_err();
        assert!(
            matches!(err, CheckpointError::Corrupt(_)),
            "cut at {cut}: {err}"
        );
        assert!(err.to_string().contains("truncated or corrupt"), "{err}");
    }
    let mut flipped = bytes.clone();
    let n = flipped.len();
    flipped[n - 10] ^= 0x40; // inside the last tensor's data
    let err = checkpoint::load_bytes_into(&flipped, &mut target, &cfg).unwrap_err();
    assert!(matches!(err, CheckpointError::Checksum { .. }), "{err}");
    let mut header = bytes.clone();
    header[9] = b'!'; // the header JSON's first bytes
    assert!(checkpoint::load_bytes_into(&header, &mut target, &cfg).is_err());
    assert!(
        target.variables()["layer0.xhat.weight"].equal(&before),
        "a failed load changed the model"
    );
    // A plain safetensors file (tch's VarStore::save) is not mistaken for a checkpoint.
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain.safetensors");
    vs.save(&plain).unwrap();
    let err = checkpoint::load(&plain).unwrap_err();
    let CheckpointError::InFile { path, source } = &err else {
        panic!("a file's error names the file: {err}");
    };
    assert_eq!(path, &plain);
    assert!(
        matches!(**source, CheckpointError::NotCheckpoint(_)),
        "{err}"
    );
    assert!(err.to_string().contains("plain.safetensors"), "{err}");
    let err = checkpoint::load(dir.path().join("absent.safetensors")).unwrap_err();
    assert!(err.to_string().contains("absent.safetensors"), "{err}");
}

#[test]
fn non_finite_weights_are_refused_by_name() {
    let cfg = small();
    let (vs, _m) = model(&cfg, 1);
    tch::no_grad(|| {
        let vars = vs.variables();
        let _ = vars["layer0.xhat.weight"]
            .flatten(0, -1)
            .get(0)
            .fill_(f64::NAN);
        let _ = vars["layer1.xhat.bias"].get(0).fill_(f64::INFINITY);
    });
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nan.safetensors");
    checkpoint::save(&path, &vs, &cfg, &Meta::new(3, None)).unwrap();
    let (mut target, _m) = model(&cfg, 2);
    let before = weights_digest(&target);
    let err = checkpoint::load_into(&path, &mut target, &cfg).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("nan.safetensors"), "{text}");
    // Tensors are checked in name order: the first bad one is named.
    assert!(
        text.contains("`layer0.xhat.weight` holds 1 non-finite"),
        "{text}"
    );
    assert_eq!(
        weights_digest(&target),
        before,
        "a refused file changed the model"
    );
    let bytes = std::fs::read(&path).unwrap();
    assert!(matches!(
        checkpoint::from_bytes(&bytes).unwrap_err(),
        CheckpointError::NonFinite { count: 1, .. }
    ));
}

/// Every variable's exact bits, in name order, hashed: equal only if the weights are identical.
fn weights_digest(vs: &VarStore) -> u64 {
    use std::hash::{DefaultHasher, Hash, Hasher};
    let mut vars: Vec<(String, Tensor)> = vs.variables().into_iter().collect();
    vars.sort_by(|a, b| a.0.cmp(&b.0));
    let mut h = DefaultHasher::new();
    for (name, t) in vars {
        name.hash(&mut h);
        let values = Vec::<f32>::try_from(t.flatten(0, -1)).unwrap();
        values.iter().for_each(|v| v.to_bits().hash(&mut h));
    }
    h.finish()
}

/// The weights' digest and the probe's sum to the bit: both processes run libtorch with one
/// thread, so the same weights give the same reduction order and the same float (two threads
/// would not).
fn fingerprint(vs: &VarStore, m: &MtaPredNet) -> String {
    let probe_sum = probe(m).sum(Kind::Double).double_value(&[]);
    format!("{:016x} {:016x}", weights_digest(vs), probe_sum.to_bits())
}

/// Child half of `another_process_loads_the_file`, which runs it (ignored on its own: without
/// the parent's file it has nothing to check).
#[test]
#[ignore]
fn child_probe() {
    let path =
        std::env::var("MTANET_CHECKPOINT_CHILD").expect("run by another_process_loads_the_file");
    tch::set_num_threads(1);
    let ck = checkpoint::load(&path).expect("child load");
    let (vs, m) = ck.build().expect("child build");
    println!("PROBE={}", fingerprint(&vs, &m));
}

#[test]
fn another_process_loads_the_file() {
    let cfg = small();
    let (vs, m) = model(&cfg, 5);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.safetensors");
    checkpoint::save(&path, &vs, &cfg, &Meta::new(1, None)).unwrap();
    let out = Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "child_probe",
            "--ignored",
            "--nocapture",
            "--test-threads=1",
        ])
        .env("MTANET_CHECKPOINT_CHILD", &path)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "child failed: {stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line = stdout
        .lines()
        .find_map(|l| l.split("PROBE=").nth(1))
        .map(str::trim)
        .unwrap_or_else(|| panic!("child printed no probe:\n{stdout}"));
    assert_eq!(
        line,
        fingerprint(&vs, &m),
        "the other process loaded different weights or predicts differently"
    );
}

/// The committed lockstep checkpoint was written with schema 1 (one convolution per unit): it
/// loads, and each unit's rows of the regrouped block are its old convolution, number for number.
#[test]
fn a_schema_1_checkpoint_is_converted_exactly() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tests/data/oval_lockstep.safetensors"
    );
    let raw: std::collections::HashMap<String, Tensor> = Tensor::read_safetensors(path)
        .unwrap()
        .into_iter()
        .collect();
    assert!(
        raw.contains_key("layer0.gu0.conv.weight"),
        "the file is schema 1"
    );
    let ck = checkpoint::load(path).unwrap();
    let (vs, model) = ck.build().unwrap();
    let vars = vs.variables();
    for (l, layer) in model.layers.iter().enumerate() {
        let rows = 4 * layer.units.hidden;
        for d in 0..layer.unit_count() {
            let old = &raw[&format!("layer{l}.gu{d}.conv.weight")];
            let new = Tensor::cat(
                &[
                    vars[&format!("layer{l}.units.wx")].narrow(0, d * rows, rows),
                    vars[&format!("layer{l}.units.wh")].narrow(0, d * rows, rows),
                ],
                1,
            );
            assert!(new.equal(old), "layer {l} unit {d}: weights differ");
            let bias = vars[&format!("layer{l}.units.bias")].narrow(0, d * rows, rows);
            assert!(
                bias.equal(&raw[&format!("layer{l}.gu{d}.conv.bias")]),
                "layer {l} unit {d}: bias"
            );
        }
    }
    // Saved again, it is schema 2 and reads back the same.
    let again = checkpoint::to_bytes(&vs, &ck.config, &ck.meta).unwrap();
    let back = checkpoint::from_bytes(&again).unwrap();
    assert_eq!(back.tensors.len(), vars.len());
}
