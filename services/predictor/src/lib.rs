//! The predictor process: answers every observation with a wheel command. The policy is chosen
//! per step: active inference through the world model once weights have arrived from the trainer,
//! a reactive line-sensor rule before that.

pub mod active_inference;
pub mod config;
pub mod policy;
pub mod service;
pub mod world_model;
