//! Scene configuration (typed keys, constant defaults, validated before anything is built) and
//! the errors of building a world.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::{CONTROL_PERIOD_S, PHYSICS_TIMESTEP_S};
use mtanet_track::TrackError;

/// Why a [`crate::World`] could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The track file is missing or invalid (or `generated:N` is malformed).
    #[error(transparent)]
    Track(#[from] TrackError),
    /// A configuration value is out of range; `field` is the key as written in the config.
    #[error("scene config: `{field}` {message}")]
    Config {
        field: &'static str,
        message: String,
    },
    /// MuJoCo rejected the generated MJCF (a bug in the generator, not in the input).
    #[error("MuJoCo could not compile the generated scene for track {track}: {message}")]
    Compile { track: PathBuf, message: String },
    /// The compiled model lacks an object the world needs (a bug in the generator).
    #[error("compiled scene has no {kind} named `{name}`")]
    MissingObject { kind: &'static str, name: String },
}

/// Scene settings. Every key has a default, so a config file names only what it changes.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneConfig {
    /// Track CSV (default: this crate's `tracks/oval.csv`); a relative path is relative to the
    /// working directory. `generated:N` is the generator's track of seed N instead of a file.
    pub track: PathBuf,
    /// MuJoCo time step, seconds.
    pub physics_timestep_s: f64,
    /// Time one `World::step` advances, seconds; a whole multiple of the physics step.
    pub control_period_s: f64,
    /// Wheel commands are clamped to +-this, rad/s.
    pub max_wheel_speed: f64,
    /// Also render the left and right cameras.
    pub side_cameras: bool,
    /// Rays per pixel edge: n casts n x n rays per pixel and averages them. 1 (default) is one
    /// ray through each pixel centre, hard-edged like the paper's small V-REP vision sensor.
    pub camera_supersample: u32,
    /// Where the car starts (and `reset` returns to): arc length along the track, metres,
    /// wrapped into the track; the sensor bar sits on the line there, heading along it.
    pub start_s_m: f64,
}

impl Default for SceneConfig {
    fn default() -> Self {
        SceneConfig {
            track: default_track(),
            physics_timestep_s: PHYSICS_TIMESTEP_S,
            control_period_s: CONTROL_PERIOD_S,
            max_wheel_speed: 20.0,
            side_cameras: false,
            start_s_m: 0.0,
            camera_supersample: 1,
        }
    }
}

/// The shipped tracks' directory, `scenes/tracks/`, beside this crate.
pub fn tracks_dir() -> PathBuf {
    let world = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    world.parent().unwrap_or(world).join("tracks")
}

fn default_track() -> PathBuf {
    tracks_dir().join("oval.csv")
}

impl SceneConfig {
    /// The same config on another track.
    pub fn with_track(mut self, track: impl Into<PathBuf>) -> Self {
        self.track = track.into();
        self
    }

    /// Checks ranges; returns the number of physics steps per control period.
    pub fn validate(&self) -> Result<u32, SceneError> {
        let bad = |field, message: String| Err(SceneError::Config { field, message });
        let ts = self.physics_timestep_s;
        if !(ts.is_finite() && ts > 0.0 && ts <= 0.02) {
            return bad(
                "physics_timestep_s",
                format!("= {ts}, expected in (0, 0.02]"),
            );
        }
        let cp = self.control_period_s;
        if !(cp.is_finite() && cp >= ts && cp <= 1.0) {
            return bad(
                "control_period_s",
                format!("= {cp}, expected in [physics_timestep_s, 1]"),
            );
        }
        let ratio = cp / ts;
        if (ratio - ratio.round()).abs() > 1e-6 {
            return bad(
                "control_period_s",
                format!("= {cp} is not a whole multiple of physics_timestep_s = {ts}"),
            );
        }
        let ms = self.max_wheel_speed;
        if !(ms.is_finite() && ms > 0.0 && ms <= 200.0) {
            return bad("max_wheel_speed", format!("= {ms}, expected in (0, 200]"));
        }
        if !(1..=4).contains(&self.camera_supersample) {
            return bad(
                "camera_supersample",
                format!("= {}, expected 1..=4", self.camera_supersample),
            );
        }
        if !self.start_s_m.is_finite() {
            return bad(
                "start_s_m",
                format!("= {}, expected a finite arc length", self.start_s_m),
            );
        }
        Ok(ratio.round() as u32)
    }
}

/// Path of a shipped track by name (`"oval"` -> `<crate>/tracks/oval.csv`); whether it exists is
/// checked when it is loaded.
pub fn shipped_track(name: &str) -> PathBuf {
    tracks_dir().join(format!("{name}.csv"))
}
