//! `cargo bench -p mtanet-models`: latency table of the predictor's and trainer's hot paths,
//! each fast path beside the straightforward form (`reference.rs`, one unit and one candidate
//! at a time) measured in the same run.
//!
//! libtorch runs with one intra-op thread unless MTANET_BENCH_THREADS says otherwise: at 8x12
//! every op is a few microseconds of dispatch, which threads cannot split, and on the 2 shared
//! cores two threads collapse 5-50x whenever another process holds a core (docs/measurements.md).
//! Optional: MTANET_BENCH_CONFIG=file.toml (model keys) to bench another size in place of the
//! default network; MTANET_BENCH_QUICK=1 for a short run; MTANET_BENCH_PEER="python script.py"
//! to time the plain PyTorch script (`mta_prednet_torch.py`, from a virtualenv outside the
//! project) in the same run, on the same synthetic data, and print the two side by side.

use hdrhistogram::Histogram;
use mtanet_models::{ModelConfig, MtaPredNet, TrainConfig, Trainer, reference};
use std::time::Instant;
use tch::{Device, Kind, Tensor, nn};

const F: (Kind, Device) = (Kind::Float, Device::Cpu);

/// p50, p99, p99.9, max in ms.
struct Row([f64; 4], usize);

fn measure(iters: usize, mut f: impl FnMut()) -> Row {
    let iters = if std::env::var_os("MTANET_BENCH_QUICK").is_some() {
        (iters / 10).max(5)
    } else {
        iters
    };
    for _ in 0..iters / 10 + 3 {
        f();
    }
    let mut h = Histogram::<u64>::new(3).expect("histogram");
    for _ in 0..iters {
        let t = Instant::now();
        f();
        h.record(t.elapsed().as_micros() as u64).expect("record");
    }
    let ms = |us: u64| us as f64 / 1000.0;
    Row(
        [
            ms(h.value_at_quantile(0.5)),
            ms(h.value_at_quantile(0.99)),
            ms(h.value_at_quantile(0.999)),
            ms(h.max()),
        ],
        iters,
    )
}

fn print(name: &str, fast: &Row, baseline: Option<&Row>) {
    let [p50, p99, p999, max] = fast.0;
    let (base, ratio) = baseline.map_or((String::from("-"), String::from("-")), |b| {
        (format!("{:.3}", b.0[0]), format!("{:.1}x", b.0[0] / p50))
    });
    println!(
        "| {name:<40} | {p50:>8.3} | {p99:>8.3} | {p999:>8.3} | {max:>8.3} | {:>5} | {base:>9} | {ratio:>7} |",
        fast.1
    );
}

fn params(vs: &nn::VarStore) -> i64 {
    vs.trainable_variables()
        .iter()
        .map(|t| t.numel() as i64)
        .sum()
}

fn peak_rss_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// A frozen network of `cfg` with its inference weights, a frame and an action (batch 1).
struct Frozen {
    _vs: nn::VarStore,
    model: MtaPredNet,
    w: mtanet_models::StepWeights,
    frame: Tensor,
    action: Tensor,
}

fn frozen(cfg: &ModelConfig) -> Frozen {
    let mut vs = nn::VarStore::new(Device::Cpu);
    let model = MtaPredNet::new(&vs.root(), cfg);
    vs.freeze();
    let w = model.inference_weights();
    let (h, wd, a) = (cfg.image_height, cfg.image_width, cfg.action_dim);
    Frozen {
        _vs: vs,
        model,
        w,
        frame: Tensor::rand([1, 1, h, wd], F),
        action: Tensor::rand([1, a], F) * 8.0,
    }
}

/// The batch-1 step (carried state, inference weights) and the straightforward form's.
fn step_batch1(f: &Frozen) -> (Row, Row) {
    let _g = tch::no_grad_guard();
    let (model, w, frame, action) = (&f.model, &f.w, &f.frame, &f.action);
    let mut s = model.zero_state(1);
    let fast = measure(3000, || {
        let (next, out) = model.f_step_with(w, &s, frame, action).unwrap();
        let _ = out.prediction.double_value(&[0, 0, 0, 0]);
        s = next;
    });
    let mut s = model.zero_state(1);
    let slow = measure(1000, || {
        let (next, p) = reference::step(model, &s, Some(frame), action);
        let _ = p.double_value(&[0, 0, 0, 0]);
        s = next;
    });
    (fast, slow)
}

fn inference(cfg: &ModelConfig) {
    let _g = tch::no_grad_guard();
    let f = frozen(cfg);
    let (model, w, frame, action) = (&f.model, &f.w, &f.frame, &f.action);
    let a = cfg.action_dim;
    let mut state = model.zero_state(1);
    for _ in 0..5 {
        state = model.f_step_with(w, &state, frame, action).unwrap().0;
    }
    let (fast, slow) = step_batch1(&f);
    print("step, batch 1", &fast, Some(&slow));
    for (k, steps, iters) in [(16, 1, 1000), (64, 1, 500), (16, 15, 200), (32, 4, 300)] {
        let plans = Tensor::rand([k, steps, a], F) * 8.0;
        let fast = measure(iters, || {
            let (p, _) = model.f_rollout(w, &state, &plans).unwrap();
            let _ = p.double_value(&[0, 0, 0, 0, 0]);
        });
        let slow = measure(iters / 4 + 5, || {
            let mut s = state.expand(k);
            for i in 0..steps {
                s = reference::step(model, &s, None, &plans.select(1, i)).0;
            }
            let _ = s.layers[0].r.double_value(&[0, 0, 0, 0]);
        });
        let what = if steps == 1 {
            format!("K = {k} candidates, one step")
        } else {
            format!("K = {k} candidates x {steps}-step rollout")
        };
        print(&what, &fast, Some(&slow));
    }
}

fn training(name: &str, cfg: &ModelConfig) -> Row {
    let train_cfg = TrainConfig::default();
    let mut trainer = Trainer::new(cfg, &train_cfg);
    let (b, t) = (train_cfg.batch_size, train_cfg.bptt);
    let (h, w, a) = (cfg.image_height, cfg.image_width, cfg.action_dim);
    let images = Tensor::rand([b, t, h, w], F);
    let actions = Tensor::rand([b, t, a], F) * 8.0;
    let fast = measure(40, || {
        trainer.update(&images, &actions).expect("update");
    });
    // Baseline: the straightforward forward and backward pass alone (no optimiser step).
    let vs = nn::VarStore::new(Device::Cpu);
    let model = MtaPredNet::new(&vs.root(), cfg);
    let frames = images.unsqueeze(2);
    let slow = measure(10, || {
        let (_, errs, _) = reference::sequence(&model, &model.zero_state(b), &frames, &actions, t);
        errs.sum(Kind::Float).backward();
    });
    print(
        &format!("training update {b} x {t}, {name}"),
        &fast,
        Some(&slow),
    );
    fast
}

/// What the PyTorch script reports for itself: (median s per update, median and p99 us per
/// batch-1 step), after training on 160 synthetic 20-step sequences (90 updates, batch 16).
fn peer(command: &str, cfg: &ModelConfig) -> Result<(f64, f64, f64), String> {
    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
    for (file, sequences, seed) in [("train.npz", 160, 1), ("eval.npz", 32, 2)] {
        let synth = mtanet_models::synth::SynthConfig {
            sequences,
            steps: 20,
            height: cfg.image_height,
            width: cfg.image_width,
            seed,
            ..Default::default()
        };
        let data = mtanet_models::synth::generate(&synth).map_err(|e| e.to_string())?;
        data.save_npz(dir.path().join(file))
            .map_err(|e| e.to_string())?;
    }
    let mut words = command.split_whitespace();
    let program = words.next().ok_or("MTANET_BENCH_PEER is empty")?;
    let channels: Vec<String> = cfg.channels.iter().map(i64::to_string).collect();
    let out = dir.path().join("peer.json");
    let status = std::process::Command::new(program)
        .args(words)
        .args([
            "--epochs",
            "9",
            "--threads",
            "1",
            "--ch",
            &channels.join(","),
        ])
        .arg("--data")
        .arg(dir.path().join("train.npz"))
        .arg("--eval")
        .arg(dir.path().join("eval.npz"))
        .arg("--out")
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .status()
        .map_err(|e| format!("{program}: {e}"))?;
    if !status.success() {
        return Err(format!("{command} exited with {status}"));
    }
    let json: serde_json::Value = serde_json::from_slice(
        &std::fs::read(&out).map_err(|e| format!("{}: {e}", out.display()))?,
    )
    .map_err(|e| format!("{}: {e}", out.display()))?;
    let field = |k: &str| {
        json[k]
            .as_f64()
            .ok_or_else(|| format!("{}: no number `{k}`", out.display()))
    };
    Ok((
        field("sec_per_update_median")?,
        field("infer_us_per_step_median_b1")?,
        field("infer_us_per_step_p99_b1")?,
    ))
}

fn main() {
    let threads: i32 = std::env::var("MTANET_BENCH_THREADS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    tch::set_num_threads(threads);
    let default = match std::env::var("MTANET_BENCH_CONFIG") {
        Ok(p) => ModelConfig::from_toml(&std::fs::read_to_string(&p).expect("read config"))
            .expect("config"),
        Err(_) => ModelConfig::default(),
    };
    // The network of the plain PyTorch comparison script: 1/16/32 channels for R and X.
    let script = ModelConfig {
        channels: vec![1, 16, 32],
        a_channels: vec![1, 16, 32],
        ..Default::default()
    };
    tch::manual_seed(0);
    for (name, cfg) in [("default", &default), ("1/16/32", &script)] {
        let vs = nn::VarStore::new(Device::Cpu);
        let _ = MtaPredNet::new(&vs.root(), cfg);
        println!(
            "{name} network: {}x{}, channels {:?}, a_channels {:?}, GUs {:?}, tau {:?}: {} parameters",
            cfg.image_height,
            cfg.image_width,
            cfg.channels,
            cfg.a_channels,
            cfg.gus,
            cfg.tau,
            params(&vs)
        );
    }
    println!("{threads} libtorch thread(s); times in ms; ref = the straightforward form, same run");
    println!(
        "| {:<40} | {:>8} | {:>8} | {:>8} | {:>8} | {:>5} | {:>9} | {:>7} |",
        "case (default network unless named)",
        "p50",
        "p99",
        "p99.9",
        "max",
        "iters",
        "ref p50",
        "speedup"
    );
    println!(
        "|{:-<42}|{:->10}|{:->10}|{:->10}|{:->10}|{:->7}|{:->11}|{:->9}|",
        "", "", "", "", "", "", "", ""
    );
    inference(&default);
    let (script_step, script_step_ref) = step_batch1(&frozen(&script));
    print(
        "step, batch 1, 1/16/32",
        &script_step,
        Some(&script_step_ref),
    );
    training("default", &default);
    let rss_default = peak_rss_mib();
    let script_update = training("1/16/32", &script);
    println!(
        "peak RSS of this process (VmHWM): {rss_default:.0} MiB after the default network's training, {:.0} MiB after the 1/16/32 one's",
        peak_rss_mib()
    );
    let trainer = Trainer::new(&default, &TrainConfig::default());
    let bytes = trainer.checkpoint_bytes(None).expect("bytes");
    let enc = measure(50, || {
        let _ = trainer.checkpoint_bytes(None).expect("bytes");
    });
    print(
        &format!("checkpoint to bytes ({} KiB)", bytes.len() / 1024),
        &enc,
        None,
    );
    let dec = measure(50, || {
        let ck = mtanet_models::checkpoint::from_bytes(&bytes).expect("decode");
        let _ = ck.build().expect("build");
    });
    print("checkpoint from bytes + build", &dec, None);
    if let Ok(command) = std::env::var("MTANET_BENCH_PEER") {
        match peer(&command, &script) {
            Ok((update_s, step_us, step_p99_us)) => {
                println!(
                    "\nthe PyTorch script, same run, same 1/16/32 network (its own timers; p50 is its median)"
                );
                println!(
                    "| {:<40} | {:>10} | {:>10} | {:>10} |",
                    "case", "script p50", "ours p50", "ours faster"
                );
                println!("|{:-<42}|{:->12}|{:->12}|{:->12}|", "", "", "", "");
                let row = |case: &str, script: f64, ours: f64| {
                    let faster = format!("{:.2}x", script / ours);
                    println!("| {case:<40} | {script:>10.1} | {ours:>10.1} | {faster:>10} |");
                };
                row(
                    "training update 16 x 20 (ms)",
                    update_s * 1e3,
                    script_update.0[0],
                );
                row("step, batch 1 (us)", step_us, script_step.0[0] * 1e3);
                row(
                    "step, batch 1, p99 (us)",
                    step_p99_us,
                    script_step.0[1] * 1e3,
                );
            }
            Err(e) => println!("\nthe PyTorch script could not be timed: {e}"),
        }
    }
}
