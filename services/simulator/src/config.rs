//! `[simulator]` section of the stack's config file (with `[simulator.scene]` and
//! `[simulator.teacher]` for the world and the teacher driver).

use mtanet_scenes::{ResetRule, SceneConfig, TeacherConfig};
use serde::{Deserialize, Serialize};

/// How simulated time relates to wall-clock time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// Each step waits for the predictor's command for that step (bounded): reproducible runs,
    /// as fast as the slowest process.
    Lockstep,
    /// Steps at 50 Hz wall clock like a real robot; a command later than half a period counts
    /// as missed.
    Realtime,
}

/// What to drive with when the predictor's command for a step does not come in time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MissPolicy {
    /// The teacher's command (keeps the car on the line and the data useful).
    Teacher,
    /// Stop the wheels.
    Stop,
    /// Repeat the last command.
    Hold,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimulatorConfig {
    pub mode: Mode,
    /// Realtime: how long a step waits for its command before the miss policy applies (at most
    /// half a control period). Lockstep waits as long as the predictor lives, checking for a
    /// dead one every this long; the miss policy applies only once none is connected.
    pub command_timeout_ms: u64,
    pub on_missed_command: MissPolicy,
    /// Lockstep: wait this long at start for a predictor (and a trainer, if expected) to connect;
    /// without one the teacher drives.
    pub wait_for_peers_s: f64,
    /// Also wait for a replay subscriber (the trainer) before the first step.
    pub expect_trainer: bool,
    /// Stop after this many steps (0: run until a signal).
    pub max_steps: u64,
    /// Publish replay chunks for the trainer.
    pub replay: bool,
    /// At the end of a run, keep the replay publisher this long while a trainer subscribes:
    /// iceoryx2 drops the samples of a publisher that left before the subscriber connected to
    /// it (eclipse-iceoryx/iceoryx2#39), so a trainer starved of CPU would lose the run's chunks.
    pub replay_linger_s: f64,
    /// Seconds of wall clock between progress log lines.
    pub log_every_s: f64,
    /// Put the car back at the start (a new episode) once it has been farther than
    /// `lost_lateral_m` from the line for this long; 0 = never. A lost car sees bare floor, and
    /// a run would otherwise record nothing useful from then on.
    pub reset_after_lost_s: f64,
    /// Distance from the line beyond which the car counts as lost.
    pub lost_lateral_m: f64,
    /// Also put the car back once it has driven this far backwards along the track within
    /// `reset_after_lost_s` (turned around, it would follow the line the wrong way); 0 = never.
    pub reverse_reset_m: f64,
    /// Lockstep: once the trainer trains, wait for it so that it makes this many updates per
    /// 1000 simulated steps (0: run as fast as the predictor answers). Learning per simulated
    /// second is then the same on a slow or a fast machine.
    pub pace_updates_per_1000_steps: f64,
    /// `--trace FILE` writes every n-th step's position and driver.
    pub trace_every_steps: u64,
    /// More tracks to drive in turn after `[simulator.scene] track` (CSV or `generated:N`), each
    /// with that scene's physics: after `switch_track_after_s` simulated seconds on one, the car
    /// moves to the start of the next (and round to the first) as a new episode, so a learner
    /// sees more kinds of bend than one track has. The trainer's probe stays on the first track.
    pub also_tracks: Vec<std::path::PathBuf>,
    /// Simulated seconds on each track before moving to the next (with `also_tracks`).
    pub switch_track_after_s: f64,
    /// `[simulator.scene]`: track and physics.
    pub scene: SceneConfig,
    /// `[simulator.teacher]`: the teacher driver.
    pub teacher: TeacherConfig,
}

impl Default for SimulatorConfig {
    fn default() -> Self {
        Self {
            mode: Mode::Realtime,
            command_timeout_ms: 200,
            on_missed_command: MissPolicy::Teacher,
            wait_for_peers_s: 30.0,
            expect_trainer: false,
            max_steps: 0,
            replay: true,
            replay_linger_s: 1.0,
            log_every_s: 5.0,
            reset_after_lost_s: 3.0,
            lost_lateral_m: 0.1,
            reverse_reset_m: 0.15,
            pace_updates_per_1000_steps: 160.0,
            trace_every_steps: 5,
            also_tracks: Vec::new(),
            switch_track_after_s: 60.0,
            scene: SceneConfig::default(),
            teacher: TeacherConfig::default(),
        }
    }
}

impl SimulatorConfig {
    /// The scenes driven in turn: `[simulator.scene]`, then one per `also_tracks` entry.
    pub fn scenes(&self) -> Vec<SceneConfig> {
        let more = self.also_tracks.iter().map(|t| SceneConfig {
            track: t.clone(),
            ..self.scene.clone()
        });
        std::iter::once(self.scene.clone()).chain(more).collect()
    }

    /// Checks what the services would otherwise find only at start (or an hour in): ranges, the
    /// scene, and that every track loads. An error names the key (`simulator.also_tracks[1]`).
    pub fn validate(&self) -> Result<(), String> {
        self.scene
            .validate()
            .map_err(|e| format!("[simulator.scene] {e}"))?;
        let t = self.switch_track_after_s;
        if !self.also_tracks.is_empty() && !(t.is_finite() && t > 0.0) {
            return Err(format!(
                "simulator.switch_track_after_s = {t}: give a positive time on each track to drive also_tracks"
            ));
        }
        for (key, v) in [
            ("reset_after_lost_s", self.reset_after_lost_s),
            ("lost_lateral_m", self.lost_lateral_m),
            ("reverse_reset_m", self.reverse_reset_m),
            (
                "pace_updates_per_1000_steps",
                self.pace_updates_per_1000_steps,
            ),
            ("wait_for_peers_s", self.wait_for_peers_s),
            ("log_every_s", self.log_every_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!(
                    "simulator.{key} = {v}: expected a finite number >= 0"
                ));
            }
        }
        for (key, track) in self.track_keys() {
            mtanet_scenes::Track::load(track).map_err(|e| format!("{key}: {e}"))?;
        }
        Ok(())
    }

    /// Each track driven with the config key that names it.
    pub fn track_keys(&self) -> Vec<(String, &std::path::Path)> {
        let more = self.also_tracks.iter().enumerate();
        std::iter::once((
            "simulator.scene.track".to_string(),
            self.scene.track.as_path(),
        ))
        .chain(more.map(|(i, t)| (format!("simulator.also_tracks[{i}]"), t.as_path())))
        .collect()
    }

    /// When the car is put back at the start.
    pub fn reset_rule(&self) -> ResetRule {
        ResetRule {
            after_lost_s: self.reset_after_lost_s,
            lost_lateral_m: self.lost_lateral_m,
            reverse_m: self.reverse_reset_m,
        }
    }
}
