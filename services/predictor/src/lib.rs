//! The predictor process: answers every observation with a wheel command. The control agent
//! (`mtanet-control`) decides: the reactive line-sensor rule with exploration until the world
//! model the trainer sends is trusted, then active inference planning through it.

pub mod config;
pub mod intake;
pub mod loader;
pub mod policy;
pub mod service;
