use bytemuck::Zeroable;
use iceoryx2::prelude::ZeroCopySend;

use crate::{ACTION_DIM, IMAGE_PIXELS};

/// What the simulator sees at one control step. Published every `CONTROL_PERIOD_S` of simulated
/// time; the image and wheel velocities are the model's input, `truth` is for evaluation only.
#[derive(Debug, Clone, Copy, Zeroable, bytemuck::Pod, ZeroCopySend)]
#[type_name("mtanet::Observation/v2")]
#[repr(C)]
pub struct Observation {
    /// `CLOCK_MONOTONIC` ns when published (see [`crate::stamp`]).
    pub stamp_ns: u64,
    /// Control step index since the simulator started, 0-based.
    pub step: u64,
    /// Simulated time in seconds.
    pub sim_time_s: f64,
    /// Middle camera, grey in [0, 1], row-major `IMAGE_HEIGHT x IMAGE_WIDTH`.
    pub image: [f32; IMAGE_PIXELS],
    /// Measured wheel velocities (rad/s, left/right) at this frame (they lag the command).
    pub wheel_velocity: [f32; ACTION_DIM],
    /// The wheel command applied during the step that led to this frame (whoever decided it):
    /// the action the world model is conditioned on, as in the replay chunks.
    pub command: [f32; ACTION_DIM],
    /// Line sensors left, middle, right: 1 when over the line.
    pub line_sensors: [u8; 3],
    /// Episode counter, bumped when the simulator resets the car.
    pub episode: u8,
    /// 1 when the simulator waits for every command (lockstep), 0 in real time.
    pub lockstep: u8,
    pub _reserved: [u8; 3],
    pub truth: GroundTruth,
}

/// Ground truth from the simulator, for evaluation and reports only (never a model input).
#[derive(Debug, Clone, Copy, Default, Zeroable, bytemuck::Pod, ZeroCopySend)]
#[type_name("mtanet::GroundTruth/v1")]
#[repr(C)]
pub struct GroundTruth {
    pub x_m: f64,
    pub y_m: f64,
    pub yaw_rad: f64,
    /// Arc length along the track of the car's projection onto the line.
    pub track_s_m: f64,
    /// Signed distance of the sensor bar's centre from the line (positive: line to the left).
    pub lateral_m: f64,
    /// Completed laps.
    pub laps: u32,
    /// 1 when |lateral| is below half the line width.
    pub on_line: u32,
}
