//! Observation of a live stack, read from what its processes publish (never their logs):
//! `mta status` (nodes, topics and each process's stats) and `mta top` (a live terminal view).

pub mod status;
pub mod top;
