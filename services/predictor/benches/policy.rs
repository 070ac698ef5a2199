//! Cost of one predictor decision with the default model: stepping the world model with a frame,
//! and active-inference planning for several candidate grids and horizons. Prints a table of
//! percentiles. The 50 Hz loop has 20 ms per step, of which the simulator waits at most half
//! for a command in realtime mode.
//!
//! `cargo bench -p mtanet-predictor`

use std::time::Instant;

use mtanet_ipc::latency::LatencyStats;
use mtanet_ipc::{IMAGE_PIXELS, Observation};
use mtanet_models::{ModelConfig, TrainConfig, Trainer};
use mtanet_predictor::active_inference::{ActiveInferenceConfig, candidates, choose};
use mtanet_predictor::world_model::WorldModel;
use tch::Tensor;

fn main() {
    tch::set_num_threads(1);
    let bytes = Trainer::new(&ModelConfig::default(), &TrainConfig::default())
        .checkpoint_bytes(None)
        .unwrap();
    let mut world = WorldModel::from_bytes(&bytes, 1).unwrap();
    let mut obs: Observation = bytemuck::Zeroable::zeroed();
    obs.wheel_velocity = [8.0, 8.0];
    let preferred = Tensor::full([1, 1, 8, 12], 0.8, (tch::Kind::Float, tch::Device::Cpu));
    let n = 200;

    println!(
        "{:<44}{:>10}{:>10}{:>10}{:>10}",
        "predictor decision (1 torch thread)", "p50 ms", "p99 ms", "p99.9 ms", "max ms"
    );
    let mut stats = LatencyStats::new();
    for i in 0..n {
        obs.image = [0.5 + 0.001 * (i % 7) as f32; IMAGE_PIXELS];
        let t = Instant::now();
        world.observe(&obs).unwrap();
        stats.record_ns(t.elapsed().as_nanos() as u64);
    }
    row("observe (model step, batch 1)", &stats);

    for (speeds, turns, horizon) in [
        (vec![8.0], vec![-6.0, -3.0, 0.0, 3.0, 6.0], 1usize),
        (vec![8.0], vec![-6.0, -3.0, 0.0, 3.0, 6.0], 3),
        (vec![5.0, 8.0, 11.0], vec![-6.0, -3.0, 0.0, 3.0, 6.0], 1),
        (vec![5.0, 8.0, 11.0], vec![-6.0, -3.0, 0.0, 3.0, 6.0], 3),
        (vec![5.0, 8.0, 11.0], vec![-6.0, -3.0, 0.0, 3.0, 6.0], 5),
    ] {
        let cfg = ActiveInferenceConfig {
            speeds,
            turns,
            horizon,
            ..Default::default()
        };
        let cands = candidates(&cfg);
        let mut stats = LatencyStats::new();
        for _ in 0..n / 4 {
            let t = Instant::now();
            choose(&world, &cands, &preferred, [8.0, 8.0], &cfg).unwrap();
            stats.record_ns(t.elapsed().as_nanos() as u64);
        }
        row(
            &format!("plan K={} horizon={}", cands.len(), cfg.horizon),
            &stats,
        );
    }
}

fn row(name: &str, stats: &LatencyStats) {
    let s = stats.summary();
    println!(
        "{name:<44}{:>10.2}{:>10.2}{:>10.2}{:>10.2}",
        s.p50_us / 1e3,
        s.p99_us / 1e3,
        s.p999_us / 1e3,
        s.max_us / 1e3
    );
}
