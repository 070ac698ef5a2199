//! Recordings of a live stack: `mta record` writes its topics into an MCAP file ([`format`]),
//! `mta replay` plays one back to a predictor in place of the simulator and compares commands.

pub mod format;
pub mod record;
pub mod replay;
