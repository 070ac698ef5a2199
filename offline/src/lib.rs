//! The offline tools over models, tracks and checkpoints, with no running stack: `mta train`,
//! `mta synth`, `mta figures`, and `mta probe` / `mta drive` (in-process active inference).

pub mod evaluate;
pub mod figures;
pub mod synth;
pub mod train;
