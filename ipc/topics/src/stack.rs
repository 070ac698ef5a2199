//! `[stack]`: the processes of the stack, described once. The local supervisor (`mta up`), the
//! systemd rendering (`mta systemd`), the soak and the system tests all start the processes from
//! this list, in its order (and stop them in reverse).

use serde::{Deserialize, Serialize};

/// What to do when a process fails (exits non-zero or is killed): like systemd's
/// `Restart=on-failure` with `StartLimitBurst`/`StartLimitIntervalSec`, plus a back-off that
/// doubles from `backoff_s` up to `max_backoff_s` while failures come in quick succession.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RestartPolicy {
    pub on_failure: bool,
    /// Wait before the first restart, seconds.
    pub backoff_s: f64,
    pub max_backoff_s: f64,
    /// At most this many restarts within `window_s`; one more and the supervisor gives up.
    pub limit: u32,
    pub window_s: f64,
}

impl Default for RestartPolicy {
    fn default() -> Self {
        Self {
            on_failure: true,
            backoff_s: 0.5,
            max_backoff_s: 8.0,
            limit: 5,
            window_s: 60.0,
        }
    }
}

/// One process of the stack.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProcessSpec {
    /// Short name: logs are `<binary>.log`, the systemd unit `mtanet-<name>.service`.
    pub name: String,
    /// Executable in the build's `target/release/`.
    pub binary: String,
    /// What it is (the unit's description).
    #[serde(default)]
    pub description: String,
    /// Arguments after `--config FILE` (and the supervisor's own, like `--summary`).
    #[serde(default)]
    pub args: Vec<String>,
    #[serde(default)]
    pub restart: RestartPolicy,
    /// systemd watchdog: the process pets it from its loop at least twice this often.
    #[serde(default = "default_watchdog")]
    pub watchdog_s: u64,
    /// SCHED_FIFO priority (1-99) for the processes on the 50 Hz path, so a busy trainer or
    /// planner (SCHED_OTHER) cannot delay their wake-ups; none: the normal scheduler. Needs
    /// root or CAP_SYS_NICE / `ulimit -r`; without it the process runs normally (a warning).
    /// Threads doing long work inside such a process (the planner) set SCHED_OTHER themselves.
    #[serde(default)]
    pub realtime_priority: Option<i32>,
}

fn default_watchdog() -> u64 {
    10
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StackConfig {
    /// `[[stack.process]]` entries, in start order.
    pub process: Vec<ProcessSpec>,
}

impl Default for StackConfig {
    fn default() -> Self {
        let p = |name: &str, binary: &str, description: &str, rt: Option<i32>| ProcessSpec {
            name: name.into(),
            binary: binary.into(),
            description: description.into(),
            args: Vec::new(),
            restart: RestartPolicy::default(),
            watchdog_s: default_watchdog(),
            realtime_priority: rt,
        };
        Self {
            process: vec![
                p(
                    "trainer",
                    "mta-trainer",
                    "mtanet trainer: online MTA-PredNet training from shared-memory replay",
                    None,
                ),
                p(
                    "predictor",
                    "mta-predictor",
                    "mtanet predictor: MTA-PredNet inference and active-inference wheel control",
                    Some(20),
                ),
                p(
                    "simulator",
                    "mta-simulator",
                    "mtanet simulator: the MuJoCo line-tracer world",
                    Some(21),
                ),
            ],
        }
    }
}

impl StackConfig {
    /// Checks names and binaries: unique, non-empty, the simulator present.
    pub fn validate(&self) -> Result<(), String> {
        let mut names = std::collections::BTreeSet::new();
        for p in &self.process {
            if p.name.is_empty()
                || !p
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-')
            {
                return Err(format!(
                    "stack.process name {:?}: use letters, digits and '-'",
                    p.name
                ));
            }
            if !names.insert(&p.name) {
                return Err(format!("stack.process name {:?} appears twice", p.name));
            }
            if p.binary.is_empty() || p.binary.contains('/') {
                return Err(format!(
                    "stack.process {:?}: binary must be a file name in target/release",
                    p.name
                ));
            }
            if p.realtime_priority.is_some_and(|q| !(1..=99).contains(&q)) {
                return Err(format!(
                    "stack.process {:?}: realtime_priority must be 1-99",
                    p.name
                ));
            }
            let r = &p.restart;
            if !(r.backoff_s >= 0.0 && r.max_backoff_s >= r.backoff_s && r.window_s > 0.0) {
                return Err(format!(
                    "stack.process {:?}: restart needs 0 <= backoff_s <= max_backoff_s and window_s > 0",
                    p.name
                ));
            }
        }
        if !self.process.iter().any(|p| p.binary == "mta-simulator") {
            return Err(
                "stack.process: the stack needs the simulator (binary mta-simulator)".into(),
            );
        }
        Ok(())
    }

    /// The stack for a run in real time or lockstep: real-time priorities only serve the 50 Hz
    /// clock; in lockstep the simulator and predictor run flat out and SCHED_FIFO would only take
    /// a core from the trainer the run waits for.
    pub fn for_mode(mut self, realtime: bool) -> Self {
        if !realtime {
            self.process
                .iter_mut()
                .for_each(|p| p.realtime_priority = None);
        }
        self
    }

    pub fn get(&self, name: &str) -> Option<&ProcessSpec> {
        self.process.iter().find(|p| p.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_the_three_processes_and_files_name_bad_entries() {
        let s = StackConfig::default();
        s.validate().unwrap();
        let names: Vec<&str> = s.process.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["trainer", "predictor", "simulator"]);
        let text = r#"
[[process]]
name = "simulator"
binary = "mta-simulator"
restart = { limit = 2 }
[[process]]
name = "simulator"
binary = "mta-simulator"
"#;
        let twice: StackConfig = toml::from_str(text).unwrap();
        assert_eq!(twice.process[0].restart.limit, 2);
        assert_eq!(
            twice.process[0].restart.backoff_s, 0.5,
            "unset keys keep the defaults"
        );
        assert!(twice.validate().unwrap_err().contains("twice"));
        let e = toml::from_str::<StackConfig>(
            "[[process]]\nname = \"x\"\nbinary = \"y\"\nrestrat = {}\n",
        )
        .unwrap_err();
        assert!(e.to_string().contains("restrat"), "{e}");
    }
}
