//! The line-tracer world of the MTA-PredNet paper (Zhong, Ogata, Cangelosi), rebuilt in MuJoCo:
//! a differential-drive car with three downward line sensors and small cameras following a dark
//! line on a light floor. The middle camera gives an 8x12 grayscale image every 0.02 s, recorded
//! with the two wheel velocities.
//!
//! - [`Track`]: a closed polyline loaded from `tracks/*.csv` (or generated: `generated:N`) and
//!   validated.
//! - [`World`]: MJCF generated from the track, compiled and stepped with MuJoCo 3.17.
//! - [`Sensors`]: camera image, line sensors, wheel velocities, ground truth for evaluation.
//! - [`Circuit`]: one car stepped round its track, lost cars put back as new episodes (no IPC),
//!   with its [`Score`]: laps, lateral error and who drove.
//! - [`Teacher`]: the classic line-tracer rule with seeded exploration noise.

pub mod camera;
pub mod car;
pub mod circuit;
mod config;
mod cull;
pub mod mjcf;
mod referee;
pub mod score;
mod teacher;
mod truth;
mod world;

pub use circuit::{Circuit, Frame, ResetRule, Stepped};
pub use config::{SceneConfig, SceneError, shipped_track, tracks_dir};
pub use mtanet_track::{Track, TrackError};
pub use referee::{Referee, Verdict};
pub use score::{ControlSummary, LateralError, Score};
pub use teacher::{Teacher, TeacherConfig};
pub use truth::GroundTruth;
pub use world::{World, WorldState};

/// The camera image and the control period, as the messages carry them: one definition.
pub use mtanet_summaries::{CONTROL_PERIOD_S, IMAGE_HEIGHT, IMAGE_PIXELS, IMAGE_WIDTH};
/// Physics time step, seconds (4 physics steps per control period).
pub const PHYSICS_TIMESTEP_S: f64 = 0.005;

/// Everything the car senses at one instant, plus ground truth for evaluation.
#[derive(Debug, Clone, Copy)]
pub struct Sensors {
    /// Middle camera, grey in [0, 1], row-major: row 0 is the top of the image (farthest from
    /// the car), column 0 the car's left.
    pub image: [f32; IMAGE_PIXELS],
    /// Left and right cameras, when `SceneConfig::side_cameras` is on.
    pub side_images: Option<[[f32; IMAGE_PIXELS]; 2]>,
    /// Line sensors: left, middle, right; true when the sensor is over the line.
    pub line: [bool; 3],
    /// Measured wheel velocities [left, right], rad/s (positive drives forward): the action.
    pub wheel_velocity: [f32; 2],
    /// Not available to a real car: for evaluation and tests only.
    pub truth: GroundTruth,
}
