//! What the simulator reports at exit (a plain data type of `mtanet-summaries`).

pub use mtanet_summaries::simulator::Summary;
