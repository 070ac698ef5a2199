//! Who drove, and how well: steps, lateral error and laps per command source, switches between
//! active inference and the rest, fallbacks. From the simulator's view (it knows every step's
//! source and the ground truth), for the run's report.

use mtanet_ipc::CommandSource;
pub use mtanet_summaries::simulator::ControlSummary;

#[derive(Debug, Default)]
pub struct ControlStats {
    steps: [u64; 5],
    lateral: [f64; 5],
    last: Option<CommandSource>,
    /// The last source other than the teacher: a single missed command (the teacher's step)
    /// inside a fallback or under active inference is no hand-over.
    last_agent: Option<CommandSource>,
    switches: u64,
    fallbacks: u64,
    laps: u32,
    lap_all_ai: bool,
    laps_ai: u32,
}

impl ControlStats {
    /// One step: who decided its command, the lateral error it started from, and the laps
    /// completed so far (all episodes).
    pub fn record(&mut self, source: CommandSource, lateral_m: f64, laps: u32) {
        let i = source as usize;
        self.steps[i] += 1;
        self.lateral[i] += lateral_m.abs();
        let ai = source == CommandSource::ActiveInference;
        if source != CommandSource::Teacher {
            if let Some(last) = self.last_agent
                && (last == CommandSource::ActiveInference) != ai
            {
                self.switches += 1;
            }
            if source == CommandSource::Fallback && self.last_agent != Some(CommandSource::Fallback)
            {
                self.fallbacks += 1;
            }
            self.last_agent = Some(source);
        }
        if !ai {
            self.lap_all_ai = false;
        } else if self.last != Some(CommandSource::ActiveInference) {
            self.lap_all_ai = false; // a lap counts only if planned from its start
        }
        if laps > self.laps {
            if self.lap_all_ai {
                self.laps_ai += laps - self.laps;
            }
            self.laps = laps;
            self.lap_all_ai = ai;
        }
        self.last = Some(source);
    }

    /// A reset put the car back: the lap in progress ends unfinished.
    pub fn end_episode(&mut self) {
        self.lap_all_ai = false;
    }

    pub fn steps_of(&self, source: CommandSource) -> u64 {
        self.steps[source as usize]
    }

    pub fn laps_under_active_inference(&self) -> u32 {
        self.laps_ai
    }

    pub fn summary(&self) -> ControlSummary {
        let mut out = ControlSummary {
            switches: self.switches,
            fallbacks: self.fallbacks,
            laps_completed_under_active_inference: self.laps_ai,
            ..Default::default()
        };
        for s in CommandSource::ALL {
            let n = self.steps[s as usize];
            out.steps.insert(s.name().into(), n);
            if n > 0 {
                out.lateral_mean_m
                    .insert(s.name().into(), self.lateral[s as usize] / n as f64);
            }
        }
        let total: u64 = self.steps.iter().sum();
        if total > 0 {
            out.exploration_fraction =
                self.steps[CommandSource::Exploration as usize] as f64 / total as f64;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use CommandSource::*;

    #[test]
    fn laps_count_for_active_inference_only_when_it_drove_the_whole_lap() {
        let mut c = ControlStats::default();
        // Reactive, then AI takes over mid-lap 1: lap 1 is not AI's.
        for (src, laps) in [(Reactive, 0), (ActiveInference, 0), (ActiveInference, 1)] {
            c.record(src, 0.01, laps);
        }
        assert_eq!(c.laps_under_active_inference(), 0);
        // Lap 2 all AI.
        c.record(ActiveInference, 0.01, 1);
        c.record(ActiveInference, 0.01, 2);
        assert_eq!(c.laps_under_active_inference(), 1);
        // Lap 3 has a fallback in it.
        c.record(Fallback, 0.03, 2);
        c.record(ActiveInference, 0.01, 2);
        c.record(ActiveInference, 0.01, 3);
        assert_eq!(c.laps_under_active_inference(), 1);
        let s = c.summary();
        assert_eq!(s.switches, 3, "R->AI, AI->F, F->AI");
        assert_eq!(s.fallbacks, 1);
        assert_eq!(s.steps["active_inference"], 6);
        assert!((s.lateral_mean_m["fallback"] - 0.03).abs() < 1e-12);
        assert!(!s.lateral_mean_m.contains_key("teacher"));
    }

    #[test]
    fn a_missed_command_is_no_hand_over() {
        let mut c = ControlStats::default();
        for src in [
            ActiveInference,
            Teacher,
            ActiveInference,
            Fallback,
            Teacher,
            Fallback,
        ] {
            c.record(src, 0.01, 0);
        }
        let s = c.summary();
        assert_eq!((s.switches, s.fallbacks), (1, 1), "{s:?}");
        assert_eq!(s.steps["teacher"], 2);
    }
}
