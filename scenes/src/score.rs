//! How a drive went, from ground truth: laps, lateral error, time on the line, and who drove
//! (steps, lateral error and laps per command source, hand-overs, fallbacks). [`crate::Drive`]
//! keeps one, so the simulator service, the standalone teacher run and `eval`'s drive count a
//! lap, and a lap under active inference, the same way.

pub use mtanet_summaries::CommandSource;
pub use mtanet_summaries::simulator::{ControlSummary, LateralError};

use crate::GroundTruth;

const SOURCES: usize = CommandSource::ALL.len();

#[derive(Debug, Default, Clone)]
pub struct Score {
    steps: u64,
    sum_abs_lateral: f64,
    max_abs_lateral: f64,
    off_line_steps: u64,
    steps_by: [u64; SOURCES],
    lateral_by: [f64; SOURCES],
    /// The last source other than the teacher: a single missed command (the teacher's step)
    /// inside a fallback or under active inference is no hand-over.
    last_agent: Option<CommandSource>,
    switches: u64,
    fallbacks: u64,
    laps: u32,
    /// Active inference decided every step of the lap in progress. False at the start of a
    /// drive and of an episode: a lap counts only when planned from its first step.
    lap_all_ai: bool,
    laps_ai: u32,
}

impl Score {
    /// One step: the truth it started from, who decided its command, and the laps completed
    /// over all episodes once it was taken.
    pub(crate) fn record(&mut self, truth: &GroundTruth, source: CommandSource, laps: u32) {
        let lat = truth.lateral_m.abs();
        self.steps += 1;
        self.sum_abs_lateral += lat;
        self.max_abs_lateral = self.max_abs_lateral.max(lat);
        self.off_line_steps += u64::from(!truth.on_line);
        let i = source as usize;
        self.steps_by[i] += 1;
        self.lateral_by[i] += lat;
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
        }
        if laps > self.laps {
            if self.lap_all_ai {
                self.laps_ai += laps - self.laps;
            }
            self.laps = laps;
            self.lap_all_ai = true;
        }
    }

    /// The car was put back: the lap in progress ends unfinished.
    pub(crate) fn end_episode(&mut self) {
        self.lap_all_ai = false;
    }

    /// Steps scored.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Completed laps over all episodes.
    pub fn laps(&self) -> u32 {
        self.laps
    }

    /// Laps in which active inference decided every step, from the lap's first.
    pub fn laps_under_active_inference(&self) -> u32 {
        self.laps_ai
    }

    pub fn steps_of(&self, source: CommandSource) -> u64 {
        self.steps_by[source as usize]
    }

    /// Mean |lateral error| (m) over the steps whose source `which` selects (None: no such step).
    pub fn lateral_mean_of(&self, which: impl Fn(CommandSource) -> bool) -> Option<f64> {
        let (mut sum, mut n) = (0.0, 0);
        for s in CommandSource::ALL.into_iter().filter(|&s| which(s)) {
            sum += self.lateral_by[s as usize];
            n += self.steps_by[s as usize];
        }
        (n > 0).then(|| sum / n as f64)
    }

    /// Mean and max |lateral error| over every step.
    pub fn lateral(&self) -> LateralError {
        LateralError {
            mean: if self.steps == 0 {
                0.0
            } else {
                self.sum_abs_lateral / self.steps as f64
            },
            max: self.max_abs_lateral,
        }
    }

    /// Fraction of steps with the sensor bar's centre over the line.
    pub fn on_line_fraction(&self) -> f64 {
        if self.steps == 0 {
            0.0
        } else {
            1.0 - self.off_line_steps as f64 / self.steps as f64
        }
    }

    /// Who drove, for the run's report.
    pub fn control(&self) -> ControlSummary {
        let mut out = ControlSummary {
            switches: self.switches,
            fallbacks: self.fallbacks,
            laps_completed_under_active_inference: self.laps_ai,
            ..Default::default()
        };
        for s in CommandSource::ALL {
            let n = self.steps_of(s);
            out.steps.insert(s.name().into(), n);
            if let Some(mean) = self.lateral_mean_of(|x| x == s) {
                out.lateral_mean_m.insert(s.name().into(), mean);
            }
        }
        if self.steps > 0 {
            out.exploration_fraction =
                self.steps_of(CommandSource::Exploration) as f64 / self.steps as f64;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use CommandSource::*;

    fn at(lateral_m: f64, on_line: bool) -> GroundTruth {
        GroundTruth {
            lateral_m,
            on_line,
            ..Default::default()
        }
    }

    #[test]
    fn laps_count_for_active_inference_only_when_it_drove_the_whole_lap() {
        let mut c = Score::default();
        let t = at(0.01, true);
        // Reactive, then AI takes over mid-lap 1: lap 1 is not AI's.
        for (src, laps) in [(Reactive, 0), (ActiveInference, 0), (ActiveInference, 1)] {
            c.record(&t, src, laps);
        }
        assert_eq!(c.laps_under_active_inference(), 0);
        // Lap 2 all AI.
        c.record(&t, ActiveInference, 1);
        c.record(&t, ActiveInference, 2);
        assert_eq!(c.laps_under_active_inference(), 1);
        // Lap 3 has a fallback in it.
        c.record(&at(0.03, true), Fallback, 2);
        c.record(&t, ActiveInference, 2);
        c.record(&t, ActiveInference, 3);
        assert_eq!(c.laps_under_active_inference(), 1);
        assert_eq!(c.laps(), 3);
        let s = c.control();
        assert_eq!(s.switches, 3, "R->AI, AI->F, F->AI");
        assert_eq!(s.fallbacks, 1);
        assert_eq!(s.steps["active_inference"], 6);
        assert!((s.lateral_mean_m["fallback"] - 0.03).abs() < 1e-12);
        assert!(!s.lateral_mean_m.contains_key("teacher"));
        let not_ai = c.lateral_mean_of(|s| s != ActiveInference).unwrap();
        assert!((not_ai - 0.02).abs() < 1e-12, "{not_ai}");
    }

    #[test]
    fn a_lap_cut_short_by_a_reset_is_not_active_inferences() {
        let mut c = Score::default();
        let t = at(0.01, true);
        c.record(&t, Reactive, 1);
        c.record(&t, ActiveInference, 1);
        c.end_episode();
        c.record(&t, ActiveInference, 2);
        assert_eq!((c.laps(), c.laps_under_active_inference()), (2, 0));
    }

    #[test]
    fn a_missed_command_is_no_hand_over() {
        let mut c = Score::default();
        for src in [
            ActiveInference,
            Teacher,
            ActiveInference,
            Fallback,
            Teacher,
            Fallback,
        ] {
            c.record(&at(0.01, true), src, 0);
        }
        let s = c.control();
        assert_eq!((s.switches, s.fallbacks), (1, 1), "{s:?}");
        assert_eq!(s.steps["teacher"], 2);
    }

    #[test]
    fn lateral_error_and_time_on_the_line_cover_every_step() {
        let mut c = Score::default();
        c.record(&at(-0.02, true), Teacher, 0);
        c.record(&at(0.04, false), Teacher, 0);
        let l = c.lateral();
        assert!(
            (l.mean - 0.03).abs() < 1e-12 && (l.max - 0.04).abs() < 1e-12,
            "{l:?}"
        );
        assert!((c.on_line_fraction() - 0.5).abs() < 1e-12);
        assert_eq!(c.steps(), 2);
    }
}
