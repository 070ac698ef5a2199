//! World stepping cost: bare `mj_step` vs. the control loop (physics + sensors + image).
//! Prints a table; `cargo bench -p mtanet-scenes`.
//!
//! The car is driven by the teacher (untimed) so contacts and the camera view are those of a
//! real recording. Per-call times go into an HDR histogram; RTF = simulated time per call over
//! the mean wall time per call.

use std::time::Instant;

use hdrhistogram::Histogram;
use mtanet_scenes::{
    CONTROL_PERIOD_S, SceneConfig, Sensors, Teacher, TeacherConfig, World, shipped_track,
};

/// Control steps per row: 200 s simulated.
const STEPS: usize = 10_000;

#[derive(Clone, Copy, PartialEq)]
enum Case {
    /// One `mj_step` per timed call (4 per control period, the car still driven).
    BareMjStep,
    /// `World::step`: one control period (4 physics steps) + lap bookkeeping.
    Step,
    /// `World::sense`: image, line sensors, wheel speeds, ground truth.
    Sense,
    /// `World::step` + `World::sense`: what the simulator does every 20 ms.
    StepSense,
}

fn run(cfg: &SceneConfig, case: Case) -> (Histogram<u64>, f64) {
    let mut world = World::new(cfg).expect("world");
    let mut teacher = Teacher::new(&TeacherConfig::default());
    let mut hist = Histogram::<u64>::new_with_bounds(1, 10_000_000_000, 3).expect("histogram");
    let mut s: Sensors = world.sense();
    let timed = |hist: &mut Histogram<u64>, f: &mut dyn FnMut()| {
        let t0 = Instant::now();
        f();
        hist.record(t0.elapsed().as_nanos().max(1) as u64)
            .expect("record");
    };
    for _ in 0..STEPS {
        let cmd = teacher.act(&s);
        match case {
            Case::BareMjStep => {
                // Set the command through an untimed control step's bookkeeping, then time the
                // bare physics steps of the next period one by one.
                world.step(cmd);
                for _ in 0..world.substeps() {
                    timed(&mut hist, &mut || world.mj_step_bare());
                }
                s = world.sense();
            }
            Case::Step => {
                timed(&mut hist, &mut || {
                    world.step(cmd);
                });
                s = world.sense();
            }
            Case::Sense => {
                world.step(cmd);
                timed(&mut hist, &mut || s = world.sense());
            }
            Case::StepSense => timed(&mut hist, &mut || {
                world.step(cmd);
                s = world.sense();
            }),
        }
    }
    let sim_per_call = match case {
        Case::BareMjStep => cfg.physics_timestep_s,
        Case::Sense => f64::NAN,
        Case::Step | Case::StepSense => CONTROL_PERIOD_S,
    };
    (hist, sim_per_call)
}

fn row(label: &str, hist: &Histogram<u64>, sim_per_call: f64) {
    let us = |ns: u64| ns as f64 / 1e3;
    let mean_s = hist.mean() / 1e9;
    let rtf = if sim_per_call.is_nan() {
        "-".to_string()
    } else {
        format!("{:.0}x", sim_per_call / mean_s)
    };
    println!(
        "{label:<40} {:>9.0} {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>8.1} {rtf:>7}",
        1.0 / mean_s,
        us(hist.value_at_quantile(0.5)),
        us(hist.value_at_quantile(0.99)),
        us(hist.value_at_quantile(0.999)),
        us(hist.max()),
        mean_s * 1e6,
    );
}

fn main() {
    println!(
        "{:<40} {:>9} {:>8} {:>8} {:>8} {:>8} {:>8} {:>7}",
        "case", "calls/s", "p50 us", "p99 us", "p99.9 us", "max us", "mean us", "RTF"
    );
    let oval = SceneConfig::default();
    let three = SceneConfig {
        side_cameras: true,
        ..oval.clone()
    };
    for (label, cfg, case) in [
        ("oval: bare mj_step (5 ms)", &oval, Case::BareMjStep),
        ("oval: World::step (20 ms, 4 mj_step)", &oval, Case::Step),
        ("oval: World::sense (1 camera)", &oval, Case::Sense),
        ("oval: step + sense (1 camera)", &oval, Case::StepSense),
        ("oval: step + sense (3 cameras)", &three, Case::StepSense),
    ] {
        let (h, sim) = run(cfg, case);
        row(label, &h, sim);
    }
    for track in ["bends", "s_loop", "square"] {
        let cfg = SceneConfig::default().with_track(shipped_track(track));
        let (h, sim) = run(&cfg, Case::StepSense);
        row(&format!("{track}: step + sense (1 camera)"), &h, sim);
    }
}
