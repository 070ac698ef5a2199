//! Learning-curve experiment on the synthetic set, without the CLI's dependencies:
//! `cargo run --release -p mtanet-models --example learn -- [config.toml] [max_updates] [seed]`
//! The TOML may hold `[model]`, `[train]` and `[synth]` tables. Prints held-out metrics every
//! 100 updates (mse / copy-last ratio, shuffled-action ratio).

use mtanet_models::synth::{SynthConfig, generate};
use mtanet_models::{ModelConfig, TrainConfig, Trainer};
use serde::Deserialize;
use std::ops::ControlFlow;
use std::time::Instant;

#[derive(Deserialize, Default)]
#[serde(default)]
struct Run {
    model: ModelConfig,
    train: TrainConfig,
    synth: SynthConfig,
}

fn main() {
    tch::set_num_threads(1);
    let args: Vec<String> = std::env::args().collect();
    let run: Run = match args.get(1).filter(|a| !a.is_empty()) {
        Some(p) => {
            toml::from_str(&std::fs::read_to_string(p).expect("read config")).expect("parse config")
        }
        None => Run::default(),
    };
    let max_updates: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(3000);
    let seed: u64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(0);
    let data = generate(&SynthConfig {
        seed,
        ..run.synth.clone()
    })
    .expect("synth");
    let eval = generate(&SynthConfig {
        seed: seed + 1000,
        sequences: 32,
        ..run.synth.clone()
    })
    .expect("synth");
    let mut trainer = Trainer::new(
        &run.model,
        &TrainConfig {
            seed,
            ..run.train.clone()
        },
    );
    let params: i64 = trainer
        .vs
        .trainable_variables()
        .iter()
        .map(|t| t.numel() as i64)
        .sum();
    println!(
        "{params} parameters; data {:?}; {:?}",
        data.images.size(),
        run.model
    );
    let start = Instant::now();
    let (mut sum, mut count, mut epoch) = (0.0, 0, 0);
    'outer: loop {
        let mut stop = false;
        let mut report = Vec::new();
        trainer
            .fit_epoch(&data, seed * 1000 + epoch, |r| match r {
                Ok(s) => {
                    sum += s.loss;
                    count += 1;
                    if s.step % 100 == 0 {
                        report.push((s.step, sum / count as f64));
                        sum = 0.0;
                        count = 0;
                    }
                    stop |= s.step >= max_updates;
                    if stop {
                        ControlFlow::Break(())
                    } else {
                        ControlFlow::Continue(())
                    }
                }
                Err(e) => {
                    println!("refused: {e}");
                    ControlFlow::Continue(())
                }
            })
            .expect("epoch");
        if let Some((step, loss)) = report.last() {
            let m = trainer.evaluate(&eval).expect("eval");
            println!(
                "update {step:>5} {:>6.0}s loss {loss:.5} mse {:.5} copy {:.5} ratio {:.3} shuffled ratio {:.3}",
                start.elapsed().as_secs_f64(),
                m.mse,
                m.copy_last_mse,
                m.mse_over_copy_last,
                m.mse_shuffled_actions.unwrap_or(f64::NAN) / m.copy_last_mse
            );
        }
        epoch += 1;
        if stop {
            break 'outer;
        }
    }
}
