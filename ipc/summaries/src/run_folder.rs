//! The files of a run folder (`mta up --out DIR`, an experiment's runs, `mta soak --out DIR`):
//! named here once, for the commands that write them and the tools that read them.

/// The run's report (`mtanet_report::Report`).
pub const REPORT: &str = "report.json";
/// The learnt (or given) model at the end of the run.
pub const MODEL: &str = "model.safetensors";
/// The checkpoint the run started from, with its probe recorded.
pub const START: &str = "start.safetensors";
/// The stack config the run used, checked.
pub const STACK: &str = "stack.toml";
/// The car's path and who drove it, every n-th step.
pub const TRACE: &str = "trace.csv";
/// The live line, once a second.
pub const PROGRESS: &str = "progress.csv";
/// What was asked of `mta up` (track, mode, checkpoint).
pub const RUN: &str = "run.json";
/// The supervisor's restarts per process.
pub const SUPERVISOR: &str = "supervisor.json";
/// `mta soak`'s report.
pub const SOAK: &str = "soak.json";
/// The trainer's checkpoint folder inside the run folder, and its newest checkpoint there.
pub const CHECKPOINTS: &str = "checkpoints";
pub const LATEST: &str = "latest.safetensors";

/// A process's exit summary: `mta-simulator.json` for `mta-simulator`.
pub fn summary_of(binary: &str) -> String {
    format!("{binary}.json")
}
