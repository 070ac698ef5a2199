//! Library side of the `mta` CLI: what its subcommands share with the system tests.

pub mod stack;
pub mod supervisor;
