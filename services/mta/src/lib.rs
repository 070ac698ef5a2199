//! Library side of the `mta` CLI: what its subcommands share with the system tests.

pub mod launch;
pub mod notify;
pub mod stack;
pub use mtanet_summaries::soak as summary;
pub mod supervisor;
