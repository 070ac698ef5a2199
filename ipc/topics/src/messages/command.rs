use bytemuck::Zeroable;
use iceoryx2::prelude::ZeroCopySend;

use crate::ACTION_DIM;

/// Segments of a plan a command can carry: the planner's longest horizon.
pub const PLAN_SEGMENTS: usize = 8;

/// The wheel command answering one observation, with the rest of the plan it comes from: a
/// simulator that misses the next commands (a paused predictor) follows the plan meanwhile.
#[derive(Debug, Clone, Copy, Zeroable, bytemuck::Pod, ZeroCopySend)]
#[type_name("mtanet::Command/v3")]
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
    /// A [`crate::CommandSource`] as u32.
    pub source: u32,
    /// Predictor's own compute time for this step in ns (saturating).
    pub compute_ns: u32,
    /// The world model's recent next-frame error over the copy-last-frame error (NaN: none).
    pub model_error_ratio: f32,
    /// Counterfactual probe of the weights in use (NaN: not measured).
    pub probe: f32,
    /// The step the plan's first segment began at (`plan[0]` is this command's segment).
    pub plan_first_step: u64,
    /// Steps each plan segment holds its command.
    pub plan_segment_steps: u32,
    /// Segments of `plan` in use (0: no plan, as when the reactive rule drives).
    pub plan_len: u32,
    /// Wheel velocities (rad/s) of each segment, from `plan_first_step` on.
    pub plan: [[f32; ACTION_DIM]; PLAN_SEGMENTS],
}

impl Command {
    /// The planned wheel velocities for `step`, while the plan covers it.
    pub fn planned_at(&self, step: u64) -> Option<[f32; ACTION_DIM]> {
        let seg = u64::from(self.plan_segment_steps);
        let i = step.checked_sub(self.plan_first_step)? / seg.max(1);
        let len = (self.plan_len as usize).min(PLAN_SEGMENTS);
        (seg > 0 && (i as usize) < len).then(|| self.plan[i as usize])
    }

    /// Carries `segments` (at most [`PLAN_SEGMENTS`]) from `first_step`, `segment_steps` each.
    pub fn set_plan(
        &mut self,
        first_step: u64,
        segment_steps: u32,
        segments: &[[f32; ACTION_DIM]],
    ) {
        let n = segments.len().min(PLAN_SEGMENTS);
        self.plan_first_step = first_step;
        self.plan_segment_steps = segment_steps;
        self.plan_len = n as u32;
        self.plan[..n].copy_from_slice(&segments[..n]);
    }
}
