//! The figures the stack's processes and runs report, as plain serde types with no IPC, model or
//! physics behind them: percentiles ([`LatencySummary`]), real-time incidents, each service's
//! exit summary, the trainer's learning curve and the soak's report; the run folder's files
//! ([`run_folder`], [`rows`] for CSV) and how every file is written and read ([`files`]:
//! atomically, with errors that name the file). The run report and its plots build on this crate
//! alone; the services fill these types and re-export them.

pub mod agent;
pub mod curve;
pub mod files;
pub mod incident;
pub mod latency;
pub mod planning;
pub mod predictor;
pub mod rows;
pub mod run_folder;
pub mod simulator;
pub mod soak;
pub mod source;
pub mod supervisor;
pub mod trainer;

pub use agent::AgentStats;
pub use latency::LatencySummary;
pub use planning::PlanningSummary;
pub use source::CommandSource;

/// The `q` quantile (0..=1) of `sorted` by linear interpolation between order statistics
/// (numpy's default, "type 7"); `None` for no values.
pub fn quantile(sorted: &[f64], q: f64) -> Option<f64> {
    let n = sorted.len();
    if n == 0 {
        return None;
    }
    let h = (n - 1) as f64 * q.clamp(0.0, 1.0);
    let (lo, hi) = (h.floor() as usize, h.ceil() as usize);
    Some(sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo]))
}

/// Simulated seconds between two observations (the paper's 0.02 s). Defined here, the one crate
/// the world, the messages and the agent all build on; they re-export it.
pub const CONTROL_PERIOD_S: f64 = 0.02;
/// Rows of the camera image (the paper's 8x12 grayscale vision sensor), row 0 farthest ahead.
pub const IMAGE_HEIGHT: usize = 8;
/// Columns of the camera image, column 0 on the car's left.
pub const IMAGE_WIDTH: usize = 12;
/// Pixels of one image, row-major.
pub const IMAGE_PIXELS: usize = IMAGE_HEIGHT * IMAGE_WIDTH;
