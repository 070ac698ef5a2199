//! How a drive went, from ground truth: laps, lateral error, time on the line, and who drove
//! (steps, lateral error and laps per command source, hand-overs, fallbacks). [`crate::Circuit`]
//! keeps one, so the simulator service, the standalone teacher run and `eval`'s drive count a
//! lap, and a lap under active inference, the same way.

use mtanet_summaries::CommandSource;
use mtanet_summaries::simulator::CURVATURE_EDGES;
pub use mtanet_summaries::simulator::{ControlSummary, CurvatureBin, LateralError};

use crate::GroundTruth;

const SOURCES: usize = CommandSource::ALL.len();
const BINS: usize = CURVATURE_EDGES.len() - 1;

/// Per curvature bin: steps and summed |lateral error| of active inference (0) and of any
/// other source (1), and fallbacks begun.
#[derive(Debug, Default, Clone, Copy)]
struct Bin {
    steps: [u64; 2],
    lateral: [f64; 2],
    fallbacks: u64,
}

/// One whole lap: its length in steps and whether active inference drove all of it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Lap {
    steps: u64,
    all_ai: bool,
}

#[derive(Debug, Clone)]
pub struct Score {
    period_s: f64,
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
    /// The step the lap in progress began at: an episode's first step or a lap line's crossing
    /// (None until the episode's first step is recorded).
    lap_start: Option<u64>,
    whole_laps: Vec<Lap>,
    bins: [Bin; BINS],
    fallback_run: u64,
    longest_fallback: u64,
}

impl Default for Score {
    fn default() -> Self {
        Self::new(crate::CONTROL_PERIOD_S)
    }
}

/// The bin of |curvature| `k`.
fn bin_of(k: f64) -> usize {
    let k = k.abs();
    (0..BINS)
        .find(|&i| k < CURVATURE_EDGES[i + 1])
        .unwrap_or(BINS - 1)
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

impl Score {
    /// An empty score for steps of `period_s` seconds.
    pub fn new(period_s: f64) -> Self {
        Self {
            period_s,
            steps: 0,
            sum_abs_lateral: 0.0,
            max_abs_lateral: 0.0,
            off_line_steps: 0,
            steps_by: [0; SOURCES],
            lateral_by: [0.0; SOURCES],
            last_agent: None,
            switches: 0,
            fallbacks: 0,
            laps: 0,
            lap_all_ai: false,
            laps_ai: 0,
            lap_start: None,
            whole_laps: Vec::new(),
            bins: [Bin::default(); BINS],
            fallback_run: 0,
            longest_fallback: 0,
        }
    }

    /// One step: the truth it started from, the line's curvature there (1/m), who decided its
    /// command, and the laps completed over all episodes once it was taken.
    pub(crate) fn record(
        &mut self,
        truth: &GroundTruth,
        curvature: f64,
        source: CommandSource,
        laps: u32,
    ) {
        let lat = truth.lateral_m.abs();
        let start = *self.lap_start.get_or_insert(self.steps);
        self.steps += 1;
        self.sum_abs_lateral += lat;
        self.max_abs_lateral = self.max_abs_lateral.max(lat);
        self.off_line_steps += u64::from(!truth.on_line);
        let i = source as usize;
        self.steps_by[i] += 1;
        self.lateral_by[i] += lat;
        let ai = source == CommandSource::ActiveInference;
        let bin = &mut self.bins[bin_of(curvature)];
        let who = usize::from(!ai);
        bin.steps[who] += 1;
        bin.lateral[who] += lat;
        if source != CommandSource::Teacher {
            if let Some(last) = self.last_agent
                && (last == CommandSource::ActiveInference) != ai
            {
                self.switches += 1;
            }
            if source == CommandSource::Fallback && self.last_agent != Some(CommandSource::Fallback)
            {
                self.fallbacks += 1;
                bin.fallbacks += 1;
            }
            self.last_agent = Some(source);
        }
        // A missed command (the teacher's step) inside a fallback does not end it.
        match source {
            CommandSource::Fallback => self.fallback_run += 1,
            CommandSource::Teacher if self.fallback_run > 0 => self.fallback_run += 1,
            _ => self.fallback_run = 0,
        }
        self.longest_fallback = self.longest_fallback.max(self.fallback_run);
        if !ai {
            self.lap_all_ai = false;
        }
        if laps > self.laps {
            if self.lap_all_ai {
                self.laps_ai += laps - self.laps;
            }
            self.whole_laps.push(Lap {
                steps: self.steps - start,
                all_ai: self.lap_all_ai,
            });
            self.lap_start = Some(self.steps);
            self.laps = laps;
            self.lap_all_ai = true;
        }
    }

    /// The car was put back: the lap in progress ends unfinished.
    pub(crate) fn end_episode(&mut self) {
        self.lap_all_ai = false;
        self.lap_start = None;
        self.fallback_run = 0;
    }

    /// Median seconds of the whole laps `which` selects (by whether active inference drove all
    /// of the lap).
    pub fn lap_time_s(&self, which: impl Fn(bool) -> bool) -> Option<f64> {
        median(
            self.whole_laps
                .iter()
                .filter(|l| which(l.all_ai))
                .map(|l| l.steps as f64 * self.period_s)
                .collect(),
        )
    }

    /// The longest stretch the fallback drove, seconds.
    pub fn longest_fallback_s(&self) -> f64 {
        self.longest_fallback as f64 * self.period_s
    }

    /// Lateral error and fallbacks per curvature bin.
    pub fn by_curvature(&self) -> Vec<CurvatureBin> {
        let mean = |sum: f64, n: u64| (n > 0).then(|| sum / n as f64);
        self.bins
            .iter()
            .enumerate()
            .map(|(i, b)| CurvatureBin {
                min_curvature: CURVATURE_EDGES[i],
                max_curvature: Some(CURVATURE_EDGES[i + 1]).filter(|k| k.is_finite()),
                steps_active_inference: b.steps[0],
                steps_other: b.steps[1],
                lateral_active_inference_m: mean(b.lateral[0], b.steps[0]),
                lateral_other_m: mean(b.lateral[1], b.steps[1]),
                fallbacks: b.fallbacks,
            })
            .collect()
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
            lap_time_s: self.lap_time_s(|_| true),
            lap_time_active_inference_s: self.lap_time_s(|ai| ai),
            longest_fallback_s: self.longest_fallback_s(),
            by_curvature: self.by_curvature(),
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
            c.record(&t, 0.0, src, laps);
        }
        assert_eq!(c.laps_under_active_inference(), 0);
        // Lap 2 all AI.
        c.record(&t, 0.0, ActiveInference, 1);
        c.record(&t, 0.0, ActiveInference, 2);
        assert_eq!(c.laps_under_active_inference(), 1);
        // Lap 3 has a fallback in it.
        c.record(&at(0.03, true), 0.0, Fallback, 2);
        c.record(&t, 0.0, ActiveInference, 2);
        c.record(&t, 0.0, ActiveInference, 3);
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
        c.record(&t, 0.0, Reactive, 1);
        c.record(&t, 0.0, ActiveInference, 1);
        c.end_episode();
        c.record(&t, 0.0, ActiveInference, 2);
        assert_eq!((c.laps(), c.laps_under_active_inference()), (2, 0));
    }

    #[test]
    fn lap_times_curvature_bins_and_the_longest_fallback() {
        let mut c = Score::new(0.5);
        let t = at(0.002, true);
        // Lap 1 (4 steps, reactive then AI), lap 2 (2 steps, all AI), then a 3-step fallback
        // in a hairpin with a missed command in it, and a reset mid-lap.
        let steps = [
            (Reactive, 0.0, 0),
            (ActiveInference, 0.0, 0),
            (ActiveInference, 0.0, 0),
            (ActiveInference, 2.5, 1),
            (ActiveInference, 2.5, 1),
            (ActiveInference, 6.0, 2),
            (Fallback, 8.0, 2),
            (Teacher, 8.0, 2),
            (Fallback, -8.0, 2),
            (ActiveInference, 0.0, 2),
        ];
        for (src, k, laps) in steps {
            c.record(&t, k, src, laps);
        }
        c.end_episode();
        c.record(&t, 0.0, ActiveInference, 2);
        assert_eq!(c.lap_time_s(|_| true), Some(1.5), "laps of 4 and 2 steps");
        assert_eq!(c.lap_time_s(|ai| ai), Some(1.0));
        assert_eq!(c.longest_fallback_s(), 1.5);
        let bins = c.by_curvature();
        assert_eq!(bins.len(), 5);
        assert_eq!(
            (bins[0].steps_active_inference, bins[0].steps_other),
            (4, 1)
        );
        assert_eq!(
            (bins[1].steps_active_inference, bins[2].steps_other),
            (2, 0)
        );
        assert_eq!(bins[3].steps_active_inference, 1, "6 1/m: the 5-7.5 bin");
        assert_eq!((bins[4].steps_other, bins[4].fallbacks), (3, 1));
        assert_eq!(bins[4].lateral_other_m, Some(0.002));
        assert_eq!(bins[4].lateral_active_inference_m, None);
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
            c.record(&at(0.01, true), 0.0, src, 0);
        }
        let s = c.control();
        assert_eq!((s.switches, s.fallbacks), (1, 1), "{s:?}");
        assert_eq!(s.steps["teacher"], 2);
    }

    #[test]
    fn lateral_error_and_time_on_the_line_cover_every_step() {
        let mut c = Score::default();
        c.record(&at(-0.02, true), 0.0, Teacher, 0);
        c.record(&at(0.04, false), 0.0, Teacher, 0);
        let l = c.lateral();
        assert!(
            (l.mean - 0.03).abs() < 1e-12 && (l.max - 0.04).abs() < 1e-12,
            "{l:?}"
        );
        assert!((c.on_line_fraction() - 0.5).abs() < 1e-12);
        assert_eq!(c.steps(), 2);
    }
}
