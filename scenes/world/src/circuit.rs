//! One car driven round its track, one control step at a time, with no IPC and no clock: the
//! simulator service, the standalone teacher run and `eval`'s in-process drive all step the world
//! through [`Circuit`], so a step, a lost car, an episode, a lap and who drove it mean the same in
//! each, and are counted once, in its [`Score`]. Where a command comes from and when the next step
//! is due are the caller's.

use crate::score::Score;
use crate::{GroundTruth, Referee, Sensors, Verdict, World};
use mtanet_summaries::CommandSource;

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
    /// The car moved on to the start of this track (its index; a new episode begins).
    pub switched_to: Option<usize>,
}

pub struct Circuit<'w> {
    /// The tracks driven in turn; `current` is the one the car is on.
    worlds: &'w mut [World],
    current: usize,
    /// Steps on one track before moving to the next (0: never).
    switch_after_steps: u64,
    /// Steps since the car came onto the current track.
    on_track_steps: u64,
    referee: Referee,
    step: u64,
    episode: u32,
    laps_before: u32,
    /// The truth at the last `sense`, scored with the command that answers it.
    sensed: Option<GroundTruth>,
    score: Score,
}

impl<'w> Circuit<'w> {
    pub fn new(world: &'w mut World, rule: ResetRule) -> Self {
        Self::round(std::slice::from_mut(world), rule, 0.0)
    }

    /// A drive that starts on `worlds[0]` and, after `switch_after_s` simulated seconds on a
    /// track, moves the car to the start of the next (round to the first) as a new episode. A
    /// lost car is put back at the start of the track it is on. 0 (or one world) never moves.
    pub fn round(worlds: &'w mut [World], rule: ResetRule, switch_after_s: f64) -> Self {
        assert!(!worlds.is_empty(), "a drive needs a world");
        let period = worlds[0].config().control_period_s;
        let switch_after_steps = if worlds.len() > 1 && switch_after_s > 0.0 {
            (switch_after_s / period).round().max(1.0) as u64
        } else {
            0
        };
        Self {
            referee: Referee::new(
                rule.after_lost_s,
                period,
                rule.lost_lateral_m,
                rule.reverse_m,
            ),
            worlds,
            current: 0,
            switch_after_steps,
            on_track_steps: 0,
            step: 0,
            episode: 0,
            laps_before: 0,
            sensed: None,
            score: Score::new(period),
        }
    }

    /// The sensors now, and the command that led here.
    pub fn sense(&mut self) -> Frame {
        let world = &mut self.worlds[self.current];
        let sensors = world.sense();
        self.sensed = Some(sensors.truth);
        Frame {
            step: self.step,
            episode: self.episode,
            time_s: world.time_s(),
            applied: world.command().map(|v| v as f32),
            sensors,
        }
    }

    /// Applies `command`, decided by `source`, for one control period and scores the step; then
    /// judges the car: a lost car (or one driving the wrong way) is put back at the start as a
    /// new episode.
    pub fn step(&mut self, command: [f32; 2], source: CommandSource) -> Stepped {
        let world = &mut self.worlds[self.current];
        let from = self.sensed.take().unwrap_or_else(|| world.truth());
        let accepted = world.step(command);
        self.step += 1;
        self.on_track_steps += 1;
        let laps = self.laps_before + world.truth().laps;
        let verdict = self.referee.judge(&world.truth(), world.progress_m());
        // The line's curvature where the sensor bar was, over 10 cm either side.
        let curvature = world.track().curvature_at(from.track_s, 0.1);
        self.score.record(&from, curvature, source, laps);
        let reset = (verdict != Verdict::Fine).then_some(verdict);
        let switch = reset.is_none()
            && self.switch_after_steps > 0
            && self.on_track_steps >= self.switch_after_steps;
        let switched_to = switch.then(|| (self.current + 1) % self.worlds.len());
        if reset.is_some() || switch {
            self.score.end_episode();
            self.laps_before = laps;
            if let Some(next) = switched_to {
                self.current = next;
                self.on_track_steps = 0;
            }
            self.worlds[self.current].reset();
            self.referee.reset();
            self.episode += 1;
        }
        Stepped {
            accepted,
            laps,
            reset,
            switched_to,
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

    /// The world of the track the car is on.
    pub fn world(&self) -> &World {
        &self.worlds[self.current]
    }

    pub fn world_mut(&mut self) -> &mut World {
        &mut self.worlds[self.current]
    }

    /// Index of the track the car is on (in the order given to [`Circuit::round`]).
    pub fn track_index(&self) -> usize {
        self.current
    }

    /// Commands refused as not finite, over every track.
    pub fn rejected_commands(&self) -> u64 {
        self.worlds.iter().map(World::rejected_commands).sum()
    }
}
