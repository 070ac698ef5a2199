//! The simulator process: steps the MuJoCo line-tracer world (`mtanet-scenes`) and talks to the
//! predictor and trainer over iceoryx2 (`service`), or runs alone with the teacher driving for
//! tests and data collection (`standalone`).

pub mod answer;
pub mod chunk;
pub mod clock;
pub mod config;
pub mod pacing;
pub mod recorder;
pub mod service;
pub mod standalone;
pub mod summary;
pub mod trace;

// The wire format and the world must agree on the image; a mismatch must not compile.
const _: () = assert!(mtanet_ipc::IMAGE_HEIGHT == mtanet_scenes::IMAGE_HEIGHT);
const _: () = assert!(mtanet_ipc::IMAGE_WIDTH == mtanet_scenes::IMAGE_WIDTH);
const _: () = assert!(mtanet_ipc::CONTROL_PERIOD_S == mtanet_scenes::CONTROL_PERIOD_S);
