//! The messages that cross shared memory, one type per file.

mod command;
mod observation;
mod process_stats;
mod replay;
mod trainer_status;
mod weights;

pub use command::{Command, PLAN_SEGMENTS};
pub use observation::{GroundTruth, Observation};
pub use process_stats::ProcessStats;
pub use replay::ReplayChunk;
pub use trainer_status::TrainerStatus;
pub use weights::WeightsHeader;

#[cfg(test)]
mod tests;
