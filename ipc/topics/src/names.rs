//! Service names. Every topic is a publish-subscribe service plus an event service of the same
//! name, so receivers block in a WaitSet instead of polling. Isolation between stacks (tests,
//! two robots on one host) comes from the iceoryx2 prefix in `node::IpcConfig`, not from names.

/// simulator -> predictor, trainer: one [`crate::Observation`] per control step.
pub const OBSERVATION: &str = "mtanet/observation";
/// predictor -> simulator: one [`crate::Command`] per observation.
pub const COMMAND: &str = "mtanet/command";
/// simulator -> trainer: [`crate::ReplayChunk`]s of consecutive steps.
pub const REPLAY: &str = "mtanet/replay";
/// trainer -> predictor: a checkpoint as a `[u8]` slice behind a [`crate::WeightsHeader`].
pub const WEIGHTS: &str = "mtanet/weights";

/// trainer -> simulator: [`crate::TrainerStatus`] after every update (lockstep pacing).
pub const TRAINER_STATUS: &str = "mtanet/trainer_status";

/// every process -> `mta status`: one [`crate::ProcessStats`] per process a second.
pub const STATS: &str = "mtanet/stats";

/// Every topic, for status listings and clean-up checks.
pub const ALL: [&str; 6] = [OBSERVATION, COMMAND, REPLAY, WEIGHTS, TRAINER_STATUS, STATS];
