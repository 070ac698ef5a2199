//! The trainer process: collects replay chunks from shared memory into a replay buffer and (as
//! the model work lands) trains MTA-PredNet on it and publishes weights to the predictor.

pub mod config;
pub mod learner;
pub mod replay;
pub mod service;
