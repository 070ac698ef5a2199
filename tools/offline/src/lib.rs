//! The offline tools over models, tracks and checkpoints, with no running stack: `mta train`,
//! `mta synth`, `mta figures`, `mta probe` / `mta drive` (in-process active inference),
//! `mta track` (a generated track as a file) and `mta analyze` (what a checkpoint's layers
//! hold, [`analyze`]).

pub mod analyze;
pub mod evaluate;
pub mod figures;
pub mod synth;
pub mod track;
pub mod train;
