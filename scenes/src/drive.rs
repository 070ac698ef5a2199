//! One car driven round its track, one control step at a time, with no IPC and no clock: the
//! simulator service, the standalone teacher run and `eval`'s in-process drive all step the world
//! through [`Drive`], so a step, a lost car, an episode, a lap and who drove it mean the same in
//! each, and are counted once, in its [`Score`]. Where a command comes from and when the next step
//! is due are the caller's.

use crate::score::{CommandSource, Score};
use crate::{GroundTruth, Referee, Sensors, Verdict, World};

/// When a car is put back at the start as a new episode (see [`Referee`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResetRule {
    /// How long the car may be lost (or drive the wrong way) first; 0 never puts it back.
    pub after_lost_s: f64,
    /// Farther than this off the line counts as lost.
    pub lost_lateral_m: f64,
    /// Driving this far backwards along the track within that time counts as the wrong way.
    pub reverse_m: f64,
}

impl Default for ResetRule {
    fn default() -> Self {
        Self {
            after_lost_s: 3.0,
            lost_lateral_m: 0.1,
            reverse_m: 0.15,
        }
    }
}

/// What the car senses at the start of a step.
#[derive(Debug, Clone, Copy)]
pub struct Frame {
    /// Control steps since the drive began (over all episodes).
    pub step: u64,
    pub episode: u32,
    /// Simulated seconds of this episode.
    pub time_s: f64,
    /// The command in force, which led to this frame.
    pub applied: [f32; 2],
    pub sensors: Sensors,
}

/// What one step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stepped {
    /// False: the command was not finite and the last good one was applied.
    pub accepted: bool,
    /// Laps completed since the drive began (over all episodes).
    pub laps: u32,
    /// The car was put back at the start (a new episode begins), and why.
    pub reset: Option<Verdict>,
}

pub struct Drive<'w> {
    world: &'w mut World,
    referee: Referee,
    step: u64,
    episode: u32,
    laps_before: u32,
    /// The truth at the last `sense`, scored with the command that answers it.
    sensed: Option<GroundTruth>,
    score: Score,
}

impl<'w> Drive<'w> {
    pub fn new(world: &'w mut World, rule: ResetRule) -> Self {
        let period = world.config().control_period_s;
        Self {
            referee: Referee::new(
                rule.after_lost_s,
                period,
                rule.lost_lateral_m,
                rule.reverse_m,
            ),
            world,
            step: 0,
            episode: 0,
            laps_before: 0,
            sensed: None,
            score: Score::new(period),
        }
    }

    /// The sensors now, and the command that led here.
    pub fn sense(&mut self) -> Frame {
        let sensors = self.world.sense();
        self.sensed = Some(sensors.truth);
        Frame {
            step: self.step,
            episode: self.episode,
            time_s: self.world.time_s(),
            applied: self.world.command().map(|v| v as f32),
            sensors,
        }
    }

    /// Applies `command`, decided by `source`, for one control period and scores the step; then
    /// judges the car: a lost car (or one driving the wrong way) is put back at the start as a
    /// new episode.
    pub fn step(&mut self, command: [f32; 2], source: CommandSource) -> Stepped {
        let from = self.sensed.take().unwrap_or_else(|| self.world.truth());
        let accepted = self.world.step(command);
        self.step += 1;
        let laps = self.laps_before + self.world.truth().laps;
        let verdict = self
            .referee
            .judge(&self.world.truth(), self.world.progress_m());
        // The line's curvature where the sensor bar was, over 10 cm either side.
        let curvature = self.world.track().curvature_at(from.track_s, 0.1);
        self.score.record(&from, curvature, source, laps);
        let reset = (verdict != Verdict::Fine).then(|| {
            self.score.end_episode();
            self.laps_before = laps;
            self.world.reset();
            self.referee.reset();
            self.episode += 1;
            verdict
        });
        Stepped {
            accepted,
            laps,
            reset,
        }
    }

    /// Steps taken so far.
    pub fn steps(&self) -> u64 {
        self.step
    }

    /// Laps, lateral error and who drove, over every step so far.
    pub fn score(&self) -> &Score {
        &self.score
    }

    pub fn episode(&self) -> u32 {
        self.episode
    }

    pub fn world(&self) -> &World {
        self.world
    }

    pub fn world_mut(&mut self) -> &mut World {
        self.world
    }
}
