//! Cost of the predictor's work with the default model: a model step (every `frame_skip`
//! control steps), batched imagination of K candidate plans, and whole plans (CEM over the
//! imagination, run on the planner's thread). Prints a table of percentiles. In real time a plan
//! has one segment (`frame_skip` x 20 ms) of wall time; a control step at most 10 ms.
//!
//! `cargo bench -p mtanet-predictor`

use std::time::Instant;

use mtanet_control::preference::{Contrast, PreferredLine};
use mtanet_control::{Cost, CostConfig, Drive, FrameShape, Imagination, Planner, PlannerConfig};
use mtanet_ipc::latency::LatencyStats;
use mtanet_models::live::{Imagined, LiveModel};
use mtanet_models::{ModelConfig, TrainConfig, Trainer};

fn row(name: &str, s: &LatencyStats) {
    let m = s.summary();
    println!(
        "| {name:<40} | {:>8.3} | {:>8.3} | {:>8.3} | {:>8.3} |",
        m.p50_us / 1000.0,
        m.p99_us / 1000.0,
        m.p999_us / 1000.0,
        m.max_us / 1000.0
    );
}

fn main() {
    tch::set_num_threads(1);
    let cfg = ModelConfig {
        frame_skip: 5,
        ..ModelConfig::default()
    };
    let bytes = Trainer::new(&cfg, &TrainConfig::default())
        .checkpoint_bytes(None)
        .unwrap();
    let mut live = LiveModel::from_bytes(&bytes, 1).unwrap();
    let frame = [0.5f32; 96];
    println!(
        "| {:<40} | {:>8} | {:>8} | {:>8} | {:>8} |",
        "predictor work (1 torch thread)", "p50 ms", "p99 ms", "p99.9 ms", "max ms"
    );
    println!(
        "|{:-<42}|{:-<10}|{:-<10}|{:-<10}|{:-<10}|",
        "", "", "", "", ""
    );
    let mut s = LatencyStats::new();
    for _ in 0..500 {
        let t = Instant::now();
        live.observe_frame(&frame, [8.0, 8.0]).unwrap();
        s.record_ns(t.elapsed().as_nanos() as u64);
    }
    row("model step (batch 1)", &s);
    let mut im = Imagined::from_bytes(&bytes).unwrap();
    // The warm start's batch (8, also the smallest a deadline chooses), the sizes a deadline
    // chooses from (8 apart, up to 32) and 6 for comparison; the first call of each batch size
    // apart: libtorch builds its convolutions' work per shape, which is why the planner's
    // thread rolls each size out once before its first plan.
    let mut first = LatencyStats::new();
    for (k, h) in [(6, 4), (8, 4), (16, 4), (24, 4), (32, 4), (64, 4), (16, 15)] {
        let plans = vec![vec![Drive::new(8.0, 1.0); h]; k];
        let mut s = LatencyStats::new();
        for i in 0..61 {
            im.start(live.state().deep_copy(), [8.0, 8.0]).unwrap();
            let t = Instant::now();
            im.imagine(&plans).unwrap();
            let ns = t.elapsed().as_nanos() as u64;
            if i == 0 {
                first.record_ns(ns)
            } else {
                s.record_ns(ns)
            }
        }
        row(&format!("imagine K = {k} plans x {h} segments"), &s);
    }
    row("imagine, the first call of each size above", &first);
    let rows = 8;
    let preferred = PreferredLine {
        shape: FrameShape::CAR,
        contrast: Contrast {
            floor: 0.85,
            amplitude: 0.75,
        },
        position_mean: vec![0.0; rows],
        position_cov: (0..rows * rows)
            .map(|i| if i / rows == i % rows { 0.01 } else { 0.0 })
            .collect(),
        mass_mean: vec![3.0; rows],
        frames: 100,
    };
    let cost = Cost::new(preferred, CostConfig::default());
    for pc in [
        PlannerConfig::default(),
        PlannerConfig {
            samples: 16,
            iterations: 2,
            ..Default::default()
        },
    ] {
        let mut planner = Planner::new(&pc).unwrap();
        let mut s = LatencyStats::new();
        for _ in 0..40 {
            let t = Instant::now();
            im.start(live.state().deep_copy(), [8.0, 8.0]).unwrap();
            planner
                .plan(&mut im, &cost, Drive::new(8.0, 0.0), None)
                .unwrap();
            s.record_ns(t.elapsed().as_nanos() as u64);
        }
        row(
            &format!(
                "plan: CEM {} x {} iterations, H = {}",
                pc.samples, pc.iterations, pc.horizon
            ),
            &s,
        );
    }
}
