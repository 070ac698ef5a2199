//! Closed-loop evaluation without IPC: an [`mtanet_control::Agent`] drives a MuJoCo
//! [`mtanet_scenes::World`] in-process, with the world itself ([`oracle`]) or a learned
//! checkpoint as its model; and the counterfactual probe of a learned model.

pub mod drive;
pub mod oracle;
pub mod probe;

pub use drive::{DriveConfig, DriveReport, drive, rule_alone};
pub use oracle::{OracleImagination, OracleModel, SeesWorld};
pub use probe::{ProbeConfig, ProbeReport, probe};
