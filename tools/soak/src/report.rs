//! `soak.json` from what the run measured: the processes' own summaries, the transport floor,
//! the machine's pauses and the supervisor's samples of each process.

use std::collections::BTreeMap;

use mtanet_ipc::latency::LatencyStats;
use mtanet_summaries::incident::{Incident, IncidentKind};
use mtanet_summaries::predictor::Summary as PredictorSummary;
use mtanet_summaries::simulator::Summary as SimulatorSummary;
use mtanet_summaries::soak::{
    Control, IncidentCounts, Machine, PauseSummary, ProcessUse, ReplayCounts, SoakReport, StartEnd,
};
use mtanet_summaries::trainer::Summary as TrainerSummary;

use crate::pauses::{self, Pause};

/// Resident memory (kB) and open files of each process, by name.
pub type Samples = BTreeMap<String, (u64, u64)>;

/// What the processes said at exit.
pub struct Summaries {
    pub sim: SimulatorSummary,
    pub pred: PredictorSummary,
    pub trainer: TrainerSummary,
}

/// What the soak itself watched.
pub struct Watched {
    pub mode: String,
    pub minutes: f64,
    pub machine: Machine,
    /// The ping-pong alone, beside the stack, and its round trips lost beside it.
    pub floor: (LatencyStats, LatencyStats, u64),
    pub pauses: Vec<Pause>,
    pub machine_pauses: PauseSummary,
    /// Scheduling class of each process as started.
    pub classes: BTreeMap<String, String>,
    /// Once warmed up, and the last while running.
    pub first: Samples,
    pub last: Samples,
    pub restarts: BTreeMap<String, u32>,
    pub clean_exit: bool,
}

pub fn soak_report(s: &Summaries, w: Watched, names: &[String]) -> SoakReport {
    let (sim, pred, tr) = (&s.sim, &s.pred, &s.trainer);
    let latency = [
        ("raw_pingpong_idle", w.floor.0.summary()),
        ("raw_pingpong", w.floor.1.summary()),
        ("round_trip", sim.round_trip),
        ("obs_to_predictor", pred.obs_to_predictor),
        ("predictor", pred.compute),
        ("cmd_to_sim", sim.cmd_to_sim),
        ("step", sim.step_time),
        ("plan", pred.plan),
        ("tick_jitter", sim.tick_jitter),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    let processes = names
        .iter()
        .map(|name| (name.clone(), process_use(name, &w)))
        .collect();
    let control = Control::new(&sim.control, Some(&pred.control));
    SoakReport {
        mode: w.mode,
        minutes: w.minutes,
        steps: sim.steps,
        machine: w.machine,
        latency,
        overruns: sim.overruns,
        missed_commands: sim.missed_commands,
        plan_followed: sim.plan_followed,
        dropped_commands: pred.commands_sent.saturating_sub(sim.commands_received),
        replay: ReplayCounts {
            chunks_sent: sim.replay_chunks_sent,
            chunks_received: tr.chunks_received,
            chunks_lost: tr.chunks_lost,
        },
        raw_pingpong_lost: w.floor.2,
        control: control.clone(),
        active_inference_share: control.active_inference_steps as f64 / sim.steps.max(1) as f64,
        planning: pred.planning.clone(),
        machine_pauses: w.machine_pauses,
        incidents: incident_counts(sim, pred, &w.pauses),
        trainer_updates: tr.session_updates,
        processes,
        restarts: w.restarts,
        clean_exit: w.clean_exit,
    }
}

fn process_use(name: &str, w: &Watched) -> ProcessUse {
    let a = w.first.get(name).copied().unwrap_or_default();
    let b = w.last.get(name).copied().unwrap_or_default();
    ProcessUse {
        scheduling: w.classes.get(name).cloned().unwrap_or_default(),
        rss_kb: StartEnd {
            start: a.0,
            end: b.0,
        },
        fds: StartEnd {
            start: a.1,
            end: b.1,
        },
    }
}

/// Missed commands, overruns and late plans, and how many of them fell in a machine pause.
fn incident_counts(
    sim: &SimulatorSummary,
    pred: &PredictorSummary,
    pauses: &[Pause],
) -> IncidentCounts {
    let incidents: Vec<Incident> = sim
        .incidents
        .iter()
        .chain(&pred.incidents)
        .copied()
        .collect();
    let kind = |k: IncidentKind| incidents.iter().filter(|i| i.kind == k).count();
    let paused = incidents
        .iter()
        .filter(|i| pauses::during_a_pause(pauses, i.start_ns, i.end_ns, 1_000_000))
        .count();
    IncidentCounts {
        missed_commands: kind(IncidentKind::MissedCommand),
        overruns: kind(IncidentKind::Overrun),
        late_plans: kind(IncidentKind::LatePlan),
        during_machine_pauses: paused,
        unexplained: incidents.len() - paused,
    }
}
