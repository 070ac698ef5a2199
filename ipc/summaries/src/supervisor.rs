//! What the supervisor (`mta up`) reports at the end of a run (`supervisor.json`).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct SupervisorSummary {
    /// Restarts of each process it ran, by binary name.
    pub restarts: BTreeMap<String, u32>,
}
