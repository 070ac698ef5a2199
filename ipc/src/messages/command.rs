use bytemuck::Zeroable;
use iceoryx2::prelude::ZeroCopySend;

use crate::ACTION_DIM;
pub use mtanet_summaries::CommandSource;

/// The wheel command answering one observation.
#[derive(Debug, Clone, Copy, Zeroable, bytemuck::Pod, ZeroCopySend)]
#[type_name("mtanet::Command/v2")]
#[repr(C)]
pub struct Command {
    /// `CLOCK_MONOTONIC` ns when published.
    pub stamp_ns: u64,
    /// The observation step this command answers; the simulator drops commands for other steps.
    pub step: u64,
    /// The answered observation's `stamp_ns`, echoed so the simulator measures the round trip.
    pub obs_stamp_ns: u64,
    /// Version of the weights that produced it (0: none loaded yet).
    pub model_version: u64,
    /// Wheel velocities (rad/s, left/right).
    pub wheel_velocity: [f32; ACTION_DIM],
    /// A [`CommandSource`] as u32.
    pub source: u32,
    /// Predictor's own compute time for this step in ns (saturating).
    pub compute_ns: u32,
    /// The world model's recent next-frame error over the copy-last-frame error (NaN: none).
    pub model_error_ratio: f32,
    /// Counterfactual probe of the weights in use (NaN: not measured).
    pub probe: f32,
}
