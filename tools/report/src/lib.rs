//! The run report and plots: `report.json`, the run's pictures and curves (`mta report`,
//! `mta plot`) and the soak's table, from the summaries and traces a run leaves in its folder.
//! Built on `mtanet-summaries` alone: no libtorch, MuJoCo or iceoryx2 (the model's figure strip
//! is passed in by the caller, [`FigureStrip`]).

pub mod pictures;
pub mod plot;
pub mod report;
pub mod soak_table;

pub use pictures::latency_picture;
pub use report::{FigureStrip, Report, ReportArgs, RunInfo, write};
pub use soak_table::print_table;
