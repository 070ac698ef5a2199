//! The trainer process: collects replay chunks from shared memory into a replay buffer, trains
//! MTA-PredNet on windows of it at the model's frame skip, judges the weights by the
//! counterfactual probe, and publishes them to the predictor.

pub mod config;
pub mod curve;
pub mod learner;
pub mod probe;
pub mod replay;
pub mod schedule;
pub mod service;
