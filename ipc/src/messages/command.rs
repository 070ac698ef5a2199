use bytemuck::Zeroable;
use iceoryx2::prelude::ZeroCopySend;

use crate::ACTION_DIM;

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

/// Who decided a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum CommandSource {
    /// A fixed reactive rule on the line sensors (no model yet).
    Reactive = 0,
    /// The simulator's teacher driver.
    Teacher = 1,
    /// Active inference through the world model.
    ActiveInference = 2,
    /// A random exploration segment while the reactive rule drives (learning data).
    Exploration = 3,
    /// The reactive rule after the line was lost under active inference.
    Fallback = 4,
}

impl CommandSource {
    /// Every source, in value order.
    pub const ALL: [CommandSource; 5] = [
        Self::Reactive,
        Self::Teacher,
        Self::ActiveInference,
        Self::Exploration,
        Self::Fallback,
    ];

    /// Lower-case name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Reactive => "reactive",
            Self::Teacher => "teacher",
            Self::ActiveInference => "active_inference",
            Self::Exploration => "exploration",
            Self::Fallback => "fallback",
        }
    }

    pub fn from_u32(v: u32) -> Option<Self> {
        match v {
            0 => Some(Self::Reactive),
            1 => Some(Self::Teacher),
            2 => Some(Self::ActiveInference),
            3 => Some(Self::Exploration),
            4 => Some(Self::Fallback),
            _ => None,
        }
    }
}
