//! `cargo bench -p mtanet-models`: latency table of the predictor's and trainer's hot paths.
//!
//! libtorch runs with one intra-op thread unless MTANET_BENCH_THREADS says otherwise: at 8x12
//! every op is a few microseconds of dispatch, which threads cannot split, and on the 2 shared
//! cores two threads collapse 5-50x whenever another process holds a core (docs/measurements.md).
//! Optional: MTANET_BENCH_CONFIG=file.toml (model keys) to bench another size.

use hdrhistogram::Histogram;
use mtanet_models::{ModelConfig, MtaPredNet, TrainConfig, Trainer};
use std::time::Instant;
use tch::{Device, Kind, Tensor, nn};

fn measure(name: &str, iters: usize, mut f: impl FnMut()) {
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
    println!(
        "| {name:<44} | {:>9.3} | {:>9.3} | {:>9.3} | {:>9.3} | {iters:>6} |",
        ms(h.value_at_quantile(0.5)),
        ms(h.value_at_quantile(0.99)),
        ms(h.value_at_quantile(0.999)),
        ms(h.max()),
    );
}

fn main() {
    let threads: i32 = std::env::var("MTANET_BENCH_THREADS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    tch::set_num_threads(threads);
    let cfg = match std::env::var("MTANET_BENCH_CONFIG") {
        Ok(p) => ModelConfig::from_toml(&std::fs::read_to_string(&p).expect("read config"))
            .expect("config"),
        Err(_) => ModelConfig::default(),
    };
    tch::manual_seed(0);
    let vs = nn::VarStore::new(Device::Cpu);
    let model = MtaPredNet::new(&vs.root(), &cfg);
    let params: i64 = vs
        .trainable_variables()
        .iter()
        .map(|t| t.numel() as i64)
        .sum();
    let (h, w, a) = (cfg.image_height, cfg.image_width, cfg.action_dim);
    let opts = (Kind::Float, Device::Cpu);
    println!(
        "MTA-PredNet {}x{} layers {:?} channels {:?} a_channels {:?} GUs {:?} tau {:?}: {params} parameters, {threads} libtorch thread(s)",
        h,
        w,
        cfg.layers(),
        cfg.channels,
        cfg.a_channels,
        cfg.gus,
        cfg.tau
    );
    println!(
        "| {:<44} | {:>9} | {:>9} | {:>9} | {:>9} | {:>6} |",
        "case", "p50 ms", "p99 ms", "p99.9 ms", "max ms", "iters"
    );
    println!(
        "|{:-<46}|{:->11}|{:->11}|{:->11}|{:->11}|{:->8}|",
        "", "", "", "", "", ""
    );

    {
        let _g = tch::no_grad_guard();
        let mut state = model.zero_state(1);
        let frame = Tensor::rand([1, 1, h, w], opts);
        let action = Tensor::rand([1, a], opts);
        measure("inference step, batch 1", 2000, || {
            let (next, out) = model.step(&state, &frame, &action);
            let _ = out.prediction.double_value(&[0, 0, 0, 0]);
            state = next;
        });
        for k in [16, 64] {
            let actions = Tensor::rand([k, a], opts);
            measure(&format!("predict_candidates, K = {k}"), 1000, || {
                let p = model.predict_candidates(&state, &actions);
                let _ = p.double_value(&[0, 0, 0, 0]);
            });
            measure(&format!("step + predict_candidates K = {k}"), 1000, || {
                let (next, _) = model.step(&state, &frame, &action);
                let p = model.predict_candidates(&next, &actions);
                let _ = p.double_value(&[0, 0, 0, 0]);
                state = next;
            });
        }
    }

    let train_cfg = TrainConfig::default();
    let mut trainer = Trainer::new(&cfg, &train_cfg);
    let (b, t) = (train_cfg.batch_size, train_cfg.bptt);
    let images = Tensor::rand([b, t, h, w], opts);
    let actions = Tensor::rand([b, t, a], opts);
    measure(
        &format!("training update, batch {b} x {t} steps"),
        30,
        || {
            trainer.update(&images, &actions).expect("update");
        },
    );
    let bytes = trainer.checkpoint_bytes(None).expect("bytes");
    measure(
        &format!("checkpoint to_bytes ({} KiB)", bytes.len() / 1024),
        50,
        || {
            let _ = trainer.checkpoint_bytes(None).expect("bytes");
        },
    );
    measure("checkpoint from_bytes + build", 50, || {
        let ck = mtanet_models::checkpoint::from_bytes(&bytes).expect("decode");
        let _ = ck.build().expect("build");
    });
}
