//! The planner and its cost, with the MuJoCo world itself as the model (the oracle), drive a lap
//! of every shipped track: if this fails the cost or the planner is wrong, whatever the learned
//! model does.

use mtanet_control::{
    Agent, AgentConfig, ExplorationConfig, FrameShape, Inline, Planner, ReactiveConfig,
};
use mtanet_eval::{DriveConfig, OracleImagination, OracleModel, drive};
use mtanet_scenes::{SceneConfig, World, shipped_track};

fn oracle_lap(track: &str) {
    let scene = SceneConfig::default().with_track(shipped_track(track));
    let mut world = World::new(&scene).unwrap();
    // Learn the preference over the first ~600 centred frames (the reactive rule drives), as
    // in the stack; then the oracle is trusted at once.
    let cfg = AgentConfig {
        preference_frames: 600,
        ..AgentConfig::default()
    };
    let off = ExplorationConfig {
        enabled: false,
        ..Default::default()
    };
    let mut agent = Agent::new(
        &cfg,
        &ReactiveConfig::default(),
        &off,
        FrameShape::CAR,
        0.02,
    );
    let skip = 5;
    let mut model = OracleModel::new(skip);
    let mut plans = Inline::new(
        Planner::new(&cfg.planner).unwrap(),
        OracleImagination::new(&scene, skip).unwrap(),
    );
    let run = DriveConfig {
        max_steps: 6000,
        stop_after_ai_laps: 1,
        trace_every: 0,
        ..Default::default()
    };
    let r = drive(&mut world, &mut agent, &mut model, &mut plans, &run).unwrap();
    println!("{track}: {}", serde_json::to_string(&r).unwrap());
    assert!(
        r.laps_under_active_inference >= 1,
        "{track}: the oracle completed no lap under active inference: {r:?}"
    );
    assert_eq!(r.lost_events, 0, "{track}: the car was lost: {r:?}");
    // A lap of the shortest track (square) takes ~990 steps: the lap must be active inference's.
    assert!(r.agent.active_inference_steps > 800, "{track}: {r:?}");
}

#[test]
fn oracle_drives_a_lap_of_the_oval() {
    oracle_lap("oval");
}

#[test]
fn oracle_drives_a_lap_of_bends() {
    oracle_lap("bends");
}

#[test]
fn oracle_drives_a_lap_of_s_loop() {
    oracle_lap("s_loop");
}

#[test]
fn oracle_drives_a_lap_of_square() {
    oracle_lap("square");
}
