//! World stepping cost: bare physics vs. a full control step (physics + sensors + image), per
//! shipped track. Prints a table; `cargo bench -p mtanet-scenes`.
//!
//! Each row times one control period (4 physics steps of 5 ms). The car is driven by the teacher
//! so contacts and the camera view are those of real recording.

use std::time::Instant;

use hdrhistogram::Histogram;
use mtanet_scenes::{SceneConfig, Teacher, TeacherConfig, World, shipped_track};

const STEPS: usize = 20_000; // control steps per row: 400 s simulated

struct Row {
    label: String,
    hist: Histogram<u64>,
    wall_s: f64,
    sim_s: f64,
    physics_steps: u64,
}

fn run(label: String, cfg: &SceneConfig, mode: Mode) -> Row {
    let mut world = World::new(cfg).expect("world");
    let mut teacher = Teacher::new(&TeacherConfig::default());
    let mut hist = Histogram::<u64>::new_with_bounds(1, 1_000_000_000, 3).expect("histogram");
    let mut sensors = world.sense();
    let sub = world.substeps() as u64;
    let t_start = Instant::now();
    for _ in 0..STEPS {
        // The teacher runs outside the timed region: it is not part of the world's cost.
        let cmd = teacher.act(&sensors);
        let t0 = Instant::now();
        match mode {
            Mode::Physics => {
                world.step(cmd);
            }
            Mode::Full => {
                world.step(cmd);
                sensors = world.sense();
            }
            Mode::SenseOnly => {
                sensors = world.sense();
            }
        }
        hist.record(t0.elapsed().as_nanos() as u64).expect("record");
        if matches!(mode, Mode::Physics | Mode::SenseOnly) {
            // Keep the car moving like in the full loop, untimed.
            if matches!(mode, Mode::Physics) {
                sensors = world.sense();
            } else {
                world.step(cmd);
            }
        }
    }
    let wall_s = t_start.elapsed().as_secs_f64();
    Row {
        label,
        hist,
        wall_s,
        sim_s: world.time_s(),
        physics_steps: STEPS as u64 * sub,
    }
}

#[derive(Clone, Copy)]
enum Mode {
    /// `World::step` only: 4 physics steps + lap bookkeeping.
    Physics,
    /// `World::step` + `World::sense` (image, line sensors, wheel speeds, truth).
    Full,
    /// `World::sense` alone.
    SenseOnly,
}

fn main() {
    println!(
        "{:<34} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>8}",
        "case (per control step = 20 ms)",
        "steps/s",
        "p50 us",
        "p99 us",
        "p99.9 us",
        "max us",
        "mean us",
        "RTF"
    );
    for track in ["oval", "bends", "s_loop", "square"] {
        let cfg = SceneConfig::default().with_track(shipped_track(track));
        let cfg_side = SceneConfig {
            side_cameras: true,
            ..cfg.clone()
        };
        let rows = [
            run(
                format!("{track}: physics only (4 mj_step)"),
                &cfg,
                Mode::Physics,
            ),
            run(format!("{track}: sense only"), &cfg, Mode::SenseOnly),
            run(format!("{track}: step + sense"), &cfg, Mode::Full),
            run(
                format!("{track}: step + sense, 3 cameras"),
                &cfg_side,
                Mode::Full,
            ),
        ];
        for r in rows {
            let us = |q: f64| r.hist.value_at_quantile(q) as f64 / 1e3;
            let mean_s = r.hist.mean() / 1e9;
            // Real-time factor from the timed part only: simulated time per control step over
            // the mean time the timed work took.
            let rtf = 0.02 / mean_s;
            println!(
                "{:<34} {:>10.0} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>7.0}x",
                r.label,
                1.0 / mean_s,
                us(0.5),
                us(0.99),
                us(0.999),
                r.hist.max() as f64 / 1e3,
                mean_s * 1e6,
                rtf
            );
            let _ = (r.wall_s, r.sim_s, r.physics_steps);
        }
    }
}
