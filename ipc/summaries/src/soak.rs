//! What `mta soak` (`soak.json`) and `mta report` (`report.json`) write, typed: the commands,
//! their tables and the tests read these definitions. Latencies are [`LatencySummary`]
//! (microseconds), as in every summary.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::simulator::ControlSummary;
use crate::{AgentStats, LatencySummary, PlanningSummary};

/// `soak.json`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct SoakReport {
    /// "realtime" or "lockstep".
    pub mode: String,
    pub minutes: f64,
    pub steps: u64,
    pub machine: Machine,
    /// Per leg ([`LEGS`]), measured in the same run.
    pub latency: BTreeMap<String, LatencySummary>,
    /// Steps whose work took longer than their 20 ms period.
    pub overruns: u64,
    /// Steps whose command did not come within the simulator's wait and no plan covered (the
    /// miss policy drove).
    pub missed_commands: u64,
    /// Steps whose command did not come in time, driven by the plan the last command carried.
    #[serde(default)]
    pub plan_followed: u64,
    /// Commands the predictor sent that the simulator never took in.
    pub dropped_commands: u64,
    pub replay: ReplayCounts,
    /// Raw ping-pong round trips that never came back.
    pub raw_pingpong_lost: u64,
    pub control: Control,
    /// Steps active inference drove, of all steps.
    pub active_inference_share: f64,
    pub planning: PlanningSummary,
    pub machine_pauses: PauseSummary,
    pub incidents: IncidentCounts,
    /// Training updates the trainer made in this run.
    pub trainer_updates: u64,
    pub processes: BTreeMap<String, ProcessUse>,
    pub restarts: BTreeMap<String, u32>,
    /// No node, service or shared-memory file of the run's namespace was left behind.
    pub clean_exit: bool,
}

/// Who drove the car: the steps as the simulator applied them (a missed command counts for the
/// miss policy, not for the source that was late), and the predictor's own counters.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Control {
    pub reactive_steps: u64,
    pub exploration_steps: u64,
    pub active_inference_steps: u64,
    pub fallback_steps: u64,
    pub teacher_steps: u64,
    pub exploration_fraction: f64,
    /// Changes from another source to active inference and back.
    pub switches: u64,
    /// Times the fallback took over (the line lost under active inference).
    pub fallbacks: u64,
    /// The longest stretch the fallback drove without a break, seconds.
    #[serde(default)]
    pub longest_fallback_s: f64,
    /// Plans taken up, and those not ready when their segment began (the predictor's).
    pub plans: u64,
    pub late_plans: u64,
    /// Seconds into the run when active inference first took the wheel (the predictor's).
    pub first_takeover_s: Option<f64>,
}

impl Control {
    pub fn new(sim: &ControlSummary, predictor: Option<&AgentStats>) -> Self {
        let steps = |k: &str| sim.steps.get(k).copied().unwrap_or(0);
        Self {
            reactive_steps: steps("reactive"),
            exploration_steps: steps("exploration"),
            active_inference_steps: steps("active_inference"),
            fallback_steps: steps("fallback"),
            teacher_steps: steps("teacher"),
            exploration_fraction: sim.exploration_fraction,
            switches: sim.switches,
            fallbacks: sim.fallbacks,
            longest_fallback_s: sim.longest_fallback_s,
            plans: predictor.map_or(0, |p| p.plans),
            late_plans: predictor.map_or(0, |p| p.late_plans),
            first_takeover_s: predictor
                .and_then(|p| p.first_takeover_step)
                .map(|s| s as f64 * crate::CONTROL_PERIOD_S),
        }
    }
}

impl std::fmt::Display for Control {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "active inference {} / reactive {} / exploration {} / fallback {} steps, {} fallbacks, {} of {} plans late",
            self.active_inference_steps,
            self.reactive_steps,
            self.exploration_steps,
            self.fallback_steps,
            self.fallbacks,
            self.late_plans,
            self.plans
        )
    }
}

/// The legs of [`SoakReport::latency`], in the order the table prints them.
pub const LEGS: [&str; 9] = [
    "raw_pingpong_idle",
    "raw_pingpong",
    "round_trip",
    "obs_to_predictor",
    "predictor",
    "cmd_to_sim",
    "step",
    "plan",
    "tick_jitter",
];

#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct ReplayCounts {
    pub chunks_sent: u64,
    pub chunks_received: u64,
    /// Chunks missing from the trainer's sequence numbers (overwritten before they were read).
    pub chunks_lost: u64,
}

/// The misses of the run and whom they belong to: a miss while the machine itself ran nothing
/// is the machine's; the rest are the stack's own.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct IncidentCounts {
    pub missed_commands: usize,
    pub overruns: usize,
    pub late_plans: usize,
    pub during_machine_pauses: usize,
    pub unexplained: usize,
}

/// A process's scheduling class, and its memory and open files once warmed up and at the end.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ProcessUse {
    /// As `ps` shows it: "FIFO 20", "OTHER nice 10".
    pub scheduling: String,
    pub rss_kb: StartEnd,
    pub fds: StartEnd,
}

#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct StartEnd {
    pub start: u64,
    pub end: u64,
}

/// The CPU a figure was measured on, and what it ran beside.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Machine {
    pub cpu_model: String,
    pub avx512: bool,
    /// CPUs this run may use.
    pub cpus: usize,
    /// Busy processes at normal priority beside the run.
    pub cpu_hog_processes: usize,
}

impl Machine {
    /// This machine, as Linux describes it (`/proc/cpuinfo`; "unknown" elsewhere).
    pub fn here(cpu_hog_processes: usize) -> Self {
        let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
        let cpu_model = info
            .lines()
            .find_map(|l| l.strip_prefix("model name"))
            .and_then(|l| l.split_once(':'))
            .map_or_else(|| "unknown".into(), |(_, m)| m.trim().to_string());
        Self {
            cpu_model,
            avx512: info.split_whitespace().any(|w| w == "avx512f"),
            cpus: std::thread::available_parallelism().map_or(1, |n| n.get()),
            cpu_hog_processes,
        }
    }

    /// The CPU alone: "AMD EPYC (no AVX-512), 2 CPUs".
    pub fn cpu(&self) -> String {
        format!("{}, {} CPUs", self.model(), self.cpus)
    }

    /// "AMD EPYC (no AVX-512)": the model and whether it has the wide vector units.
    fn model(&self) -> String {
        let simd = if self.avx512 { "AVX-512" } else { "no AVX-512" };
        format!("{} ({simd})", self.cpu_model)
    }
}

impl std::fmt::Display for Machine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}, {} CPU(s) for the run, {} CPU hog process(es) beside it",
            self.model(),
            self.cpus,
            self.cpu_hog_processes
        )
    }
}

/// What the machine-pause watch saw: times a CPU ran nothing at all (not even a SCHED_FIFO 99
/// thread) for 3 ms or more.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct PauseSummary {
    /// False without the privilege to run SCHED_FIFO 99 (nothing was measured then).
    pub measured: bool,
    pub count: usize,
    pub per_minute: f64,
    pub worst_ms: f64,
    pub total_ms: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_machine_is_described_by_its_cpu_and_what_ran_beside_it() {
        let m = Machine::here(2);
        assert!(m.cpus >= 1 && m.cpu_hog_processes == 2, "{m:?}");
        let shown = m.to_string();
        assert!(
            shown.starts_with(&m.cpu_model) && shown.ends_with("2 CPU hog process(es) beside it"),
            "{shown}"
        );
        let avx = Machine {
            avx512: true,
            cpus: 2,
            cpu_model: "X".into(),
            cpu_hog_processes: 0,
        };
        assert_eq!(avx.cpu(), "X (AVX-512), 2 CPUs");
        assert_eq!(
            avx.to_string(),
            "X (AVX-512), 2 CPU(s) for the run, 0 CPU hog process(es) beside it"
        );
    }
}
