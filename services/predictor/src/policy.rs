//! Policies turn an observation into wheel velocities: active inference through the world model
//! when it is loaded and trusted, the reactive line-sensor rule otherwise.

use mtanet_ipc::{CommandSource, Observation};

use crate::active_inference::{self, ActiveInferenceConfig, Preference};
use crate::config::PredictorConfig;
use crate::world_model::WorldModel;

/// The fallback before any usable weights exist: steer toward the side sensor that sees the
/// line. Deliberately simple; it only has to keep the car near the line while data accumulates.
#[derive(Debug, Clone)]
pub struct Reactive {
    cruise: f32,
    turn: f32,
    last_side: f32,
}

impl Reactive {
    pub fn new(cfg: &PredictorConfig) -> Self {
        Self {
            cruise: cfg.cruise,
            turn: cfg.turn,
            last_side: 0.0,
        }
    }

    pub fn act(&mut self, obs: &Observation) -> [f32; 2] {
        let [l, m, r] = obs.line_sensors.map(|v| v != 0);
        // +1: turn left, -1: turn right.
        let side = match (l, m, r) {
            (true, _, false) => 1.0,
            (false, _, true) => -1.0,
            (false, false, false) => self.last_side,
            _ => 0.0,
        };
        if side != 0.0 {
            self.last_side = side;
        }
        let (c, t) = (self.cruise, self.turn * side);
        [c - t, c + t]
    }
}

/// Everything the predictor decides with.
pub struct Policy {
    reactive: Reactive,
    pub world: Option<WorldModel>,
    preference: Preference,
    cfg: ActiveInferenceConfig,
    candidates: Vec<[f32; 2]>,
    previous: [f32; 2],
    episode: Option<u8>,
}

impl Policy {
    pub fn new(cfg: &PredictorConfig) -> Self {
        Self {
            reactive: Reactive::new(cfg),
            world: None,
            preference: Preference::default(),
            candidates: active_inference::candidates(&cfg.active_inference),
            cfg: cfg.active_inference.clone(),
            previous: [0.0; 2],
            episode: None,
        }
    }

    /// Steps the world model with the observation and decides the next command.
    pub fn act(&mut self, obs: &Observation) -> anyhow::Result<([f32; 2], CommandSource)> {
        if self.episode.is_some_and(|e| e != obs.episode) {
            // The simulator put the car back: the past no longer predicts the present.
            if let Some(world) = self.world.as_mut() {
                world.reset_state();
            }
            self.reactive.last_side = 0.0;
            self.previous = [0.0; 2];
        }
        self.episode = Some(obs.episode);
        self.preference.observe(obs);
        let mut decided = None;
        if let Some(world) = self.world.as_mut() {
            world.observe(obs)?;
            let preferred = self.preference.image(self.cfg.preference_frames);
            if let Some(preferred) = preferred.filter(|_| {
                self.cfg.enabled && world.trusted(self.cfg.trust_ratio, self.cfg.trust_after_steps)
            }) {
                let (cmd, _cost) = active_inference::choose(
                    world,
                    &self.candidates,
                    &preferred,
                    self.previous,
                    &self.cfg,
                )?;
                decided = Some((cmd, CommandSource::ActiveInference));
            }
        }
        let (cmd, source) =
            decided.unwrap_or_else(|| (self.reactive.act(obs), CommandSource::Reactive));
        self.previous = cmd;
        Ok((cmd, source))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(line: [u8; 3]) -> Observation {
        let mut o: Observation = bytemuck::Zeroable::zeroed();
        o.line_sensors = line;
        o
    }

    #[test]
    fn reactive_turns_toward_the_line() {
        let mut p = Reactive::new(&PredictorConfig::default());
        let [l, r] = p.act(&obs([1, 0, 0]));
        assert!(r > l, "line on the left must turn left: {l} {r}");
        let [l, r] = p.act(&obs([0, 0, 1]));
        assert!(l > r, "line on the right must turn right: {l} {r}");
        let [l, r] = p.act(&obs([0, 1, 0]));
        assert_eq!(l, r);
        // Lost: keep turning toward where the line was last seen (right).
        let [l, r] = p.act(&obs([0, 0, 0]));
        assert!(l > r);
    }

    #[test]
    fn without_a_model_the_reactive_rule_drives() {
        let mut p = Policy::new(&PredictorConfig::default());
        let (_, source) = p.act(&obs([0, 1, 0])).unwrap();
        assert_eq!(source, CommandSource::Reactive);
    }
}
