//! What every mtanet process shares: the message types that cross shared memory, the service
//! names, and the process glue (iceoryx2 node, signals, systemd notify, logging, latency stats).
//!
//! Messages are plain `#[repr(C)]` data with an explicit iceoryx2 `type_name`, so two separately
//! built binaries agree on them; sizes are pinned by tests in `messages`.

pub mod child;
pub mod cli;
pub mod config;
pub mod incident;
pub mod latency;
pub mod logging;
pub mod messages;
pub mod names;
pub mod node;
pub mod ports;
pub mod sched;
pub mod shutdown;
pub mod stack;
pub mod stamp;
pub mod stats;
pub mod systemd;
pub mod wait;
pub mod weights_topic;

pub use messages::*;
/// Who decided a command: defined with the summaries that count it, carried by [`Command`].
pub use mtanet_summaries::CommandSource;

/// The camera image (8x12, row-major) and the period of the observations: one definition.
pub use mtanet_summaries::{CONTROL_PERIOD_S, IMAGE_HEIGHT, IMAGE_PIXELS, IMAGE_WIDTH};
/// The action: left and right wheel angular velocity in rad/s.
pub const ACTION_DIM: usize = 2;
/// Steps in one replay chunk (one training sequence, the paper's T = 20).
pub const REPLAY_STEPS: usize = 20;
