//! Watching a live stack, read from what its processes publish (never their logs):
//! `mta status` (nodes, topics and each process's stats), `mta top` (a live terminal view),
//! `mta record` (its topics into an MCAP file, [`format`]) and `mta replay` (a recording played
//! back to a predictor in place of the simulator, its commands compared).

pub mod format;
pub mod record;
pub mod replay;
pub mod status;
pub mod top;
