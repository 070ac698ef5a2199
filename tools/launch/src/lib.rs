//! Launching and supervising the stack: the one launch plan and spawner ([`plan`]), the local
//! supervisor with its readiness sockets, the effective run config, `mta up` (the whole stack
//! here, with a live progress line and the run's report) and `mta systemd` (the same plan as
//! systemd units).

pub mod baseline;
pub mod notify;
pub mod plan;
mod progress;
pub mod runcfg;
pub mod stack;
pub mod supervisor;
pub mod systemd;
pub mod up;

pub use plan::{Launch, Run, args_of, command, missing_hint, plan};
